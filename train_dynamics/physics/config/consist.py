"""
The consist: which vehicles make the train, front to rear, and the couplings between them.

A consist file (parameter ``consist_file``) is YAML::

    vehicle_types:            # optional: add to (or replace) config/vehicles.yaml's types
      my_wagon: {mass: 80000.0, length: 14.0, brake_regime: G}
    vehicles:                 # front to rear
      - {type: electric_passenger_locomotive}
      - {type: my_wagon, count: 20, davis_a: 900.0}    # count repeats; fields override

The fields a vehicle may set are the parameters with ``vehicle`` in the table
(:data:`~train_dynamics.physics.config.table.VEHICLE_PARAMETERS`; ``mass`` is ``coach_mass``,
``length`` is ``coach_length``): the parameter's value is the field of the uniform train (no
consist file) and the default of a type that leaves the field out; its range is the field's.

Couplings: two vehicle ends in series. A vehicle's buffer and draw-gear fields are those of
each of its ends (its datasheet: stiffness and friction constant [N/m] of the paper's law,
stroke, free play, blocked stiffness); ``front:`` and ``rear:`` mappings in a type or a vehicle
entry give one end its own values. Coupler i joins the rear end of vehicle i to the front end
of vehicle i+1 (:func:`coupling_of_ends`): the springs are in series, so the compliances of the
loading branches (k + k_friction) add and so do those of the unloading branches
(k - k_friction); strokes add and free play adds (the ``connection`` of each field in the
table). Two identical ends give a coupling of half their stiffness and friction and twice
their travel, exactly.

Whole-coupling constants, where a user has only those: the parameters of the uniform train (no
consist file) are the constants of each coupling (the paper's measured constants are), and a
consist's ``couplings:`` mapping sets constants of every coupling as is. A vehicle type that
leaves an end field out takes the end whose coupling with an identical end is the parameter's
(:func:`end_of_coupling`).

Errors (unknown field, missing type, non-physical value) raise
:class:`~train_dynamics.physics.config.spec.ConfigError` naming the file, the vehicle and the
field. Never imports rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from train_dynamics.physics import characteristics
from train_dynamics.physics.config import spec
from train_dynamics.physics.config.budgets import fmt_bytes
from train_dynamics.physics.config.ends import (CURVE_FIELDS, Curves, curves_of, END_KEYS,
                                                ends_resolved, pretension_strokes,
                                                resistance_laws)
from train_dynamics.physics.config.files import config_dirs, FastRosParamLoader, resolve_path
from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.physics.config.table import (MAX_VEHICLES, PARAMETERS, validate_value,
                                                 VEHICLE_PARAMETERS)
# as modules: they import this package's table first (the attributes are read at call time)
from train_dynamics.physics.kernel import layout
from train_dynamics.quoting import clip, quote
import yaml

#: the fields a vehicle type may set (each a simulator parameter, see PARAM_OF)
VEHICLE_FIELDS = tuple(VEHICLE_PARAMETERS)

#: vehicle field -> simulator parameter, where the names differ
PARAM_OF = {f: s.name for f, s in VEHICLE_PARAMETERS.items() if f != s.name}

#: coupling constants: ends in series (compliances add) and travels that add
SERIES = tuple(f for f, s in VEHICLE_PARAMETERS.items() if s.connection == spec.SERIES)
ADDED = tuple(f for f, s in VEHICLE_PARAMETERS.items() if s.connection == spec.ADDED)

#: per-coupler constants in the order the kernel stores them
COUPLER_FIELDS = ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
                  'draw_gear_friction', 'draw_gear_slack', 'buffer_slack', 'draw_gear_stroke',
                  'buffer_stroke', 'blocked_stiffness')

#: the fields of a preloaded, progressive or tabulated end and the screw coupling's
#: pretension (a coupling of such ends is tabled)
CHARACTERISTIC_FIELDS = tuple(f'{device}_{what}' for device in ('buffer', 'draw_gear')
                              for what in ('preload', 'final_force', 'energy',
                                           'characteristic')) + ('coupling_pretension',)

#: the fields one vehicle end may have of its own (``front:`` / ``rear:``)
END_FIELDS = COUPLER_FIELDS + CHARACTERISTIC_FIELDS

#: the parameters a consist is built from: a configuration whose values of these are
#: unchanged keeps its consist (no file is read again)
CONSIST_PARAMETERS = frozenset({'consist_file', 'num_coaches', 'masses',
                                *(s.name for s in VEHICLE_PARAMETERS.values())})

#: friction below stiffness, for buffers and draw gear: (stiffness, friction, in symbols)
_FRICTION_PAIRS = (('buffer_stiffness', 'buffer_friction', 'k_f < k_e'),
                   ('draw_gear_stiffness', 'draw_gear_friction', 'k_fc < k_ec'))

#: a locomotive's force limits and their power limits: (force, power)
_POWER_PAIRS = (('max_tractive_force', 'max_power'),
                ('max_dynamic_brake_force', 'max_dynamic_brake_power'))

LIBRARY = 'vehicles.yaml'

#: [bytes] the largest consist file read (~20000 lines, ~0.5 s to parse): a parameter set
#: naming a file reads it on the node's executor, so its cost is bounded
MAX_FILE_BYTES = 1 << 20


def _at(i: int, size: int, unit: str, labels: Sequence[str] | None) -> str:
    """Return ' at <unit> <label>' of element ``i`` of arrays of ``size`` ('' for one value)."""
    if size <= 1:
        return ''
    return f' at {unit} {labels[i] if labels is not None else i + 1}'


def check_friction_below_stiffness(fields: Mapping[str, Any], where: str = '',
                                   unit: str = 'coupler',
                                   labels: Sequence[str] | None = None) -> None:
    """
    Raise :class:`ConfigError` unless friction < stiffness for buffers and draw gear (eqs. 2-3).

    Otherwise the force would change sign on unloading. ``fields``: numbers or arrays (one
    value per ``unit``; the first failing one is named, by ``labels`` when given, else by its
    1-based index); ``where`` prefixes the message.
    """
    for stiff, fric, rule in _FRICTION_PAIRS:
        k = np.atleast_1d(np.asarray(fields[stiff], dtype=float))
        f = np.broadcast_to(np.asarray(fields[fric], dtype=float), k.shape)
        bad = np.flatnonzero(~(f < k))
        if bad.size:
            i = bad[0]
            raise ConfigError(f'{where}{fric} must be < {stiff} ({rule}; {f[i]:g} >= {k[i]:g}'
                              f'{_at(i, k.size, unit, labels)}), or the force would change sign '
                              'on unloading')


def check_traction_power(fields: Mapping[str, Any], where: str = '',
                         labels: Sequence[str] | None = None) -> None:
    """
    Raise :class:`ConfigError` for a force limit without its power limit (traction.py).

    The available force is min(F, P / |v|, mu m g): a vehicle with ``max_tractive_force`` > 0
    and ``max_power`` 0 would pull only at standstill (it crept at mm/s); the same for the
    dynamic brake. ``fields``: numbers or arrays (one per vehicle; the first failing one is
    named, as in :func:`check_friction_below_stiffness`); ``where`` prefixes the message.
    """
    for force, power in _POWER_PAIRS:
        f = np.atleast_1d(np.asarray(fields[force], dtype=float))
        p = np.broadcast_to(np.asarray(fields[power], dtype=float), f.shape)
        bad = np.flatnonzero((f > 0.0) & ~(p > 0.0))
        if bad.size:
            i = bad[0]
            at = _at(i, f.size, 'vehicle', labels)
            raise ConfigError(f'{where}{power} must be > 0 with {force} {f[i]:g} N{at}: the '
                              f'available force min({force}, {power} / |v|) would be 0 at any '
                              'speed; give the power [W] at the wheel rim')


def _read_yaml(path: Path) -> Any:
    """Return the YAML document of ``path``; refuse a file over :data:`MAX_FILE_BYTES` unread."""
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise ConfigError(f'{path}: {fmt_bytes(size)}, more than the limit of '
                              f'{fmt_bytes(MAX_FILE_BYTES)} for a consist file (use count: to '
                              'repeat a vehicle)')
        with open(path, encoding='utf-8') as fh:
            return yaml.load(fh, Loader=FastRosParamLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(clip(f'cannot read {path}: {exc}'.splitlines()[0])) from None


def check_field(field: str, value: Any, where: str) -> Any:
    """Return ``value`` validated as vehicle field ``field``; ConfigError names ``where``."""
    if field in END_KEYS:
        if not isinstance(value, dict):
            raise ConfigError(f'{where}: {field}: a mapping of end fields '
                              f'({", ".join(END_FIELDS)})')
        bad = set(value) - set(END_FIELDS)
        if bad:
            raise ConfigError(f'{where}: {field}: not an end field: {", ".join(sorted(bad))} '
                              f'(end fields: {", ".join(END_FIELDS)})')
        return {k: check_field(k, v, f'{where}: {field}') for k, v in value.items()}
    if field not in VEHICLE_FIELDS:
        raise ConfigError(f'{where}: unknown field {quote(field)} (fields: '
                          f'{", ".join(VEHICLE_FIELDS)}, {", ".join(END_KEYS)})')
    param = PARAM_OF.get(field, field)
    try:
        return validate_value(param, value)
    except ConfigError as exc:
        reason = str(exc).split(': ', 1)[-1]
        raise ConfigError(f'{where}: {field}: {reason}') from None


def _types_of(doc: Any, source: str) -> dict[str, dict[str, Any]]:
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: vehicle_types must be a mapping of name -> fields')
    types = {}
    for name, fields in doc.items():
        if not isinstance(name, str):
            raise ConfigError(f'{source}: vehicle type name {quote(name)} is not a string')
        fields = fields or {}
        if not isinstance(fields, dict):
            raise ConfigError(f'{source}: vehicle type {quote(name)}: fields must be a mapping')
        types[name] = {k: check_field(k, v, f'{source}: vehicle type {quote(name)}')
                       for k, v in fields.items()}
    return types


def library_types() -> dict[str, dict[str, Any]]:
    """Return the shipped vehicle library (``config/vehicles.yaml``), checked."""
    path = resolve_path(LIBRARY, str(config_dirs()[0]))
    doc = _read_yaml(path) or {}
    return _types_of(doc.get('vehicle_types'), str(path))


def library_curves() -> dict[str, dict]:
    """Return the shipped tabulated curves (``characteristics:`` of ``config/vehicles.yaml``)."""
    path = resolve_path(LIBRARY, str(config_dirs()[0]))
    doc = _read_yaml(path) or {}
    return curves_of(doc.get('characteristics'), str(path))


def end_of_coupling(field: str, value: float) -> float:
    """
    Return the end value whose coupling with an identical end is ``value`` (a coupling constant).

    Stiffness and friction: 2 k (two such ends in series give k); travel: S / 2. Exact in
    floating point (a factor of 2), so the coupling of two such ends is ``value`` bit for bit.
    """
    if field in SERIES:
        return 2.0 * value
    if field in ADDED:
        return 0.5 * value
    return value


def defaults_of(values: dict[str, Any]) -> dict[str, Any]:
    """
    Return each vehicle field's default from the simulator parameters.

    The parameter of the same name; for an end field the end whose coupling with an identical
    end is the parameter's (:func:`end_of_coupling`: parameters are whole-coupling constants).
    """
    out = {}
    for field in VEHICLE_FIELDS:
        param = PARAM_OF.get(field, field)
        out[field] = end_of_coupling(field, values.get(param, PARAMETERS[param].default))
    return out


def series(a, b) -> np.ndarray:
    """
    Return a b / (a + b), the stiffness of springs a and b joined end to end: compliances add.

    Exactly a / 2 when a == b; 0 when either is 0 (arrays or scalars [N/m]).
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        both = np.where(a + b > 0.0, a * b / (a + b), 0.0)
    return np.where(a == b, 0.5 * a, both)


def coupling_of_ends(rear: Mapping[str, np.ndarray],
                     front: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """
    Return the coupling constants of the rear ends ``rear`` joined to the front ends ``front``.

    Both: end field -> array (one per coupling). The law of each end is the paper's (eqs. 2-3):
    loading branch (k + k_fr)|y|, unloading (k - k_fr)|y|. Under the one force the coupling
    carries, both ends load or unload together, so the coupling's loading stiffness is the
    series of the ends' loading stiffnesses, its unloading stiffness the series of the
    unloading ones: k = (K_load + K_unload) / 2, k_fr = (K_load - K_unload) / 2 (exactly the
    ends' halves when the ends are identical). Blocked stiffness in series; strokes and free
    play add.
    """
    out = {}
    for stiff, fric in (('buffer_stiffness', 'buffer_friction'),
                        ('draw_gear_stiffness', 'draw_gear_friction')):
        ka, fa, kb, fb = rear[stiff], rear[fric], front[stiff], front[fric]
        load = series(ka + fa, kb + fb)
        unload = series(ka - fa, kb - fb)
        same = (ka == kb) & (fa == fb)
        out[stiff] = np.where(same, 0.5 * ka, 0.5 * (load + unload))
        out[fric] = np.where(same, 0.5 * fa, 0.5 * (load - unload))
    for field in COUPLER_FIELDS:
        if field in out:
            continue
        if field in SERIES:
            out[field] = series(rear[field], front[field])
        else:
            out[field] = np.asarray(rear[field], dtype=float) + np.asarray(front[field], float)
    return out


@dataclass
class Consist:
    """
    The vehicles front to rear: type names, each field's values (arrays of N), the couplings.

    ``fields`` holds a vehicle's fields (the end fields of ends without their own values);
    ``couplings`` the constants of each coupling, :data:`COUPLER_FIELDS` -> array of N-1;
    ``tables`` the table rows of each coupling (``layout.TABLE_ROWS``, one column per
    coupling; all 0 for a coupling of linear ends without preload: the paper's law).
    """

    types: list[str]
    fields: dict[str, np.ndarray]      # numeric fields, arrays of N
    regimes: list[str]                 # brake_regime per vehicle
    couplings: dict[str, np.ndarray]   # coupling constants, arrays of N-1
    tables: np.ndarray                 # (len(TABLE_ROWS), N-1)

    @property
    def n(self) -> int:
        """Return the number of vehicles."""
        return len(self.types)

    def __getitem__(self, field: str) -> np.ndarray:
        """Return one numeric field of every vehicle (array of N)."""
        return self.fields[field]

    def choices(self, field: str) -> list[str]:
        """Return a choice field of every vehicle by name (stored as its index, _number)."""
        if field == 'brake_regime':
            return list(self.regimes)
        names = VEHICLE_PARAMETERS[field].choices
        return [names[int(code)] for code in self.fields[field]]

    @property
    def locomotives(self) -> list[int]:
        """Return the 0-based indices of the vehicles with traction or dynamic brake."""
        f = self.fields
        return np.flatnonzero((f['max_tractive_force'] > 0.0)
                              | (f['max_dynamic_brake_force'] > 0.0)).tolist()

    @property
    def remotes(self) -> list[int]:
        """Return the 0-based indices of the distributed-power (remote) locomotives."""
        return [int(i) for i in np.flatnonzero(self.fields['remote'] > 0.5)]

    @property
    def commanded(self) -> list[int]:
        """Return the locomotives that take traction commands: all but the remotes."""
        remotes = self.remotes
        return [i for i in self.locomotives if i not in remotes]

    def coupler(self, field: str) -> np.ndarray:
        """Return one constant of every coupling (:data:`COUPLER_FIELDS`): N-1 values."""
        return self.couplings[field]

    def coupler_array(self) -> np.ndarray:
        """Return the (9, N-1) array of :data:`COUPLER_FIELDS` per coupler."""
        return np.array([self.coupler(f) for f in COUPLER_FIELDS])


def _end(row: dict[str, Any], key: str) -> dict[str, float]:
    """Return the end fields of one end (``front`` or ``rear``) of a complete field dict."""
    own = row.get(key) or {}
    return {f: float(own.get(f, row[f])) for f in END_FIELDS}


def _number(field: str, value: Any) -> float:
    """Return a field's value as a number: a choice (friction_material) as its index."""
    choices = VEHICLE_PARAMETERS[field].choices
    return float(choices.index(value)) if choices else float(value)


def _make(entries: list[tuple[str, dict[str, Any], int]], source: str,
          whole: Mapping[str, float] | None = None, curves=(), gravity: float = 9.81) -> Consist:
    """
    Build a Consist from (type, complete field dict, count) entries of a file.

    Cross-field checks once per entry (on arrays of the entries, each named by its first
    vehicle; each end's buffer and draw gear on their own); the arrays are the entries'
    fields repeated ``count`` times (the caller bounded the sum of the counts). Coupling j
    joins the rear end of vehicle j to the front end of vehicle j + 1
    (:func:`coupling_of_ends`); ``whole``: whole-coupling constants that replace the ends'
    series values in every coupling.
    """
    counts = np.array([c for _, _, c in entries], dtype=np.int64)
    numeric = [f for f in VEHICLE_FIELDS if f != 'brake_regime']
    per_entry = {f: np.array([_number(f, e[1][f]) for e in entries], dtype=float)
                 for f in numeric}
    firsts = np.concatenate(([1], 1 + np.cumsum(counts[:-1])))
    labels = [f'{first} ({name})' for first, (name, _, _) in zip(firsts, entries)]
    ends = {}
    for key in END_KEYS:
        own = [_end(e[1], key) for e in entries]
        ends[key] = {f: np.array([o[f] for o in own]) for f in END_FIELDS}
        check_friction_below_stiffness(ends[key], f'{source}: {key} end: ', 'vehicle', labels)
        for i, end in enumerate(own):
            _check_characteristic(end, f'{source}: vehicle {labels[i]}: {key} end: ')
    check_traction_power(per_entry, f'{source}: ', labels)
    n = int(counts.sum())
    if n < 2:
        raise ConfigError(f'{source}: a train needs at least 2 vehicles, got {n}')
    resistance_laws(per_entry, counts, gravity)
    fields = {f: np.repeat(a, counts) for f, a in per_entry.items()}
    types = [name for name, _, c in entries for _ in range(c)]
    regimes = [f['brake_regime'] for _, f, c in entries for _ in range(c)]
    entry_of = np.repeat(np.arange(len(entries)), counts)
    couplings = coupling_of_ends({f: a[entry_of[:-1]] for f, a in ends['rear'].items()},
                                 {f: a[entry_of[1:]] for f, a in ends['front'].items()})
    for f, v in (whole or {}).items():
        couplings[f] = np.full(n - 1, float(v))
    if whole:
        check_friction_below_stiffness(couplings, f'{source}: couplings: ')
        tables = np.zeros((len(layout.TABLE_ROWS), n - 1))
    else:
        tables = coupling_tables(ends['rear'], ends['front'], entry_of[:-1], entry_of[1:],
                                 curves, source)
        pretension_strokes(couplings, tables, ends['rear'], ends['front'], entry_of[:-1],
                           entry_of[1:], source)
    return Consist(types, fields, regimes, couplings, tables)


def _check_characteristic(end: Mapping[str, float], where: str) -> None:
    """Raise ConfigError unless one end's preload, final force and energy make a curve."""
    for device in ('buffer', 'draw_gear'):
        if not characteristics.has_characteristic(end, device):
            continue
        try:
            characteristics.end_loading(
                0.0, k=end[f'{device}_stiffness'], k_friction=end[f'{device}_friction'],
                stroke=end[f'{device}_stroke'], preload=end[f'{device}_preload'],
                final_force=end[f'{device}_final_force'], energy=end[f'{device}_energy'],
                kb=end['blocked_stiffness'])
        except ValueError as exc:
            raise ConfigError(f'{where}{device}: {exc}') from None


def coupling_tables(rear: Mapping[str, np.ndarray], front: Mapping[str, np.ndarray],
                    rear_of: np.ndarray, front_of: np.ndarray, curves=(),
                    source: str = 'parameters') -> np.ndarray:
    """
    Return the table rows (``layout.TABLE_ROWS``) of every coupling: (len, N-1).

    ``rear``, ``front``: end field -> array per entry; coupling j joins the rear end of entry
    ``rear_of[j]`` to the front end of entry ``front_of[j]``. A coupling whose two ends have
    no preload and no final force keeps the linear law (rows 0); the others get
    :func:`~train_dynamics.physics.characteristics.coupling_table` (the ends' characteristics in
    series: equal force, strokes add), computed once per distinct pair of ends. ``curves``:
    the tabulated curves the ends' codes number; ConfigError (naming ``source``) for a
    pretension more than a device carries.
    """
    out = np.zeros((len(layout.TABLE_ROWS), rear_of.shape[0]))
    done: dict[tuple[int, int], np.ndarray] = {}
    for j, pair in enumerate(zip(rear_of.tolist(), front_of.tolist())):
        if pair not in done:
            a = {f: float(v[pair[0]]) for f, v in rear.items()}
            b = {f: float(v[pair[1]]) for f, v in front.items()}
            if any(characteristics.has_characteristic(e, dev) for e in (a, b)
                   for dev in ('buffer', 'draw_gear')):
                try:
                    done[pair] = characteristics.coupling_table(a, b, layout.TABLE_KNOTS,
                                                                curves)
                except ValueError as exc:
                    raise ConfigError(f'{source}: coupling {j + 1}: {exc}') from None
            else:
                done[pair] = None
        if done[pair] is not None:
            out[:, j] = done[pair]
    return out


def _whole_couplings(doc: Any, source: str) -> dict[str, float]:
    """Return a consist's ``couplings:`` (whole-coupling constants, as the parameters), checked."""
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: couplings: a mapping of coupling constants '
                          f'({", ".join(COUPLER_FIELDS)})')
    bad = set(doc) - set(COUPLER_FIELDS)
    if bad:
        raise ConfigError(f'{source}: couplings: not a coupling constant: '
                          f'{", ".join(sorted(map(str, bad)))} ({", ".join(COUPLER_FIELDS)})')
    return {k: check_field(k, v, f'{source}: couplings') for k, v in doc.items()}


def _count_of(entry: dict[str, Any], where: str) -> int:
    """Return the ``count`` of a vehicles entry (1 when absent), checked."""
    count = entry.pop('count', 1)
    if not isinstance(count, int) or isinstance(count, bool) or count < 1:
        raise ConfigError(f'{where}: count: must be an integer >= 1, got {quote(count)}')
    if count > MAX_VEHICLES:
        raise ConfigError(f'{where}: count: {count}, more than the limit of {MAX_VEHICLES} '
                          'vehicles in a train')
    return count


def load_consist(path: str, values: dict[str, Any], base_dir: str | None = None) -> Consist:
    """
    Read a consist file; ``values`` are the simulator parameters (the fields' defaults).

    Raise ConfigError naming the file, the vehicle (1-based, with its type) and the field.
    The number of vehicles (the sum of the counts) is checked against
    :data:`~train_dynamics.physics.config.table.MAX_VEHICLES` before any per-vehicle array
    is built.
    """
    file = resolve_path(path, base_dir)
    source = str(file)
    doc = _read_yaml(file)
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: a consist file is a mapping with vehicles: (and '
                          'optionally vehicle_types:)')
    unknown = set(doc) - {'vehicle_types', 'vehicles', 'couplings', 'characteristics'}
    if unknown:
        raise ConfigError(clip(f'{source}: unknown key(s) '
                               f'{", ".join(sorted(quote(k) for k in unknown))} '
                               '(expected vehicle_types, vehicles, couplings, '
                               'characteristics)'))
    types = library_types()
    types.update(_types_of(doc.get('vehicle_types'), source))
    curves = Curves({**library_curves(), **curves_of(doc.get('characteristics'), source)})
    vehicles = doc.get('vehicles')
    if not isinstance(vehicles, list) or not vehicles:
        raise ConfigError(f'{source}: vehicles: must be a non-empty list, front to rear')
    if len(vehicles) > MAX_VEHICLES:
        raise ConfigError(f'{source}: vehicles: {len(vehicles)} entries, more than the limit of '
                          f'{MAX_VEHICLES} vehicles in a train')
    defaults = defaults_of(values)
    entries: list[tuple[str, dict[str, Any], int]] = []
    total = 0
    for k, entry in enumerate(vehicles, start=1):
        where = f'{source}: vehicles[{k}]'
        if not isinstance(entry, dict) or 'type' not in entry:
            raise ConfigError(f'{where}: each entry needs type: NAME')
        entry = dict(entry)
        name = entry.pop('type')
        if not isinstance(name, str) or name not in types:
            raise ConfigError(clip(f'{where}: unknown vehicle type {quote(name)} (known: '
                                   f'{", ".join(sorted(types))})'))
        count = _count_of(entry, f'{where} ({name})')
        total += count
        if total > MAX_VEHICLES:
            raise ConfigError(f'{source}: vehicles: {total} vehicles up to vehicles[{k}], more '
                              f'than the limit of {MAX_VEHICLES} vehicles in a train')
        overrides = {f: check_field(f, v, f'{where} ({name})') for f, v in entry.items()}
        merged = {**defaults, **types[name], **overrides}
        for key in END_KEYS:     # an end's own fields: the type's, then the entry's
            merged[key] = {**(types[name].get(key) or {}), **(overrides.get(key) or {})}
        own = {**types[name], **overrides, **{k: merged[k] for k in END_KEYS}}
        merged = ends_resolved(merged, own, curves, f'{where} ({name})')
        entries.append((name, merged, count))
    return _make(entries, source, _whole_couplings(doc.get('couplings'), source),
                 curves.arrays, float(values.get('gravity', 9.81)))


def uniform_consist(values: dict[str, Any]) -> Consist:
    """
    Return the uniform train of the parameters (num_coaches/masses and the constants).

    The parameters are checked as a whole by the configuration (friction below stiffness
    included), not here.
    """
    defaults = defaults_of(values)
    masses = values.get('masses') or [float(values.get('coach_mass', defaults['mass']))] * int(
        values.get('num_coaches', PARAMETERS['num_coaches'].default))
    n = len(masses)
    if n < 2:
        raise ConfigError(f'parameters: a train needs at least 2 vehicles, got {n}')
    curves = Curves(library_curves() if any(defaults[f] for f in CURVE_FIELDS) else {})
    defaults = ends_resolved({**defaults, 'buffers_per_end': 1}, {}, curves, 'parameters')
    fields = {f: np.full(n, _number(f, v)) for f, v in defaults.items() if f != 'brake_regime'}
    fields['mass'] = np.array([float(m) for m in masses])
    resistance_laws(fields, np.ones(n, int), float(values.get('gravity', 9.81)))
    ends = {f: fields[f][1:] for f in COUPLER_FIELDS}
    one = {f: fields[f][:1] for f in END_FIELDS}
    _check_characteristic({f: float(v[0]) for f, v in one.items()}, 'parameters: ')
    zeros = np.zeros(n - 1, int)
    couplings = coupling_of_ends(ends, ends)
    tables = coupling_tables(one, one, zeros, zeros, curves.arrays)
    pretension_strokes(couplings, tables, one, one, zeros, zeros, 'parameters')
    return Consist(['coach'] * n, fields, [defaults['brake_regime']] * n, couplings, tables)


def consist_of(values: dict[str, Any], base_dir: str | None = None) -> Consist:
    """Return the consist of a parameter set: its ``consist_file``, else the uniform train."""
    name = values.get('consist_file', '')
    if name:
        return load_consist(name, values, base_dir)
    return uniform_consist(values)
