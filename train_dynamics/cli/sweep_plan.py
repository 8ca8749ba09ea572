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

Numbers are read as in parameter files (YAML 1.2: ``1.0e6`` and ``1e-3`` are floats). A
relative ``consist_file`` in ``grid`` is looked for in the sweep file's folder, then in the
package's ``config/`` (as ``input``; the base parameter file's own ``consist_file`` is
relative to the base file). A sweep has at most :data:`MAX_CASES` cases, counted from the
file's list lengths and ``samples`` before anything is built.

Every mistake in the file (unknown key or parameter, a value out of its range, a bad range,
a missing input bag or consist file, too many cases) raises
:class:`train_dynamics.cli.errors.CliError` (exit 2, one line quoting at most a bounded
prefix of a value) before any case runs. A case whose combination of values fails the
cross-parameter checks (:meth:`~train_dynamics.physics.config.SimConfig.check`, e.g.
``buffer_friction`` >= ``buffer_stiffness``) is kept as a case with that error, not run.

The plan's digest (resume, ``sweep.json``) identifies the files a case reads by their
content: the consist files (base and swept) and the vehicle library by a SHA-256 of their
bytes, not by their path, so an edited consist file is a different sweep.
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

from train_dynamics.cli.errors import CliError, INVALID_PARAMETERS
from train_dynamics.cli.scenario import brake_inputs, load_config
from train_dynamics.param_files import read_param_file
from train_dynamics.physics.config import (ConfigError, DOUBLE, INTEGER, PARAMETERS,
                                           resolve_path, validate_value)
from train_dynamics.physics.config.consist import LIBRARY
from train_dynamics.physics.config.files import config_dirs, RosParamLoader
from train_dynamics.quoting import clip, quote
from train_dynamics.simulation.runner import InputSchedule
from train_dynamics.topics import VALVE_NODE_NAME
import yaml

#: parameters a sweep may not vary (they do not change an offline run, or name files)
NOT_SWEPT = ('record_bag', 'real_time_factor', 'publish_clock', 'input_timeout',
             'on_input_timeout')
_TOP_KEYS = ('duration', 'input', 'namespace', 'grid', 'lhs')
#: the most cases of a sweep (grid points x hypercube samples): planning them takes seconds
#: and ~1 kB each; more is a different study (split it, or sample it with lhs)
MAX_CASES = 100_000
#: parameters that name a file (a swept name is resolved against the sweep file's folder)
FILE_PARAMETERS = tuple(name for name, spec in PARAMETERS.items() if spec.file_input)
_LHS_KEYS = ('samples', 'seed', 'ranges')


@dataclass
class Case:
    """One case: its number, the swept values, the full parameters, or why it cannot run."""

    index: int
    swept: dict[str, Any]
    inputs: InputSchedule | None = None
    error: str = ''
    base: dict[str, Any] = field(default_factory=dict, repr=False)   # shared by all cases
    files: dict[str, str] = field(default_factory=dict)    # swept file names, resolved

    @property
    def params(self) -> dict[str, Any]:
        """Return the case's parameters (built on demand: a plan holds many cases)."""
        if self.error:
            return {}
        return {**self.base, **self.swept, **self.files}


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
        raise _fail(path, f'unknown parameter {quote(name)}')
    if name in NOT_SWEPT:
        raise _fail(path, f'{name} cannot be swept')
    return name


def _value(path: str, name: str, value: Any) -> Any:
    if isinstance(value, dict) or (isinstance(value, list) and any(
            isinstance(v, (list, dict)) for v in value)):
        raise _fail(path, f'{name}: expected a value, got a nested {type(value).__name__}')
    try:
        return validate_value(name, value)
    except ConfigError as exc:
        raise _fail(path, clip(str(exc))) from None


def read_sweep_file(path: str) -> dict[str, Any]:
    """Return the sweep file as a mapping; raise :class:`CliError` if it is not one."""
    try:
        with open(path, encoding='utf-8') as fh:
            doc = yaml.load(fh, Loader=RosParamLoader)       # 1.0e6: a float (YAML 1.2)
    except FileNotFoundError:
        raise CliError(f'sweep file not found: {path}') from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise CliError(f'cannot read sweep file {path}: {exc}'.splitlines()[0]) from None
    if not isinstance(doc, dict):
        raise _fail(path, 'not a mapping (see docs/offline.md, "sweep", for the format)')
    unknown = [k for k in doc if k not in _TOP_KEYS]
    if unknown:
        raise _fail(path, f'unknown key {quote(unknown[0])} (allowed: {", ".join(_TOP_KEYS)})')
    if 'grid' not in doc and 'lhs' not in doc:
        raise _fail(path, 'nothing to sweep: give grid and/or lhs')
    return doc


def grid_axes(path: str, grid: Any) -> tuple[list[str], list[list]]:
    """Return the grid's parameter names and their lists of values (not yet checked)."""
    if grid is None:
        return [], []
    if not isinstance(grid, dict) or not grid:
        raise _fail(path, 'grid: expected a mapping parameter -> list of values')
    names, axes = [], []
    for name, values in grid.items():
        names.append(_check_name(path, name))
        if not isinstance(values, list) or not values:
            raise _fail(path, f'grid: {name}: expected a non-empty list of values')
        axes.append(values)
    return names, axes


def grid_points(path: str, grid: Any) -> tuple[list[str], list[tuple]]:
    """Return the grid's parameter names and every point of the full product."""
    names, axes = grid_axes(path, grid)
    count_cases(path, [len(a) for a in axes], 1)
    checked = [[_value(path, name, v) for v in values] for name, values in zip(names, axes)]
    return names, list(itertools.product(*checked))


def count_cases(path: str, axis_lengths: list[int], samples: int) -> int:
    """Return grid points x samples; raise :class:`CliError` past :data:`MAX_CASES`."""
    n = math.prod(axis_lengths) * samples
    if n > MAX_CASES:
        shape = ' x '.join(map(str, axis_lengths + ([samples] if samples > 1 else [])))
        raise _fail(path, f'{n} cases ({shape}), more than {MAX_CASES}: split the sweep, '
                    'or sample the space with lhs')
    return n


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


def lhs_samples(path: str, lhs: Any) -> int:
    """Return the number of hypercube samples (1 without ``lhs``)."""
    if lhs is None:
        return 1
    n = lhs.get('samples') if isinstance(lhs, dict) else None
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= MAX_CASES:
        raise _fail(path, f'lhs: samples must be an integer in 1..{MAX_CASES}, got {quote(n)}')
    return n


def _hypercube(d: int, seed: int) -> qmc.LatinHypercube:
    """
    Return scipy's Latin hypercube sampler of ``d`` dimensions on ``default_rng(seed)``.

    scipy >= 1.15 takes the generator as ``rng``, older versions (1.11, Ubuntu 24.04's) as
    ``seed``: the same generator either way.
    """
    gen = np.random.default_rng(seed)
    try:
        return qmc.LatinHypercube(d=d, rng=gen)
    except TypeError:                                   # scipy < 1.15: no ``rng``
        return qmc.LatinHypercube(d=d, seed=gen)


def lhs_points(path: str, lhs: Any) -> tuple[list[str], list[tuple]]:
    """Return the hypercube's parameter names and its samples (seeded)."""
    if lhs is None:
        return [], [()]
    if not isinstance(lhs, dict) or set(lhs) - set(_LHS_KEYS) or 'ranges' not in lhs:
        raise _fail(path, 'lhs: expected samples, seed and ranges')
    n, seed = lhs_samples(path, lhs), lhs.get('seed', 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise _fail(path, f'lhs: seed must be an integer >= 0, got {quote(seed)}')
    ranges = lhs['ranges']
    if not isinstance(ranges, dict) or not ranges:
        raise _fail(path, 'lhs: ranges: expected a mapping parameter -> [min, max]')
    names = [_check_name(path, k) for k in ranges]
    bounds = [_range(path, k, v) for k, v in ranges.items()]
    u = _hypercube(len(names), seed).random(n)
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
        points.append(tuple(validate_value(k, v) for k, v in zip(names, values)))
    return names, points


def make_plan(base_path: str, sweep_path: str) -> Plan:
    """Read and check the base parameters and the sweep file; return the plan (no run)."""
    base = load_config(base_path)
    doc = read_sweep_file(sweep_path)
    duration = _duration(sweep_path, doc)
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
    # count before building anything that grows with the number of cases
    gnames, axes = grid_axes(sweep_path, doc.get('grid'))
    count_cases(sweep_path, [len(a) for a in axes], lhs_samples(sweep_path, doc.get('lhs')))
    gnames, gpoints = grid_points(sweep_path, doc.get('grid'))
    lnames, lpoints = lhs_points(sweep_path, doc.get('lhs'))
    twice = set(gnames) & set(lnames)
    if twice:
        raise _fail(sweep_path, f'{sorted(twice)[0]} is in both grid and lhs')
    swept = gnames + lnames
    files = _swept_files(sweep_path, folder, swept, gpoints)
    args = argparse.Namespace(input=bag, namespace=namespace, params=base_path)
    cases, inputs_cache = [], {}
    base_values = base.values                         # one dict, shared by every case
    for index, (g, s) in enumerate(itertools.product(gpoints, lpoints)):
        case = Case(index, dict(zip(swept, g + s)), base=base_values)
        case.files = {k: files[v] for k, v in case.swept.items() if k in FILE_PARAMETERS}
        try:
            cfg = base.replace(**{**case.swept, **case.files})   # the consist kept unless swept
        except ConfigError as exc:
            case.error = f'{INVALID_PARAMETERS}: {clip(str(exc))}'
        else:
            key = tuple(cfg.values[k] for k in (
                'brake_input', 'integration_step', 'atmospheric_pressure',
                'pipe_nominal_pressure', 'full_service_pressure')) + (cfg.n_coaches,)
            if key not in inputs_cache:
                inputs_cache[key] = brake_inputs(args, cfg)      # CliError: exit 2
            case.inputs = inputs_cache[key]
        cases.append(case)
    plan = Plan(swept, cases, duration, str(Path(base_path).resolve()), bag, namespace)
    digests: dict[str, str] = {}
    identity = {'base': _by_content(base_values, {}, digests),
                'library': _file_digest(_library(), digests),
                'valve': read_param_file(base_path, VALVE_NODE_NAME),
                'input': bag, 'namespace': namespace, 'duration': duration,
                'cases': [[_by_content(c.swept, c.files, digests), c.error] for c in cases]}
    plan.digest = hashlib.sha256(json.dumps(identity, sort_keys=True, default=repr).encode()
                                 ).hexdigest()[:16]
    return plan


def _duration(path: str, doc: dict[str, Any]) -> float:
    """Return the sweep file's ``duration`` [s]: a finite number > 0."""
    if 'duration' not in doc:
        raise _fail(path, 'duration [s] is required')
    duration = doc['duration']
    if not isinstance(duration, (int, float)) or isinstance(duration, bool):
        raise _fail(path, f'duration: expected a number [s], got {quote(duration)}')
    if not math.isfinite(duration) or duration <= 0:
        raise _fail(path, f'duration: must be a finite number > 0 s, got {duration:g}')
    return float(duration)


def _swept_files(path: str, folder: Path, names: list[str], points: list[tuple]
                 ) -> dict[str, str]:
    """Return {name in the sweep file: resolved path} of the swept file parameters."""
    out: dict[str, str] = {}
    for j, name in enumerate(names):
        if name not in FILE_PARAMETERS:
            continue
        for value in {p[j] for p in points if j < len(p)}:
            if value and value not in out:
                try:
                    out[value] = str(resolve_path(value, str(folder), name))
                except ConfigError as exc:
                    raise _fail(path, f'grid: {clip(str(exc))}') from None
            out.setdefault(value, value)
    return out


def _file_digest(path: Path | str, cache: dict[str, str]) -> str:
    """Return ``sha256:<hex>`` of a file's bytes (``missing:<path>`` if it cannot be read)."""
    key = str(path)
    if key not in cache:
        try:
            cache[key] = 'sha256:' + hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            cache[key] = f'missing:{path}'
    return cache[key]


def _library() -> Path:
    return config_dirs()[0] / LIBRARY


def _by_content(values: dict[str, Any], files: dict[str, str], cache: dict[str, str]
                ) -> dict[str, Any]:
    """Return ``values`` with each file parameter replaced by its content's digest."""
    out = dict(values)
    for name in FILE_PARAMETERS:
        where = files.get(name) or out.get(name)
        if where:
            if where not in cache:
                try:
                    cache[where] = _file_digest(resolve_path(where, what=name), cache)
                except ConfigError:
                    cache[where] = f'missing:{where}'
            out[name] = cache[where]
    return out
