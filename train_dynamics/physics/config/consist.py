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

Couplings. A vehicle's buffer and draw-gear constants describe a connection between two such
vehicles, as the paper's constants do. Coupler i joins vehicles i and i+1 (a, b); it takes
the harmonic mean 2 k_a k_b / (k_a + k_b) of each stiffness and friction constant and of the
blocked stiffness (springs in series), and the arithmetic mean of each stroke and slack (the
``connection`` of each field in the table). Two identical vehicles give their own values
(exactly).

Errors (unknown field, missing type, non-physical value) raise
:class:`~train_dynamics.physics.config.spec.ConfigError` naming the file, the vehicle and the
field. Never imports rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from train_dynamics.physics.config import spec
from train_dynamics.physics.config.budgets import fmt_bytes
from train_dynamics.physics.config.files import config_dirs, FastRosParamLoader, resolve_path
from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.physics.config.table import (MAX_VEHICLES, PARAMETERS, validate_value,
                                                 VEHICLE_PARAMETERS)
from train_dynamics.quoting import clip, quote
import yaml

#: the fields a vehicle type may set (each a simulator parameter, see PARAM_OF)
VEHICLE_FIELDS = tuple(VEHICLE_PARAMETERS)

#: vehicle field -> simulator parameter, where the names differ
PARAM_OF = {f: s.name for f, s in VEHICLE_PARAMETERS.items() if f != s.name}

#: connection constants: harmonic mean (springs in series) and arithmetic mean
HARMONIC = tuple(f for f, s in VEHICLE_PARAMETERS.items() if s.connection == spec.HARMONIC)
ARITHMETIC = tuple(f for f, s in VEHICLE_PARAMETERS.items() if s.connection == spec.ARITHMETIC)

#: per-coupler constants in the order the kernel stores them
COUPLER_FIELDS = ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
                  'draw_gear_friction', 'draw_gear_slack', 'buffer_slack', 'draw_gear_stroke',
                  'buffer_stroke', 'blocked_stiffness')

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
    if field not in VEHICLE_FIELDS:
        raise ConfigError(f'{where}: unknown field {quote(field)} (fields: '
                          f'{", ".join(VEHICLE_FIELDS)})')
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


def defaults_of(values: dict[str, Any]) -> dict[str, Any]:
    """Return each vehicle field's default: the simulator parameter of the same name."""
    out = {}
    for field in VEHICLE_FIELDS:
        param = PARAM_OF.get(field, field)
        out[field] = values.get(param, PARAMETERS[param].default)
    return out


@dataclass
class Consist:
    """The vehicles front to rear: their type names and each field's values (arrays of N)."""

    types: list[str]
    fields: dict[str, np.ndarray]      # numeric fields, arrays of N
    regimes: list[str]                 # brake_regime per vehicle

    @property
    def n(self) -> int:
        """Return the number of vehicles."""
        return len(self.types)

    def __getitem__(self, field: str) -> np.ndarray:
        """Return one numeric field of every vehicle (array of N)."""
        return self.fields[field]

    @property
    def locomotives(self) -> list[int]:
        """Return the 0-based indices of the vehicles with traction or dynamic brake."""
        f = self.fields
        return np.flatnonzero((f['max_tractive_force'] > 0.0)
                              | (f['max_dynamic_brake_force'] > 0.0)).tolist()

    def coupler(self, field: str) -> np.ndarray:
        """Return the connection value of a field, one per coupler: N-1 values."""
        a = self.fields[field][:-1]
        b = self.fields[field][1:]
        if field in HARMONIC:
            return connection_harmonic(a, b)
        if field in ARITHMETIC:
            return np.where(a == b, a, 0.5 * (a + b))
        raise KeyError(field)

    def coupler_array(self) -> np.ndarray:
        """Return the (9, N-1) array of :data:`COUPLER_FIELDS` per coupler."""
        return np.array([self.coupler(f) for f in COUPLER_FIELDS])


def connection_harmonic(a, b) -> np.ndarray:
    """Return 2 a b / (a + b) (springs in series): a when a == b, 0 when either is 0."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        mean = np.where(a + b > 0.0, 2.0 * a * b / (a + b), 0.0)
    return np.where(a == b, a, mean)


def _make(entries: list[tuple[str, dict[str, Any], int]], source: str) -> Consist:
    """
    Build a Consist from (type, complete field dict, count) entries of a file.

    Cross-field checks once per entry (on arrays of the entries, each named by its first
    vehicle); the arrays are the entries' fields repeated ``count`` times (the caller bounded
    the sum of the counts).
    """
    counts = np.array([c for _, _, c in entries], dtype=np.int64)
    numeric = [f for f in VEHICLE_FIELDS if f != 'brake_regime']
    per_entry = {f: np.array([e[1][f] for e in entries], dtype=float) for f in numeric}
    firsts = np.concatenate(([1], 1 + np.cumsum(counts[:-1])))
    labels = [f'{first} ({name})' for first, (name, _, _) in zip(firsts, entries)]
    check_friction_below_stiffness(per_entry, f'{source}: ', 'vehicle', labels)
    check_traction_power(per_entry, f'{source}: ', labels)
    n = int(counts.sum())
    if n < 2:
        raise ConfigError(f'{source}: a train needs at least 2 vehicles, got {n}')
    fields = {f: np.repeat(a, counts) for f, a in per_entry.items()}
    types = [name for name, _, c in entries for _ in range(c)]
    regimes = [f['brake_regime'] for _, f, c in entries for _ in range(c)]
    return Consist(types, fields, regimes)


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
    unknown = set(doc) - {'vehicle_types', 'vehicles'}
    if unknown:
        raise ConfigError(clip(f'{source}: unknown key(s) '
                               f'{", ".join(sorted(quote(k) for k in unknown))} '
                               '(expected vehicle_types, vehicles)'))
    types = library_types()
    types.update(_types_of(doc.get('vehicle_types'), source))
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
        entries.append((name, {**defaults, **types[name], **overrides}, count))
    return _make(entries, source)


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
    fields = {f: np.full(n, float(v)) for f, v in defaults.items() if f != 'brake_regime'}
    fields['mass'] = np.array([float(m) for m in masses])
    return Consist(['coach'] * n, fields, [defaults['brake_regime']] * n)


def consist_of(values: dict[str, Any], base_dir: str | None = None) -> Consist:
    """Return the consist of a parameter set: its ``consist_file``, else the uniform train."""
    name = values.get('consist_file', '')
    if name:
        return load_consist(name, values, base_dir)
    return uniform_consist(values)
