"""
What an offline run is made of: the parameter file, the duration and the brake inputs.

Shared by ``train-dynamics simulate`` and ``compare``. Brake input:

* ``--input BAG``: the input topics of the file's ``brake_input`` mode, read by
  :func:`train_dynamics.recording.inputs.read_input_bag`;
* no input bag (``pipe_head`` only): the head-pipe pressure follows the ``brake_valve``
  section of the same parameter file (the ``brake_valve`` node's schedule and rates, see
  :mod:`train_dynamics.physics.brake_valve`), sampled at every integration step; without that
  section: emergency braking at t = 1 s.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from train_dynamics import topics
from train_dynamics.cli.errors import CliError, warn
from train_dynamics.param_files import load_param_file, valve_params
from train_dynamics.physics.brake_valve import BrakeValveModel
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.recording.inputs import InputBagError, read_command_bag, read_input_bag
from train_dynamics.simulation.runner import command_events, InputSchedule

#: the brake valve without a ``schedule`` or ``position`` in the parameter file
DEFAULT_VALVE_SCHEDULE = ['0.0:release', '1.0:emergency']


def load_config(path: str) -> SimConfig:
    """Return the simulator parameters of the parameter file at ``path`` (strict)."""
    if not Path(path).is_file():
        raise CliError(f'parameter file not found: {path}')
    try:
        return load_param_file(path, warn=warn)
    except ConfigError as exc:
        raise CliError(str(exc)) from None


def check_duration(duration: float) -> float:
    """Return ``duration`` [s] if it is finite and > 0, else raise :class:`CliError`."""
    if not math.isfinite(duration) or duration <= 0.0:
        raise CliError(f'--duration must be a finite number > 0 s, got {duration:g}')
    return duration


def brake_inputs(args: argparse.Namespace, cfg: SimConfig) -> InputSchedule:
    """
    Return the inputs of the run: the ``--input`` bag or the brake-valve schedule.

    The commands (traction, EP / ECP, WSP valves, the brake control unit's inputs, ED
    forces): the bag's of a kind when it has any, else the parameter file's schedule of
    that kind (``traction_schedule_*``, ``ep_schedule_*``, ``demand_schedule_*`` ...).
    """
    inputs = _brake_only(args, cfg)
    from_bag = []
    if args.input:
        try:
            from_bag = read_command_bag(args.input, cfg, namespace=args.namespace, warn=warn)
        except InputBagError as exc:
            raise CliError(str(exc)) from None
    inputs.commands = command_events(cfg, from_bag)
    return inputs


def _brake_only(args: argparse.Namespace, cfg: SimConfig) -> InputSchedule:
    """Return the brake input of the run: the ``--input`` bag or the brake-valve schedule."""
    if cfg.blending == 'builtin':   # the brake control unit sets the cylinders itself
        return InputSchedule(cfg.brake_input, [], None, 'brake control unit')
    if args.input:
        try:
            return read_input_bag(args.input, cfg, namespace=args.namespace, warn=warn)
        except InputBagError as exc:
            raise CliError(str(exc)) from None
    if cfg.brake_input != topics.PIPE_HEAD:
        raise CliError(f'brake_input {cfg.brake_input} needs --input BAG with its pressures '
                       f'(without an input bag only {topics.PIPE_HEAD}, driven by the '
                       'brake_valve section, is possible)')
    return InputSchedule(topics.PIPE_HEAD, [], valve_from_param_file(args.params, cfg),
                         'brake_valve schedule')


def valve_from_param_file(path: str, cfg: Any) -> BrakeValveModel:
    """
    Return the brake valve of the ``brake_valve`` section (strict); default emergency at 1 s.

    The valve's running and full-service pressures default to the simulator's, so that a
    released valve leaves the distributors released.
    """
    try:
        params = valve_params(path)
    except ConfigError as exc:
        raise CliError(str(exc)) from None
    if 'schedule' not in params and 'position' not in params:
        params['schedule'] = list(DEFAULT_VALVE_SCHEDULE)
    params.setdefault('pipe_nominal_pressure', float(cfg.pipe_nominal_pressure))
    params.setdefault('full_service_pressure', float(cfg.full_service_pressure))
    try:
        return BrakeValveModel.from_params(params, strict=True)
    except ValueError as exc:
        raise CliError(f'{path}: brake_valve: {exc}') from None
