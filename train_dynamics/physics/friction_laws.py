"""
Friction laws of brake blocks and pads: the shipped materials and the user's, one table.

A vehicle's ``friction_material`` names a law: ``paper`` (the paper's eq. 13, built in: no
law, the force is adhesion_coefficient m g p / p_max) or an entry of a ``friction_materials:``
mapping, in the vehicle library ``config/vehicles.yaml`` (where the shipped materials
``cast_iron``, ``composite_k``, ``composite_ll`` and ``disc`` are, with their sources) or in a
consist file (its entries add to the library's or replace one of the same name). An entry
is one of two forms (units: speed [m/s] and block or pad force [N], unless the entry says
``speed_unit: km/h`` and/or ``force_unit: kN``; F is the force of ONE block or pad, the
vehicle's normal force over ``brake_blocks``)::

    friction_materials:
      my_block:                  # a table: mu over speed and block force
        speeds: [0.0, 8.0, 16.0, 33.0]           # ascending, at most MAX_SPEEDS
        forces: [10000.0, 40000.0]               # ascending, at most MAX_FORCES (optional)
        mu: [[0.32, 0.26], [0.27, 0.22], [0.24, 0.20], [0.21, 0.18]]   # a row per speed
      my_karwatzki:              # Karwatzki-type coefficients
        coefficients: {a: 0.024, b: 61312.5, c: 12262.5, d: 27.78, e: 5.556}

Table: bilinear between the knots, clamped at the ends of each axis (beyond the last speed
or force the value at it); without ``forces`` ``mu`` is one value per speed.
Coefficients: mu = a (F + b) / (F + c) * (v + d) / (v + e), a [-], b and c in the force
unit, d and e in the speed unit (Karwatzki's cast-iron formula, ORE B 126, has this form;
:func:`karwatzki_coefficients`). Every law is checked when read: 0 < mu <= 1 everywhere
(a table's values; the coefficients' mu at the corners F, v in {0, infinity}: the form is
monotonic in each of F and v, so its extremes are there), knots ascending, sizes within
the kernel's (kernel/friction.py).

A law is a vector of numbers the kernel reads per vehicle (kernel/friction.py); the
Python side evaluates the same compiled function (:meth:`FrictionLaw.mu`).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping

import numpy as np

from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.physics.kernel import friction as _kernel
from train_dynamics.quoting import quote

#: the built-in law: the paper's eq. (13), no friction law
PAPER = 'paper'
#: the shipped materials of the vehicle library, in their historical order (their index is
#: their code in :data:`train_dynamics.physics.friction.MATERIAL_CODES`; paper is 0)
SHIPPED = ('paper', 'cast_iron', 'composite_k', 'composite_ll', 'disc')

#: the units an entry may give its speeds and forces in: name -> factor to SI
SPEED_UNITS = {'m/s': 1.0, 'km/h': 1.0 / 3.6}
FORCE_UNITS = {'N': 1.0, 'kN': 1000.0}
#: the keys of an entry
_TABLE_KEYS = {'speeds', 'forces', 'mu'}
_COEFF_KEYS = ('a', 'b', 'c', 'd', 'e')
_UNIT_KEYS = {'speed_unit', 'force_unit', 'source'}


@dataclass(frozen=True)
class FrictionLaw:
    """A friction law: its name and the kernel's vector (kernel/friction.py, LAW_LEN)."""

    name: str
    vector: np.ndarray

    @property
    def paper(self) -> bool:
        """Tell whether this is the paper's eq. (13) (no law)."""
        return self.vector[0] == _kernel.PAPER_LAW

    def mu(self, v: float, block_force: float) -> float:
        """Return the friction coefficient [-] at v [m/s] and block force [N]."""
        return float(_kernel.law_friction(self.vector, float(v), float(block_force)))


def paper_law() -> FrictionLaw:
    """Return the paper's eq. (13): no friction law."""
    return FrictionLaw(PAPER, np.zeros(_kernel.LAW_LEN))


def coefficient_law(name: str, a: float, b: float, c: float, d: float, e: float,
                    where: str = '') -> FrictionLaw:
    """
    Return the Karwatzki-type law mu = a (F + b) / (F + c) (v + d) / (v + e) (SI: N, m/s).

    ConfigError (prefixed ``where``) unless a > 0, b, d >= 0, c, e > 0 and mu <= 1 at the
    four corners F, v in {0, infinity} (module docstring).
    """
    vals = (a, b, c, d, e)
    if not all(isinstance(x, float) and math.isfinite(x) for x in vals):
        raise ConfigError(f'{where}coefficients a, b, c, d, e must be finite numbers')
    if not (a > 0.0 and b >= 0.0 and c > 0.0 and d >= 0.0 and e > 0.0):
        raise ConfigError(f'{where}coefficients: need a > 0, b >= 0, c > 0, d >= 0, e > 0 '
                          f'(got {", ".join(f"{x:g}" for x in vals)}): mu would not stay '
                          'positive and finite')
    corners = [a * fb * fv for fb in (b / c, 1.0) for fv in (d / e, 1.0)]
    if max(corners) > 1.0:
        raise ConfigError(f'{where}coefficients give mu up to {max(corners):.3g} (> 1) at '
                          'the ends of the speed and force ranges')
    vector = np.zeros(_kernel.LAW_LEN)
    vector[:6] = (_kernel.COEFF_LAW, a, b, c, d, e)
    return FrictionLaw(name, vector)


def karwatzki_coefficients(g: float = 9.81) -> tuple[float, float, float, float, float]:
    """
    Return (a, b, c, d, e) [-, N, N, m/s, m/s] of Karwatzki's cast-iron (P10) formula.

    mu = 0.6 (16 K + 100) / (80 K + 100) (V + 100) / (5 V + 100), K the block force in
    tonnes-force, V [km/h] (ORE B 126, as used by TrainDy), is the coefficient form with
    a = 0.6 (16 / 80) (1 / 5) = 0.024, b = 6.25 t g 1000, c = 1.25 t g 1000, d = 100 / 3.6,
    e = 20 / 3.6.
    """
    return 0.024, 6250.0 * g, 1250.0 * g, 100.0 / 3.6, 20.0 / 3.6


def _numbers(value: Any, what: str, where: str) -> np.ndarray:
    """Return a list of numbers as a float array; ConfigError otherwise."""
    if not isinstance(value, list) or not value or not all(
            isinstance(x, (int, float)) and not isinstance(x, bool) for x in value):
        raise ConfigError(f'{where}{what}: a non-empty list of numbers')
    out = np.array(value, dtype=float)
    if not np.all(np.isfinite(out)):
        raise ConfigError(f'{where}{what}: every value must be finite')
    return out


def table_law(name: str, speeds, forces, mu, where: str = '') -> FrictionLaw:
    """
    Return the table law of mu [-] over speeds [m/s] and block forces [N] (SI, checked).

    ``mu``: one row per speed, one value per force (``forces`` None: one value per speed).
    """
    v = np.asarray(speeds, dtype=float)
    f = np.array([0.0]) if forces is None else np.asarray(forces, dtype=float)
    m = np.asarray(mu, dtype=float).reshape(len(v), len(f)) if forces is None \
        else np.asarray(mu, dtype=float)
    if len(v) > _kernel.MAX_SPEEDS or len(f) > _kernel.MAX_FORCES:
        raise ConfigError(f'{where}at most {_kernel.MAX_SPEEDS} speeds and '
                          f'{_kernel.MAX_FORCES} forces (got {len(v)} and {len(f)})')
    if m.shape != (len(v), len(f)):
        raise ConfigError(f'{where}mu: {len(v)} rows (one per speed) of {len(f)} values (one '
                          'per force) expected')
    for what, knots in (('speeds', v), ('forces', f)):
        if np.any(knots < 0.0) or np.any(np.diff(knots) <= 0.0):
            raise ConfigError(f'{where}{what}: must be >= 0 and strictly ascending')
    if not np.all((m > 0.0) & (m <= 1.0)):
        raise ConfigError(f'{where}mu: every value must be in (0, 1] (got {m.min():g} to '
                          f'{m.max():g})')
    vector = np.zeros(_kernel.LAW_LEN)
    vector[:3] = (_kernel.TABLE_LAW, len(v), len(f))
    vector[_kernel.V0:_kernel.V0 + len(v)] = v
    vector[_kernel.F0:_kernel.F0 + len(f)] = f
    for i in range(len(v)):
        start = _kernel.MU0 + i * _kernel.MAX_FORCES
        vector[start:start + len(f)] = m[i]
    return FrictionLaw(name, vector)


def law_of_entry(name: str, entry: Any, where: str) -> FrictionLaw:
    """Return the law of one ``friction_materials:`` entry (module docstring), checked."""
    where = f'{where}: friction_materials: {quote(name)}: '
    if not isinstance(entry, dict):
        raise ConfigError(f'{where}a mapping: speeds/forces/mu (a table) or coefficients')
    unknown = set(entry) - _TABLE_KEYS - _UNIT_KEYS - {'coefficients'}
    if unknown:
        raise ConfigError(f'{where}unknown key(s) {", ".join(sorted(map(str, unknown)))} '
                          '(speeds, forces, mu, coefficients, speed_unit, force_unit, source)')
    units = []
    for key, table in (('speed_unit', SPEED_UNITS), ('force_unit', FORCE_UNITS)):
        unit = entry.get(key, next(iter(table)))
        if unit not in table:
            raise ConfigError(f'{where}{key}: {quote(unit)} is not one of {", ".join(table)}')
        units.append(table[unit])
    sv, sf = units
    if 'coefficients' in entry:
        if set(entry) & _TABLE_KEYS:
            raise ConfigError(f'{where}either a table (speeds, mu) or coefficients, not both')
        coeff = entry['coefficients']
        if not isinstance(coeff, dict) or set(coeff) != set(_COEFF_KEYS):
            raise ConfigError(f'{where}coefficients: a mapping of a, b, c, d, e (mu = a (F + '
                              'b) / (F + c) (v + d) / (v + e))')
        try:
            a, b, c, d, e = (float(coeff[k]) for k in _COEFF_KEYS)
        except (TypeError, ValueError):
            raise ConfigError(f'{where}coefficients: numbers expected') from None
        return coefficient_law(name, a, b * sf, c * sf, d * sv, e * sv, where)
    if not {'speeds', 'mu'} <= set(entry):
        raise ConfigError(f'{where}a table needs speeds and mu (and optionally forces)')
    speeds = _numbers(entry['speeds'], 'speeds', where) * sv
    forces = None if entry.get('forces') is None \
        else _numbers(entry['forces'], 'forces', where) * sf
    mu = entry['mu']
    if forces is None:
        mu = _numbers(mu, 'mu', where)
    elif not isinstance(mu, list) or not all(isinstance(row, list) for row in mu):
        raise ConfigError(f'{where}mu: a list of rows (one per speed), each a list of values '
                          '(one per force)')
    else:
        mu = [_numbers(row, 'mu', where) for row in mu]
        if any(len(row) != len(forces) for row in mu):
            raise ConfigError(f'{where}mu: each row needs one value per force '
                              f'({len(forces)})')
    if forces is None and len(mu) != len(speeds):
        raise ConfigError(f'{where}mu: one value per speed ({len(speeds)}) expected')
    return table_law(name, speeds, forces, mu, where)


def laws_of(doc: Any, source: str) -> dict[str, FrictionLaw]:
    """Return the laws of a ``friction_materials:`` mapping (None: none); ``paper`` is refused."""
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: friction_materials: a mapping of name -> law')
    out = {}
    for name, entry in doc.items():
        if not isinstance(name, str) or not name:
            raise ConfigError(f'{source}: friction_materials: name {quote(name)} is not a '
                              'string')
        if name == PAPER:
            raise ConfigError(f'{source}: friction_materials: {PAPER} is eq. 13 of the paper, '
                              'built in; give the law another name')
        out[name] = law_of_entry(name, entry, source)
    return out


def library_laws() -> dict[str, FrictionLaw]:
    """Return the laws of the vehicle library's ``friction_materials:`` (config/vehicles.yaml)."""
    from train_dynamics.physics.config.files import config_dirs, FastRosParamLoader, resolve_path
    import yaml
    path = resolve_path('vehicles.yaml', str(config_dirs()[0]))
    try:
        with open(path, encoding='utf-8') as fh:
            doc = yaml.load(fh, Loader=FastRosParamLoader) or {}
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f'cannot read {path}: {exc}'.splitlines()[0]) from None
    return laws_of(doc.get('friction_materials') if isinstance(doc, dict) else None, str(path))


def resolve(names, laws: Mapping[str, FrictionLaw], where: str = '') -> list[FrictionLaw]:
    """
    Return the laws of ``names`` (paper first, then the others in order of first use).

    ConfigError naming the unknown material and the known ones.
    """
    out = {PAPER: paper_law()}
    for name in names:
        if name in out:
            continue
        if name not in laws:
            known = ', '.join([PAPER] + sorted(laws))
            raise ConfigError(f'{where}friction_material {quote(name)} is not a friction law '
                              f'(known: {known}; a consist file or the vehicle library may '
                              'add one under friction_materials:)')
        out[name] = laws[name]
    return list(out.values())
