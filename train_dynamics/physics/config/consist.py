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
from typing import Any, Mapping

import numpy as np
from train_dynamics.physics.config import spec
from train_dynamics.physics.config.files import config_dirs, resolve_path, RosParamLoader
from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.physics.config.table import PARAMETERS, validate_value, VEHICLE_PARAMETERS
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

LIBRARY = 'vehicles.yaml'


def check_friction_below_stiffness(fields: Mapping[str, Any], where: str = '') -> None:
    """
    Raise :class:`ConfigError` unless friction < stiffness for buffers and draw gear (eqs. 2-3).

    Otherwise the force would change sign on unloading. ``fields``: numbers or arrays (one
    value per coupler; the first failing one is named); ``where`` prefixes the message.
    """
    for stiff, fric, rule in _FRICTION_PAIRS:
        k = np.atleast_1d(np.asarray(fields[stiff], dtype=float))
        f = np.broadcast_to(np.asarray(fields[fric], dtype=float), k.shape)
        bad = np.flatnonzero(~(f < k))
        if bad.size:
            i = bad[0]
            at = f' at coupler {i + 1}' if k.size > 1 else ''
            raise ConfigError(f'{where}{fric} must be < {stiff} ({rule}; {f[i]:g} >= {k[i]:g}'
                              f'{at}), or the force would change sign on unloading')


def _read_yaml(path: Path) -> Any:
    try:
        with open(path, encoding='utf-8') as fh:
            return yaml.load(fh, Loader=RosParamLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(f'cannot read {path}: {exc}'.splitlines()[0]) from None


def check_field(field: str, value: Any, where: str) -> Any:
    """Return ``value`` validated as vehicle field ``field``; ConfigError names ``where``."""
    if field not in VEHICLE_FIELDS:
        raise ConfigError(f'{where}: unknown field {field!r} (fields: '
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
        fields = fields or {}
        if not isinstance(fields, dict):
            raise ConfigError(f'{source}: vehicle type {name!r}: fields must be a mapping')
        types[str(name)] = {k: check_field(k, v, f'{source}: vehicle type {name!r}')
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
        return [i for i in range(self.n)
                if f['max_tractive_force'][i] > 0.0 or f['max_dynamic_brake_force'][i] > 0.0]

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


def _make(rows: list[tuple[str, dict[str, Any]]], source: str) -> Consist:
    """Build a Consist from (type, complete field dict) rows of a file; cross-field checks."""
    checked: set[int] = set()
    for k, (name, f) in enumerate(rows, start=1):
        if id(f) not in checked:        # a vehicle repeated by count: its fields once
            check_friction_below_stiffness(f, f'{source}: vehicle {k} ({name}): ')
            checked.add(id(f))
    if len(rows) < 2:
        raise ConfigError(f'{source}: a train needs at least 2 vehicles, got {len(rows)}')
    numeric = [f for f in VEHICLE_FIELDS if f != 'brake_regime']
    fields = {f: np.array([r[1][f] for r in rows], dtype=float) for f in numeric}
    return Consist([r[0] for r in rows], fields, [r[1]['brake_regime'] for r in rows])


def load_consist(path: str, values: dict[str, Any], base_dir: str | None = None) -> Consist:
    """
    Read a consist file; ``values`` are the simulator parameters (the fields' defaults).

    Raise ConfigError naming the file, the vehicle (1-based, with its type) and the field.
    """
    file = resolve_path(path, base_dir)
    source = str(file)
    doc = _read_yaml(file)
    if not isinstance(doc, dict):
        raise ConfigError(f'{source}: a consist file is a mapping with vehicles: (and '
                          'optionally vehicle_types:)')
    unknown = set(doc) - {'vehicle_types', 'vehicles'}
    if unknown:
        raise ConfigError(f'{source}: unknown key(s) {", ".join(sorted(map(str, unknown)))} '
                          '(expected vehicle_types, vehicles)')
    types = library_types()
    types.update(_types_of(doc.get('vehicle_types'), source))
    vehicles = doc.get('vehicles')
    if not isinstance(vehicles, list) or not vehicles:
        raise ConfigError(f'{source}: vehicles: must be a non-empty list, front to rear')
    defaults = defaults_of(values)
    rows: list[tuple[str, dict[str, Any]]] = []
    for k, entry in enumerate(vehicles, start=1):
        where = f'{source}: vehicles[{k}]'
        if not isinstance(entry, dict) or 'type' not in entry:
            raise ConfigError(f'{where}: each entry needs type: NAME')
        entry = dict(entry)
        name = str(entry.pop('type'))
        if name not in types:
            raise ConfigError(f'{where}: unknown vehicle type {name!r} (known: '
                              f'{", ".join(sorted(types))})')
        count = entry.pop('count', 1)
        if not isinstance(count, int) or isinstance(count, bool) or count < 1:
            raise ConfigError(f'{where} ({name}): count: must be an integer >= 1, got {count!r}')
        overrides = {f: check_field(f, v, f'{where} ({name})') for f, v in entry.items()}
        merged = {**defaults, **types[name], **overrides}
        rows.extend((name, merged) for _ in range(count))
    return _make(rows, source)


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
