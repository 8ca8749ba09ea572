"""
A controller-test scenario file, read and checked before anything runs.

A scenario file (YAML)::

    parameters_file: ../config/some_train.yaml   # optional, relative to the scenario file
    parameters:                                  # optional: sim_node parameters on top
      initial_speed: 10.0
      consist_file: my_consist.yaml              # relative: next to the scenario file
    controller_parameters:                       # optional: ROS parameters of the controller
      target_deceleration: 0.6
    duration: 20.0                               # [s] simulation time, > 0
    figures: false                               # optional: report figures (default off)
    criteria:                                    # optional (train_dynamics.testing.criteria)
      stopped: {equals: true}
      stopping_distance: {max: 120.0}

What is checked when it is read (:meth:`Scenario.load`), each refusal one
:class:`ConfigError` line naming the file and the key:

- the keys above, and no other (a misspelled key is refused, not ignored);
- ``parameters``: every name and value against the simulator's parameter table, the one the
  offline command and ``sim_node`` use (:data:`~train_dynamics.physics.config.PARAMETERS`,
  :data:`~train_dynamics.ros.node_parameters.SIM_NODE_PARAMETERS`), then the whole configuration
  (``parameters_file`` with ``parameters`` on top) as the offline command checks it
  (:meth:`SimConfig.from_dict <train_dynamics.physics.config.SimConfig.from_dict>`: consist
  file read, cross-checks). The parameters the harness sets itself
  (:data:`HARNESS_PARAMETERS`) are refused there, saying where they are given instead;
- a relative file input (``consist_file``) of ``parameters`` is resolved by the path rule of
  :mod:`train_dynamics.physics.config.files` with the scenario file's folder as the parameter
  file's folder (then the shipped ``config/``);
- ``controller_parameters``: ROS parameter names and values (true/false, integers, finite
  numbers, strings, non-empty lists of one of these; nested mappings for dotted names);
- ``criteria``: :mod:`train_dynamics.testing.criteria`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import difflib
import math
import os
from pathlib import Path
import re
from typing import Any, Mapping

from train_dynamics.param_files import ROS_BUILTIN_PARAMETERS, simulator_params
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig, validate_value
from train_dynamics.physics.config.files import resolve_file_inputs, RosParamLoader
from train_dynamics.quoting import quote
from train_dynamics.ros.node_parameters import SIM_NODE_PARAMETERS
from train_dynamics.testing.criteria import Criterion, parse_criteria
import yaml

SCENARIO_KEYS = ('parameters_file', 'parameters', 'controller_parameters', 'duration',
                 'figures', 'criteria')
#: sim_node parameters the harness sets for every run, and where a user gives them instead
HARNESS_PARAMETERS = {
    'sync_mode': 'the harness always runs lockstep',
    'real_time_factor': 'run_scenario(real_time_factor=...) or --real-time-factor',
    'duration': "the scenario's duration key",
    'record_bag': "the harness records to the run folder's bag",
    'lockstep_timeout': 'run_scenario(lockstep_timeout=...) or --lockstep-timeout',
    'lockstep_on_timeout': 'the harness ends the run on a lockstep timeout',
}
#: a ROS 2 parameter name (one level; nested mappings give the dotted names)
_ROS_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')


@dataclass
class Scenario:
    """A scenario: sim_node parameters, a duration, controller parameters and criteria."""

    duration: float
    parameters: dict[str, Any] = field(default_factory=dict)
    parameters_file: Path | None = None
    criteria: list[Criterion] = field(default_factory=list)
    name: str = 'scenario'
    controller_parameters: dict[str, Any] = field(default_factory=dict)
    figures: bool = False
    #: the simulator configuration :meth:`check` built (None before)
    config: SimConfig | None = field(default=None, init=False, repr=False, compare=False)

    @classmethod
    def load(cls, path: str | os.PathLike) -> Scenario:
        """Read and check a scenario file; raise :class:`ConfigError` (one line) when wrong."""
        path = Path(path)
        try:
            with open(path, encoding='utf-8') as fh:
                doc = yaml.load(fh, Loader=RosParamLoader)
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            raise ConfigError(' '.join(f'{path}: {exc}'.split())) from None
        if not isinstance(doc, Mapping) or 'duration' not in doc:
            raise ConfigError(f'{path}: a scenario is a mapping with at least duration')
        unknown = [k for k in doc if k not in SCENARIO_KEYS]
        if unknown:
            close = difflib.get_close_matches(str(unknown[0]), SCENARIO_KEYS, n=1)
            raise ConfigError(f'{path}: unknown key(s) {", ".join(quote(k) for k in unknown)}'
                              + (f' (did you mean {close[0]}?)' if close else '')
                              + f' (known: {", ".join(SCENARIO_KEYS)})')
        try:
            params = _mapping(doc.get('parameters'), 'parameters')
            pfile = doc.get('parameters_file')
            if pfile is not None and not isinstance(pfile, str):
                raise ConfigError(f'parameters_file: expected a path, got {quote(pfile)}')
            # the path rule: the scenario file stands where a parameter file would
            params.update(resolve_file_inputs(params, str(path.parent.absolute())))
            figures = doc.get('figures', False)
            if not isinstance(figures, bool):
                raise ConfigError(f'figures: expected true or false, got {quote(figures)}')
            scenario = cls(duration=doc['duration'], parameters=params,
                           parameters_file=(path.parent / pfile).absolute() if pfile else None,
                           criteria=parse_criteria(doc.get('criteria')), name=path.stem,
                           controller_parameters=_mapping(doc.get('controller_parameters'),
                                                          'controller_parameters'),
                           figures=figures)
            scenario.check()
        except ConfigError as exc:
            raise ConfigError(f'{path}: {exc}') from None
        return scenario

    def check(self) -> None:
        """
        Check the scenario as a whole; normalise the parameters' values (ints of doubles).

        Relative paths (``parameters_file``, a file input such as ``consist_file`` in
        ``parameters``) are made absolute against the current folder: the path rule for
        values given in Python (a scenario file's are absolute already, :meth:`load`).

        Raises :class:`ConfigError` (one line) naming the key; see the module.
        """
        self.duration = check_duration(self.duration)
        if self.parameters_file is not None:
            # absolute: the node runs in the run folder
            self.parameters_file = Path(self.parameters_file).absolute()
            if not self.parameters_file.is_file():
                raise ConfigError(f'parameters_file: file not found: {self.parameters_file}')
        params = _mapping(self.parameters, 'parameters')
        # a scenario built in Python: relative file inputs by the path rule (current folder);
        # load() made those of a scenario file absolute already
        params.update(resolve_file_inputs(params, os.getcwd()))
        self.parameters, self.config = check_parameters(params, self.parameters_file)
        check_controller_parameters(self.controller_parameters)
        for c in self.criteria:
            if not isinstance(c, Criterion):
                raise ConfigError(f'criteria: expected Criterion objects, got {quote(c)}')


def _mapping(value: Any, key: str) -> dict[str, Any]:
    """Return the mapping under ``key`` as a dict ({} when absent); refuse anything else."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ConfigError(f'{key}: expected a mapping name -> value, got {quote(value)}')
    for name in value:
        if not isinstance(name, str):
            raise ConfigError(f'{key}: name {quote(name)} is not a string')
    return dict(value)


def check_duration(value: Any) -> float:
    """Return the scenario's duration [s] if it is a number > 0 that sim_node takes."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'duration: expected a number of seconds, got {quote(value)}')
    if not value > 0.0:          # (NaN too)
        raise ConfigError(f'duration: must be > 0 s, got {quote(value)}')
    return validate_value('duration', value, SIM_NODE_PARAMETERS)


def check_parameters(params: Mapping[str, Any], parameters_file: Path | None
                     ) -> tuple[dict[str, Any], SimConfig]:
    """
    Return ``params`` (a scenario's sim_node parameters) checked and normalised, and the config.

    Each name must be a simulator parameter (the offline command's table), a sim_node
    parameter or a ROS 2 one (``use_sim_time``), and not one of :data:`HARNESS_PARAMETERS`;
    each value is checked by that table. Then ``parameters_file``'s simulator parameters with
    ``params`` on top must make a configuration the offline command accepts.
    """
    out = {}
    for name, value in params.items():
        if name in HARNESS_PARAMETERS:
            raise ConfigError(f'parameters: {name} is set by the harness '
                              f'({HARNESS_PARAMETERS[name]})')
        if name in ROS_BUILTIN_PARAMETERS:
            if not isinstance(value, bool):
                raise ConfigError(f'parameters: {name}: expected true or false, got '
                                  f'{quote(value)}')
            out[name] = value
            continue
        table = PARAMETERS if name in PARAMETERS else SIM_NODE_PARAMETERS
        if name not in table:
            known = list(PARAMETERS) + list(SIM_NODE_PARAMETERS)
            close = difflib.get_close_matches(name, known, n=1)
            raise ConfigError(f'parameters: unknown parameter {quote(name)}'
                              + (f' (did you mean {close[0]}?)' if close else ''))
        try:
            out[name] = validate_value(name, value, table)
        except ConfigError as exc:
            raise ConfigError(f'parameters: {exc}') from None
    base = {}
    if parameters_file is not None:
        base = simulator_params(str(parameters_file))   # its errors name the file
        extra = [k for k in base if k not in PARAMETERS and k not in SIM_NODE_PARAMETERS]
        if extra:
            raise ConfigError(f'{parameters_file}: unknown parameter(s) '
                              f'{", ".join(quote(k) for k in extra)}')
    merged = {k: v for k, v in {**base, **out}.items() if k in PARAMETERS}
    try:
        cfg = SimConfig.from_dict(merged)
    except ConfigError as exc:
        where = f'parameters (with {parameters_file})' if parameters_file else 'parameters'
        raise ConfigError(f'{where}: {exc}') from None
    return out, cfg


def check_controller_parameters(params: Mapping[str, Any], prefix: str = '') -> None:
    """Refuse what a ROS 2 parameter file cannot carry to the controller (one line)."""
    for name, value in params.items():
        label = f'controller_parameters: {prefix}{name}'
        if not isinstance(name, str) or not _ROS_NAME.fullmatch(name):
            raise ConfigError(f'controller_parameters: {quote(prefix + str(name))} is not a '
                              'ROS parameter name (letters, digits, _)')
        if isinstance(value, Mapping):
            if not value:
                raise ConfigError(f'{label}: an empty mapping sets nothing')
            check_controller_parameters(value, f'{prefix}{name}.')
        elif isinstance(value, list):
            if not value:
                raise ConfigError(f'{label}: an empty list has no ROS parameter type')
            kinds = {_kind(label, item) for item in value}
            if len(kinds - {'integer'}) > 1 or ('bool' in kinds and len(kinds) > 1) or \
                    ('string' in kinds and len(kinds) > 1):
                raise ConfigError(f'{label}: a list of mixed types ({", ".join(sorted(kinds))})'
                                  '; a ROS parameter list holds one type')
        else:
            _kind(label, value)


def _kind(label: str, value: Any) -> str:
    """Return the ROS parameter type of a scalar ``value``; refuse None, NaN, nested lists."""
    if isinstance(value, bool):
        return 'bool'
    if isinstance(value, int):
        if value.bit_length() > 63:
            raise ConfigError(f'{label}: {quote(value)} does not fit a 64-bit integer')
        return 'integer'
    if isinstance(value, float):
        if not math.isfinite(value):
            raise ConfigError(f'{label}: {value} is not a finite number')
        return 'double'
    if isinstance(value, str):
        return 'string'
    raise ConfigError(f'{label}: {quote(value)} is no ROS parameter value (true/false, a '
                      'number, a string or a list of one of these)')


def controller_params_document(params: Mapping[str, Any]) -> dict[str, Any]:
    """Return the ROS 2 parameter file (``/**`` section) of ``controller_parameters``."""
    def fix(value: Any) -> Any:
        if isinstance(value, Mapping):
            return {k: fix(v) for k, v in value.items()}
        if isinstance(value, list) and any(isinstance(v, float) for v in value):
            return [float(v) for v in value]       # ints among doubles: a double list
        return value
    return {'/**': {'ros__parameters': fix(params)}}
