"""
The plan of a sweep: the sweep file, read and checked, and its cases.

A sweep file (YAML)::

    duration: 20.0                 # [s] simulated per case (required)
    input: brake_inputs_bag        # optional input bag (relative to the sweep file)
    namespace: ''                  # optional: its topics' namespace
    grid:                          # full factorial grid (optional)
      model_type: [sign, tanh]
      integration_step: [0.001, 0.0001]
    lhs:                           # Latin hypercube (optional)
      samples: 16
      seed: 1
      ranges:
        brake_propagation_speed: [150.0, 300.0]
        scale_factor: {min: 100.0, max: 10000.0, log: true}

Any simulator parameter (:data:`train_dynamics.physics.config.PARAMETERS`) may be swept;
the rest come from the base parameter file. With both ``grid`` and ``lhs`` every grid point
is combined with every sample (cases = grid points x samples), the grid varying slowest.
The hypercube is :class:`scipy.stats.qmc.LatinHypercube` with the given ``seed``: the same
file gives the same cases. Integer parameters take ``lo + floor(u (hi - lo + 1))``;
``log: true`` samples log-uniformly.

Every mistake in the file (unknown key or parameter, a value out of its range, a bad range,
a missing input bag) raises :class:`train_dynamics.cli.errors.CliError` (exit 2) before
any case runs. A case whose combination of values fails the cross-parameter checks
(:meth:`~train_dynamics.physics.config.SimConfig.check`, e.g. ``buffer_friction`` >=
``buffer_stiffness``) is kept as a case with that error, not run.
"""
from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import hashlib
import itertools
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np
from scipy.stats import qmc

from train_dynamics.cli.errors import CliError
from train_dynamics.cli.scenario import brake_inputs, check_duration, load_config
from train_dynamics.physics.config import (ConfigError, DOUBLE, INTEGER, PARAMETERS,
                                           read_param_file, validate_value)
from train_dynamics.simulation.runner import InputSchedule
from train_dynamics.topics import VALVE_NODE_NAME
import yaml

#: parameters a sweep may not vary (they do not change an offline run, or name files)
NOT_SWEPT = ('record_bag', 'real_time_factor', 'publish_clock', 'input_timeout',
             'on_input_timeout')
_TOP_KEYS = ('duration', 'input', 'namespace', 'grid', 'lhs')
_LHS_KEYS = ('samples', 'seed', 'ranges')


@dataclass
class Case:
    """One case: its number, the swept values, the full parameters, or why it cannot run."""

    index: int
    swept: dict[str, Any]
    params: dict[str, Any] = field(default_factory=dict)
    inputs: InputSchedule | None = None
    error: str = ''


@dataclass
class Plan:
    """A checked sweep: the swept parameter names, the cases, the run settings."""

    swept: list[str]
    cases: list[Case]
    duration: float
    base: str
    input: str | None  # noqa: A003 - the sweep file's key
    namespace: str
    digest: str = ''

    def describe(self) -> dict[str, Any]:
        """Return what identifies the sweep (``sweep.json``; resume checks ``digest``)."""
        return {'base': self.base, 'input': self.input, 'namespace': self.namespace,
                'duration': self.duration, 'swept': self.swept, 'cases': len(self.cases),
                'digest': self.digest}


def _fail(path: str, text: str) -> CliError:
    return CliError(f'sweep file {path}: {text}')


def _check_name(path: str, name: Any) -> str:
    if not isinstance(name, str) or name not in PARAMETERS:
        raise _fail(path, f'unknown parameter {name!r}')
    if name in NOT_SWEPT:
        raise _fail(path, f'{name} cannot be swept')
    return name


def _value(path: str, name: str, value: Any) -> Any:
    try:
        return validate_value(name, value)
    except ConfigError as exc:
        raise _fail(path, str(exc)) from None


def read_sweep_file(path: str) -> dict[str, Any]:
    """Return the sweep file as a mapping; raise :class:`CliError` if it is not one."""
    try:
        with open(path, encoding='utf-8') as fh:
            doc = yaml.safe_load(fh)
    except FileNotFoundError:
        raise CliError(f'sweep file not found: {path}') from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise CliError(f'cannot read sweep file {path}: {exc}'.splitlines()[0]) from None
    if not isinstance(doc, dict):
        raise _fail(path, 'not a mapping (see docs/offline.md, "sweep", for the format)')
    unknown = [k for k in doc if k not in _TOP_KEYS]
    if unknown:
        raise _fail(path, f'unknown key {unknown[0]!r} (allowed: {", ".join(_TOP_KEYS)})')
    if 'grid' not in doc and 'lhs' not in doc:
        raise _fail(path, 'nothing to sweep: give grid and/or lhs')
    return doc


def grid_points(path: str, grid: Any) -> tuple[list[str], list[tuple]]:
    """Return the grid's parameter names and every point of the full product."""
    if grid is None:
        return [], [()]
    if not isinstance(grid, dict) or not grid:
        raise _fail(path, 'grid: expected a mapping parameter -> list of values')
    names, axes = [], []
    for name, values in grid.items():
        names.append(_check_name(path, name))
        if not isinstance(values, list) or not values:
            raise _fail(path, f'grid: {name}: expected a non-empty list of values')
        axes.append([_value(path, name, v) for v in values])
    return names, list(itertools.product(*axes))


def _range(path: str, name: str, spec: Any) -> tuple[float, float, bool]:
    kind = PARAMETERS[name].kind
    if kind not in (DOUBLE, INTEGER):
        raise _fail(path, f'lhs: {name} is a {kind} parameter; give it in grid')
    log = False
    if isinstance(spec, dict):
        extra = set(spec) - {'min', 'max', 'log'}
        if extra or 'min' not in spec or 'max' not in spec:
            raise _fail(path, f'lhs: {name}: expected {{min: A, max: B[, log: true]}}')
        lo, hi, log = spec['min'], spec['max'], spec.get('log', False)
    elif isinstance(spec, list) and len(spec) == 2:
        lo, hi = spec
    else:
        raise _fail(path, f'lhs: {name}: expected [min, max] or {{min: A, max: B}}')
    if not isinstance(log, bool):
        raise _fail(path, f'lhs: {name}: log must be true or false')
    lo, hi = _value(path, name, lo), _value(path, name, hi)
    if not lo < hi:
        raise _fail(path, f'lhs: {name}: min {lo!r} must be < max {hi!r}')
    if log and not lo > 0:
        raise _fail(path, f'lhs: {name}: a log range needs min > 0')
    return lo, hi, log


def lhs_points(path: str, lhs: Any) -> tuple[list[str], list[tuple]]:
    """Return the hypercube's parameter names and its samples (seeded)."""
    if lhs is None:
        return [], [()]
    if not isinstance(lhs, dict) or set(lhs) - set(_LHS_KEYS) or 'ranges' not in lhs:
        raise _fail(path, 'lhs: expected samples, seed and ranges')
    n, seed = lhs.get('samples'), lhs.get('seed', 0)
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= 1_000_000:
        raise _fail(path, f'lhs: samples must be an integer in 1..1000000, got {n!r}')
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise _fail(path, f'lhs: seed must be an integer >= 0, got {seed!r}')
    ranges = lhs['ranges']
    if not isinstance(ranges, dict) or not ranges:
        raise _fail(path, 'lhs: ranges: expected a mapping parameter -> [min, max]')
    names = [_check_name(path, k) for k in ranges]
    bounds = [_range(path, k, v) for k, v in ranges.items()]
    u = qmc.LatinHypercube(d=len(names), rng=np.random.default_rng(seed)).random(n)
    points = []
    for row in u:
        values = []
        for name, (lo, hi, log), x in zip(names, bounds, row):
            if PARAMETERS[name].kind == INTEGER:
                values.append(min(int(lo + math.floor(x * (hi - lo + 1))), int(hi)))
            elif log:
                values.append(float(math.exp(math.log(lo) + x * (math.log(hi) - math.log(lo)))))
            else:
                values.append(float(lo + x * (hi - lo)))
        points.append(tuple(values))
    return names, points


def make_plan(base_path: str, sweep_path: str) -> Plan:
    """Read and check the base parameters and the sweep file; return the plan (no run)."""
    base = load_config(base_path)
    doc = read_sweep_file(sweep_path)
    if 'duration' not in doc:
        raise _fail(sweep_path, 'duration [s] is required')
    duration = doc['duration']
    if not isinstance(duration, (int, float)) or isinstance(duration, bool):
        raise _fail(sweep_path, f'duration: expected a number [s], got {duration!r}')
    duration = check_duration(float(duration))
    folder = Path(sweep_path).resolve().parent
    bag = doc.get('input')
    if bag is not None:
        if not isinstance(bag, str) or not bag:
            raise _fail(sweep_path, 'input: expected the path of a bag')
        bag = str(folder / bag)
        if not os.path.exists(bag):
            raise _fail(sweep_path, f'input bag not found: {bag}')
    namespace = doc.get('namespace', '') or ''
    if not isinstance(namespace, str):
        raise _fail(sweep_path, 'namespace: expected a string')
    gnames, gpoints = grid_points(sweep_path, doc.get('grid'))
    lnames, lpoints = lhs_points(sweep_path, doc.get('lhs'))
    twice = set(gnames) & set(lnames)
    if twice:
        raise _fail(sweep_path, f'{sorted(twice)[0]} is in both grid and lhs')
    swept = gnames + lnames
    args = argparse.Namespace(input=bag, namespace=namespace, params=base_path)
    cases, inputs_cache = [], {}
    for index, (g, s) in enumerate(itertools.product(gpoints, lpoints)):
        case = Case(index, dict(zip(swept, g + s)))
        try:
            cfg = base.replace(**case.swept)      # the base's consist kept unless swept
        except ConfigError as exc:
            case.error = f'invalid parameters: {exc}'
        else:
            case.params = cfg.values
            key = tuple(case.params[k] for k in (
                'brake_input', 'integration_step', 'atmospheric_pressure',
                'pipe_nominal_pressure', 'full_service_pressure')) + (cfg.n_coaches,)
            if key not in inputs_cache:
                inputs_cache[key] = brake_inputs(args, cfg)      # CliError: exit 2
            case.inputs = inputs_cache[key]
        cases.append(case)
    plan = Plan(swept, cases, duration, str(Path(base_path).resolve()), bag, namespace)
    identity = {'base': base.values, 'valve': read_param_file(base_path, VALVE_NODE_NAME),
                'input': bag,
                'namespace': namespace, 'duration': duration,
                'cases': [[c.swept, c.error] for c in cases]}
    plan.digest = hashlib.sha256(json.dumps(identity, sort_keys=True, default=repr).encode()
                                 ).hexdigest()[:16]
    return plan
