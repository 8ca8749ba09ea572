"""
A property-based fuzz (Hypothesis) over the parameter space of the validator.

Any parameter set the validator accepts runs 1 s offline (in-process, the runner of the offline
command) without an exception and with finite outputs; any set it rejects gives one line
``train-dynamics: error: ...`` and exit 2 through the command line. Values are drawn inside,
at and beyond every bound; small trains and steps >= 1 ms keep it fast.
"""
from __future__ import annotations

import math

from fuzz_helpers import run_one_second
from hypothesis import event, given, HealthCheck, settings, strategies as st
from train_dynamics.cli import offline as cli
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig
import yaml

#: drawn as given (structural, costly or covered elsewhere)
FIXED = {'num_coaches', 'masses', 'integration_step', 'publish_rate', 'record_bag',
         'cylinder_fill_time', 'cylinder_fill_fraction', 'cylinder_release_time',
         'cylinder_release_fraction', 'brake_input'}


def _number(spec):
    """Values around and beyond the bounds of ``spec``, and plain odd numbers."""
    edges = [v for v in (spec.low, spec.high, spec.default)
             if v is not None and not isinstance(v, list)]
    near = [e * f for e in edges for f in (0.5, 0.999999, 1.0, 1.000001, 2.0)] + [-1.0, 0.0]
    if spec.kind == 'integer':
        return st.one_of(st.sampled_from([int(v) for v in near]),
                         st.integers(-5, 20))
    inside = (st.floats(spec.low, spec.high, allow_nan=False)
              if spec.low is not None and spec.high is not None else st.floats(0.0, 1e6))
    return st.one_of(st.sampled_from(near), inside,
                     st.sampled_from([math.inf, -math.inf, math.nan, 1e300, -1e-300]))


def _value(spec):
    if spec.kind in ('double', 'integer'):
        return _number(spec)
    if spec.kind == 'bool':
        return st.booleans()
    if spec.kind == 'string':
        return st.sampled_from(list(spec.choices) + ['bogus']) if spec.choices else st.just('')
    if spec.kind == 'double_array':      # track and traction tables: short lists, odd values
        return st.lists(_number(spec), max_size=3)
    raise AssertionError(spec.kind)


PARAMS = st.fixed_dictionaries({}, optional={
    **{name: _value(spec) for name, spec in PARAMETERS.items() if name not in FIXED},
    'num_coaches': st.integers(-1, 6),
    'masses': st.lists(st.sampled_from([1e-20, 499.0, 500.0, 4.5e4, 1e6, 2e6]), max_size=5),
    'integration_step': st.sampled_from([1e-3, 2e-3, 3e-3, 5e-3, 0.01, 0.05, 0.0, 0.1, -1.0]),
    'publish_rate': st.sampled_from([10.0, 20.0, 50.0, 100.0, 30.0, 1e4, 0.0, -5.0]),
})


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture,
                                 HealthCheck.too_slow])
@given(params=PARAMS)
def test_accepted_sets_run_and_rejected_sets_are_one_line_exit_2(params, tmp_path, capsys):
    try:
        cfg = SimConfig.from_dict(params)
    except ConfigError as exc:
        event('rejected')
        assert '\n' not in str(exc)
        path = tmp_path / 'p.yaml'
        path.write_text(yaml.safe_dump({'train_dynamics': {'ros__parameters': params}}))
        code = cli.main(['simulate', '--params', str(path), '--duration', '1', '--output',
                         str(tmp_path / 'never'), '-q'])
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and err[0].startswith('train-dynamics: error: '), err
        assert not (tmp_path / 'never').exists()
        return
    event('accepted')
    run_one_second(cfg)


def _inside(spec):
    """Values within the bounds of ``spec`` (what the validator accepts alone)."""
    if spec.kind == 'integer':
        return st.integers(int(spec.low), int(spec.high))
    if spec.kind == 'double':
        low = spec.low if not spec.low_exclusive else spec.low + max(abs(spec.low) * 1e-9, 1e-9)
        return st.floats(low, spec.high, allow_nan=False)
    return _value(spec).filter(lambda v: v != 'bogus')


INSIDE = st.fixed_dictionaries({}, optional={
    **{name: _inside(spec) for name, spec in PARAMETERS.items() if name not in FIXED},
    'num_coaches': st.integers(2, 6),
    'masses': st.lists(st.floats(500.0, 1e6), min_size=2, max_size=5),
    'integration_step': st.sampled_from([1e-3, 2e-3, 5e-3, 0.01, 0.05]),
}).filter(lambda p: 'real_time_factor' not in p or p['real_time_factor'] >= 0)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(params=INSIDE)
def test_in_range_sets_run_one_second_with_finite_outputs_or_a_one_line_reason(params):
    try:
        cfg = SimConfig.from_dict(params)
    except ConfigError as exc:                # a cross-parameter rule (k_f < k_e, ...)
        event('rejected by a cross-parameter check')
        assert '\n' not in str(exc)
        return
    event('accepted')
    run_one_second(cfg)
