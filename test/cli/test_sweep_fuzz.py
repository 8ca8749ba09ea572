"""
A property-based fuzz (Hypothesis) over sweep files, through the sweep's planner and command.

Any sweep file the planner accepts has at most ``MAX_CASES`` cases, each either with a
one-line reason (an invalid combination) or parameters that run 1 s (the case function of
the Dask workers, in-process) to finite metrics or a reported fault; any file it rejects
gives one line ``train-dynamics: error: sweep file ...`` and exit 2 through the command line,
before a cluster starts. Each example is planned in a few seconds.
"""
from __future__ import annotations

import math
from pathlib import Path
import time

from hypothesis import event, given, HealthCheck, settings, strategies as st
import pytest
from train_dynamics.cli import offline as cli
from train_dynamics.cli.errors import CliError
from train_dynamics.cli.sweep_case import run_case
from train_dynamics.cli.sweep_plan import make_plan, MAX_CASES
from train_dynamics.physics.config import PARAMETERS
import yaml

PAPER = str(Path(__file__).resolve().parents[2] / 'config' / 'paper_3coach.yaml')

ODD = st.sampled_from([math.inf, -math.inf, math.nan, 0.0, -1.0, 1e300, True, None, 'x', [],
                       {}, [1.0, [2.0]]])


def _scalar(name):
    spec = PARAMETERS[name]
    if spec.kind in ('double', 'integer'):
        edges = [v for v in (spec.low, spec.high, spec.default) if v is not None]
        good = st.sampled_from([e * f for e in edges for f in (0.5, 1.0, 1.5)])
        if spec.kind == 'integer':
            good = good.map(int)
        return st.one_of(good, ODD)
    if spec.kind == 'string':
        return st.one_of(st.sampled_from(list(spec.choices) + ['bogus']), ODD) \
            if spec.choices else st.one_of(st.just(''), ODD)
    if spec.kind == 'double_array':
        return st.lists(st.sampled_from([4.5e4, 1e5, -1.0, math.nan]), max_size=4)
    return ODD


#: what a sweep may vary (and a few it may not, or that do not exist)
NAMES = ['model_type', 'scale_factor', 'coach_mass', 'buffer_friction', 'integration_step',
         'num_coaches', 'initial_speed', 'masses', 'brake_propagation_speed']
BAD_NAMES = ['record_bag', 'no_such_parameter', 'real_time_factor']

GRID = st.dictionaries(st.sampled_from(NAMES + BAD_NAMES),
                       st.sampled_from(NAMES).flatmap(lambda n: st.one_of(
                           st.lists(_scalar(n), min_size=1, max_size=4), ODD)),
                       max_size=3).flatmap(
    lambda d: st.fixed_dictionaries({k: st.lists(_scalar(k), min_size=0, max_size=4)
                                     if k in PARAMETERS else st.just(v)
                                     for k, v in d.items()}))
RANGE = st.one_of(st.tuples(st.floats(1e2, 1e4), st.floats(1e2, 1e4)).map(list),
                  st.fixed_dictionaries({'min': st.floats(1.0, 100.0),
                                         'max': st.floats(100.0, 1e4)},
                                        optional={'log': st.booleans()}),
                  ODD)
LHS = st.fixed_dictionaries(
    {'samples': st.one_of(st.integers(-1, 4), st.sampled_from([MAX_CASES + 1, 10 ** 12]), ODD),
     'ranges': st.dictionaries(st.sampled_from(['scale_factor', 'brake_propagation_speed',
                                                'model_type', 'no_such_parameter']),
                               RANGE, max_size=2)},
    optional={'seed': st.one_of(st.integers(0, 5), ODD)})
HOSTILE = st.fixed_dictionaries(
    {}, optional={'duration': st.one_of(st.sampled_from([0.5, 1.0, 1e-3]), ODD),
                  'grid': GRID, 'lhs': LHS, 'namespace': st.one_of(st.just(''), ODD),
                  'bogus_key': st.just(1)})


def _good(name):
    """Return values of ``name`` the validator accepts alone (combinations may still fail)."""
    spec = PARAMETERS[name]
    if spec.choices:
        return st.sampled_from(list(spec.choices))
    if name == 'masses':
        return st.lists(st.sampled_from([4.5e4, 1e5, 3e4]), min_size=2, max_size=4)
    if name == 'num_coaches':
        return st.integers(2, 5)
    if name == 'integration_step':
        return st.sampled_from([1e-3, 2e-3, 5e-3])
    low = spec.low * 1.000001 if spec.low_exclusive else spec.low
    return st.floats(low, spec.high if spec.high is not None else 10 * spec.default,
                     allow_nan=False)


#: well-formed files with in-range values: most are accepted
VALID = st.fixed_dictionaries(
    {'duration': st.sampled_from([0.5, 1.0, 2.0]),
     'grid': st.dictionaries(st.sampled_from(NAMES), st.just(None), min_size=1,
                             max_size=2).flatmap(lambda d: st.fixed_dictionaries(
                                 {k: st.lists(_good(k), min_size=1, max_size=2) for k in d}))},
    optional={'lhs': st.fixed_dictionaries(
        {'samples': st.integers(1, 3), 'seed': st.integers(0, 3),
         'ranges': st.just({'brake_propagation_speed': [150.0, 300.0]})})})
SWEEP = st.one_of(VALID, HOSTILE)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(doc=SWEEP)
def test_sweep_files_plan_and_run_or_give_one_line_exit_2(doc, tmp_path, capsys):
    path = tmp_path / 'sweep.yaml'
    path.write_text(yaml.safe_dump(doc))
    t0 = time.process_time()         # CPU s: the work, not the machine's load
    try:
        plan = make_plan(PAPER, str(path))
    except CliError as exc:
        event('rejected')
        assert time.process_time() - t0 < 5.0
        assert '\n' not in str(exc) and len(str(exc)) < 500, str(exc)
        out = tmp_path / 'never'
        code = cli.main(['sweep', '--params', PAPER, '--sweep', str(path), '--output',
                         str(out), '-q'])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith('train-dynamics: error: '), err
        assert not out.exists()
        return
    event('accepted')
    assert time.process_time() - t0 < 5.0
    assert 1 <= len(plan.cases) <= MAX_CASES
    for case in plan.cases[:2]:
        if case.error:
            event('an invalid combination')
            assert '\n' not in case.error
            continue
        row = run_case(case.index, case.params, 1.0, case.inputs)
        assert row['error'] == '' or row['error'].startswith('simulation fault'), row['error']
        for key in ('max_tension', 'max_compression', 'max_deceleration'):
            if row[key] is not None:
                assert math.isfinite(row[key]), (key, row)
        if not row['error']:
            assert row['samples'] == pytest.approx(101, abs=1)
