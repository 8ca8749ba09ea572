"""
Vehicle ends and running resistance laws of a consist: side buffers, curves, pretension.

Helpers of :mod:`.consist` (which builds the consist with them), each a step of its build:

- :func:`ends_resolved`: a vehicle's fields with its side buffers in parallel
  (``buffers_per_end`` n: a buffer figure the type gives is one buffer's, the end's n times
  it) and its tabulated curves (``characteristics:`` mapping of the library or the consist
  file, :class:`Curves`) numbered;
- :func:`pretension_strokes`: the strokes a pretensioned screw coupling leaves
  (physics/characteristics.py, ``pretension_table``);
- :func:`resistance_laws`: a vehicle on Strahl or Sauthoff gets the Davis coefficients of its
  law (physics/resistance.py).

Never imports rclpy.
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np
from train_dynamics.physics import characteristics, resistance
from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.quoting import clip, quote

#: the keys of a type or vehicle entry that hold one end's own fields
END_KEYS = ('front', 'rear')

#: fields naming a tabulated curve (``characteristics:``), stored as 1 + its index (0: none)
CURVE_FIELDS = ('buffer_characteristic', 'draw_gear_characteristic')

#: the buffer figures that are each side buffer's when ``buffers_per_end`` > 1: an end's are
#: n times them (n buffers in parallel carry n times the force at the same stroke)
PARALLEL_BUFFER_FIELDS = ('buffer_stiffness', 'buffer_friction', 'buffer_preload',
                          'buffer_final_force', 'buffer_energy')


def curves_of(doc: Any, source: str) -> dict[str, dict]:
    """
    Return a ``characteristics:`` mapping (name -> curve), each curve checked.

    Its preload ramp is checked against the blocked stiffness of the end that names it
    (:meth:`Curves.code`), the rest here.
    """
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: characteristics: a mapping of name -> curve (stroke, '
                          'loading, unloading)')
    for name, curve in doc.items():
        try:
            characteristics.check_curve(curve, np.inf)
        except ValueError as exc:
            raise ConfigError(f'{source}: characteristics: {quote(name)}: {exc}') from None
    return dict(doc)


class Curves:
    """
    The tabulated curves a consist's ends use, numbered as the ends store them (1 + index).

    ``known``: name -> curve (library and consist file); each end's curve scaled by its side
    buffers (:data:`PARALLEL_BUFFER_FIELDS`: a buffer curve is one buffer's) and checked
    against its blocked stiffness once per (name, factor, K_b).
    """

    def __init__(self, known: Mapping[str, dict]):
        self.known = known
        self.arrays: list[tuple[np.ndarray, np.ndarray, np.ndarray, float]] = []
        self._codes: dict[tuple[str, float, float], int] = {}

    def code(self, name: str, factor: float, kb: float, where: str) -> float:
        """Return the number (1 + index) of curve ``name`` times ``factor``; none is 0."""
        if name == '':
            return 0.0
        if name not in self.known:
            raise ConfigError(clip(f'{where}: unknown characteristic {quote(name)} (known: '
                                   f'{", ".join(sorted(self.known)) or "none"})'))
        key = (name, factor, kb)
        if key not in self._codes:
            try:
                d, load, unload = characteristics.check_curve(self.known[name], kb)
            except ValueError as exc:
                raise ConfigError(f'{where}: characteristic {quote(name)}: {exc}') from None
            preload = factor * float(self.known[name]['loading'][0])
            self.arrays.append((d, factor * load, factor * unload, preload))
            self._codes[key] = len(self.arrays)
        return float(self._codes[key])


def ends_resolved(merged: dict[str, Any], own: Mapping[str, Any], curves: Curves,
                  where: str) -> dict[str, Any]:
    """
    Return a vehicle's complete fields with its buffers in parallel and its curves numbered.

    ``own``: the fields the type and the vehicle entry give (not the defaults). With
    ``buffers_per_end`` n, each buffer figure of :data:`PARALLEL_BUFFER_FIELDS` the type or
    entry gives (also in ``front:`` / ``rear:``) is one buffer's: the end's is n times it;
    a default (the parameter's end) is the end's already. A named curve (:data:`CURVE_FIELDS`)
    becomes its code, its last stroke the device's stroke, a buffer curve n times its forces.
    """
    n = float(merged['buffers_per_end'])
    out = dict(merged)
    for key in (None,) + tuple(k for k in END_KEYS if k in out):
        given = own if key is None else (own.get(key) or {})
        row = out if key is None else dict(out[key])
        for field in PARALLEL_BUFFER_FIELDS:
            if field in given and n != 1.0:
                row[field] = n * float(given[field])
        for field in CURVE_FIELDS:
            name = row.get(field, '' if key else merged[field])
            if key is not None and field not in row:
                continue
            device = field[:-len('_characteristic')]
            factor = n if device == 'buffer' else 1.0
            kb = float(row.get('blocked_stiffness', merged['blocked_stiffness']))
            row[field] = curves.code(name, factor, kb, f'{where}: {field}')
            if row[field]:
                row[f'{device}_stroke'] = float(curves.arrays[int(row[field]) - 1][0][-1])
        if key is not None:
            out[key] = row
    return out


def resistance_laws(fields: dict[str, np.ndarray], counts, gravity: float) -> None:
    """
    Replace the Davis coefficients of the vehicles on another law by that law's (in place).

    ``fields``: numeric field -> array (per entry of ``counts`` vehicles, or per vehicle with
    counts 1). The laws are quadratics in v, so the kernel's Davis form carries them exactly
    (:func:`~train_dynamics.physics.resistance.davis_of_law`); Sauthoff's n is the number of
    vehicles on it; ``gravity`` [m/s^2] makes the weight m g of the laws' specific
    resistance.
    """
    law = fields['resistance_law']
    other = law > 0.0
    if not other.any():
        return
    n = int(np.sum(np.asarray(counts)[law == resistance.RESISTANCE_LAWS.index('sauthoff')]))
    a, b, c = resistance.davis_of_law(
        law, fields['mass'], strahl_k=fields['strahl_k'], sauthoff_c=fields['sauthoff_c'],
        sauthoff_area=fields['sauthoff_area'], wind=fields['resistance_wind'], n=n,
        gravity=gravity)
    for name, value in (('davis_a', a), ('davis_b', b), ('davis_c', c)):
        fields[name] = np.where(other, value, fields[name])


def pretension_strokes(couplings, tables, rear, front, rear_of, front_of, source) -> None:
    """
    Set the strokes of pretensioned couplings to the travel their tables leave (in place).

    At rest the draw gear is already stretched and the buffers compressed by the
    pretension (:func:`~train_dynamics.physics.characteristics.pretension_table`): each
    blocks after the rest of its stroke, the span of its table. A pretensioned coupling has
    no free play (the screw coupling is tightened): ConfigError otherwise.
    """
    p = np.maximum(rear['coupling_pretension'][rear_of], front['coupling_pretension'][front_of])
    for j in np.flatnonzero(p > 0.0):
        if couplings['draw_gear_slack'][j] > 0.0 or couplings['buffer_slack'][j] > 0.0:
            raise ConfigError(f'{source}: coupling {j + 1}: coupling_pretension {p[j]:g} N '
                              'needs no free play (buffer_slack and draw_gear_slack 0): a '
                              'tightened screw coupling has none')
        couplings['draw_gear_stroke'][j] = characteristics.table_span(tables[:, j], 0)
        couplings['buffer_stroke'][j] = characteristics.table_span(tables[:, j], 1)
