"""
The consist: which vehicles make the train, front to rear, and the couplings between them.

A consist file (parameter ``consist_file``) is YAML::

    vehicle_types:            # optional: add to (or replace) config/vehicles.yaml's types
      my_wagon: {mass: 80000.0, length: 14.0, brake_regime: G}
    vehicles:                 # front to rear
      - {type: electric_passenger_locomotive}
      - {type: my_wagon, count: 20, davis_a: 900.0}    # count repeats; fields override

Every field of :data:`VEHICLE_FIELDS` is also a simulator parameter of the same name (``mass``
is ``coach_mass``, ``length`` is ``coach_length``): the value of the uniform train (no
consist file) and the default of a type that leaves the field out.

Couplings. A vehicle's buffer and draw-gear constants describe a connection between two such
vehicles, as the paper's constants do. Coupler i joins vehicles i and i+1 (a, b); it takes
the harmonic mean 2 k_a k_b / (k_a + k_b) of each stiffness and friction constant and of the
blocked stiffness (springs in series), and the arithmetic mean of each stroke and slack. Two
identical vehicles give their own values (exactly).

Errors (unknown field, missing type, non-physical value) raise
:class:`~train_dynamics.physics.parameters.ConfigError` naming the file, the vehicle and the
field. Never imports rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
import sys
from typing import Any

import numpy as np
# parameters imports this module: use its names at call time only (parameters.X)
from train_dynamics.physics import parameters
import yaml

#: the fields a vehicle type may set (each also a simulator parameter, see PARAM_OF)
VEHICLE_FIELDS = (
    'mass', 'length', 'rotating_mass_factor', 'davis_a', 'davis_b', 'davis_c',
    'buffer_stiffness', 'buffer_friction', 'buffer_stroke', 'buffer_slack',
    'draw_gear_stiffness', 'draw_gear_friction', 'draw_gear_stroke', 'draw_gear_slack',
    'blocked_stiffness', 'adhesion_coefficient', 'max_cylinder_pressure', 'brake_regime',
    'max_tractive_force', 'max_power', 'max_dynamic_brake_force', 'max_dynamic_brake_power',
    'traction_build_up_time', 'traction_adhesion', 'dynamic_brake_fade_speed')

#: vehicle field -> simulator parameter, where the names differ
PARAM_OF = {'mass': 'coach_mass', 'length': 'coach_length'}

#: connection constants: harmonic mean (springs in series) and arithmetic mean
HARMONIC = ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
            'draw_gear_friction', 'blocked_stiffness')
ARITHMETIC = ('buffer_stroke', 'buffer_slack', 'draw_gear_stroke', 'draw_gear_slack')

#: per-coupler constants in the order the kernel stores them
COUPLER_FIELDS = ('buffer_stiffness', 'buffer_friction', 'draw_gear_stiffness',
                  'draw_gear_friction', 'draw_gear_slack', 'buffer_slack', 'draw_gear_stroke',
                  'buffer_stroke', 'blocked_stiffness')

LIBRARY = 'vehicles.yaml'


def _error(message: str) -> Exception:
    """Return a ConfigError (looked up late: the parameters module imports this one)."""
    return parameters.ConfigError(message)


def config_dirs() -> list[Path]:
    """Return the folders holding the shipped ``config/`` files: source tree, then installed."""
    dirs = [Path(__file__).resolve().parents[2] / 'config']
    try:   # optional: only present in a sourced ROS 2 environment
        from ament_index_python.packages import get_package_share_directory
        dirs.append(Path(get_package_share_directory('train_dynamics')) / 'config')
    except Exception:  # noqa: B902 - not installed, or the package is not in the index
        pass
    dirs.append(Path(sys.prefix) / 'share' / 'train_dynamics' / 'config')
    return dirs


def resolve_path(name: str, base_dir: str | None = None) -> Path:
    """Return the file ``name``: absolute, else in ``base_dir`` (or cwd), else in ``config/``."""
    path = Path(os.path.expanduser(name))
    if path.is_absolute():
        if path.is_file():
            return path
        raise _error(f'consist_file: file not found: {path}')
    tried = [Path(base_dir or os.getcwd()) / path] + [d / path for d in config_dirs()]
    for candidate in tried:
        if candidate.is_file():
            return candidate
    raise _error(f'consist_file: {name!r} not found (looked in '
                 f'{", ".join(str(t.parent) for t in tried)})')


def _read_yaml(path: Path) -> Any:
    try:
        with open(path, encoding='utf-8') as fh:
            return yaml.load(fh, Loader=parameters._RosParamLoader)
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise _error(f'cannot read {path}: {exc}'.splitlines()[0]) from None


def check_field(field: str, value: Any, where: str) -> Any:
    """Return ``value`` validated as vehicle field ``field``; ConfigError names ``where``."""
    if field not in VEHICLE_FIELDS:
        raise _error(f'{where}: unknown field {field!r} (fields: '
                     f'{", ".join(VEHICLE_FIELDS)})')
    param = PARAM_OF.get(field, field)
    try:
        return parameters.validate_value(param, value)
    except parameters.ConfigError as exc:
        reason = str(exc).split(': ', 1)[-1]
        raise _error(f'{where}: {field}: {reason}') from None


def _types_of(doc: Any, source: str) -> dict[str, dict[str, Any]]:
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise _error(f'{source}: vehicle_types must be a mapping of name -> fields')
    types = {}
    for name, fields in doc.items():
        fields = fields or {}
        if not isinstance(fields, dict):
            raise _error(f'{source}: vehicle type {name!r}: fields must be a mapping')
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
        out[field] = values.get(param, parameters.PARAMETERS[param].default)
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
    """Build a Consist from (type, complete field dict) rows; cross-field checks."""
    for k, (name, f) in enumerate(rows, start=1):
        where = f'{source}: vehicle {k} ({name})'
        for stiff, fric in (('buffer_stiffness', 'buffer_friction'),
                            ('draw_gear_stiffness', 'draw_gear_friction')):
            if not f[fric] < f[stiff]:
                raise _error(f'{where}: {fric}: must be < {stiff} ({f[fric]:g} >= '
                             f'{f[stiff]:g})')
    if len(rows) < 2:
        raise _error(f'{source}: a train needs at least 2 vehicles, got {len(rows)}')
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
        raise _error(f'{source}: a consist file is a mapping with vehicles: (and '
                     'optionally vehicle_types:)')
    unknown = set(doc) - {'vehicle_types', 'vehicles'}
    if unknown:
        raise _error(f'{source}: unknown key(s) {", ".join(sorted(map(str, unknown)))} '
                     '(expected vehicle_types, vehicles)')
    types = library_types()
    types.update(_types_of(doc.get('vehicle_types'), source))
    vehicles = doc.get('vehicles')
    if not isinstance(vehicles, list) or not vehicles:
        raise _error(f'{source}: vehicles: must be a non-empty list, front to rear')
    defaults = defaults_of(values)
    rows: list[tuple[str, dict[str, Any]]] = []
    for k, entry in enumerate(vehicles, start=1):
        where = f'{source}: vehicles[{k}]'
        if not isinstance(entry, dict) or 'type' not in entry:
            raise _error(f'{where}: each entry needs type: NAME')
        entry = dict(entry)
        name = str(entry.pop('type'))
        if name not in types:
            raise _error(f'{where}: unknown vehicle type {name!r} (known: '
                         f'{", ".join(sorted(types))})')
        count = entry.pop('count', 1)
        if not isinstance(count, int) or isinstance(count, bool) or count < 1:
            raise _error(f'{where} ({name}): count: must be an integer >= 1, got {count!r}')
        overrides = {f: check_field(f, v, f'{where} ({name})') for f, v in entry.items()}
        merged = {**defaults, **types[name], **overrides}
        rows.extend((name, merged) for _ in range(count))
    return _make(rows, source)


def uniform_consist(values: dict[str, Any]) -> Consist:
    """Return the uniform train of the parameters (num_coaches/masses and the constants)."""
    defaults = defaults_of(values)
    masses = values.get('masses') or [float(values.get('coach_mass', defaults['mass']))] * int(
        values.get('num_coaches', parameters.PARAMETERS['num_coaches'].default))
    rows = [('coach', {**defaults, 'mass': float(m)}) for m in masses]
    return _make(rows, 'parameters')


def consist_of(values: dict[str, Any], base_dir: str | None = None) -> Consist:
    """Return the consist of a parameter set: its ``consist_file``, else the uniform train."""
    name = values.get('consist_file', '')
    if name:
        return load_consist(name, values, base_dir)
    return uniform_consist(values)
