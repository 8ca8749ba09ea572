"""
The ``integrator`` parameter: one name for the method, the tolerances keeping their meaning.

``fixed`` is the plain fixed step, ``multirate`` (the default) the fixed step with multirate
re-integration at ``multirate_tolerance``, ``adaptive`` error control at
``integration_tolerance`` (1e-3 when unset). Older files that set only a tolerance still select
the method they did; a contradiction is one line, exit 2 offline, a refused set in the node.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from train_dynamics.cli import offline
from train_dynamics.param_files import load_param_file
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig
from train_dynamics.physics.config.integrator import ADAPTIVE_TOLERANCE, INTEGRATORS
from train_dynamics.physics.kernel.drivers import (advance_error_controlled, advance_fixed,
                                                   DRIVERS)
from train_dynamics.physics.kernel.layout import PARAM
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.bag_read import read_topics

ROOT = Path(__file__).resolve().parents[2]


def _run(overrides: dict, duration: float = 1.0) -> tuple[TrainSimulator, np.ndarray]:
    """Run 5 paper coaches, emergency from the head, for ``duration`` [s]: (sim, [y, v])."""
    sim = TrainSimulator(SimConfig.from_dict({'num_coaches': 5, **overrides}))
    sim.set_head_pipe_pressure(0.0)      # emergency at the head: the couplers load up
    sim.advance_to(duration)
    return sim, np.concatenate([np.asarray(sim.y, float), np.asarray(sim.v, float)])


@pytest.mark.parametrize('over, method, tol, mrtol', [
    ({}, 'multirate', 0.0, 1e-3),
    ({'integrator': 'multirate', 'multirate_tolerance': 3e-4}, 'multirate', 0.0, 3e-4),
    ({'integrator': 'fixed'}, 'fixed', 0.0, 0.0),
    ({'integrator': 'adaptive'}, 'adaptive', ADAPTIVE_TOLERANCE, 1e-3),
    ({'integrator': 'adaptive', 'integration_tolerance': 1e-4}, 'adaptive', 1e-4, 1e-3),
    # older files: a tolerance alone names the method
    ({'integration_tolerance': 2e-3}, 'adaptive', 2e-3, 1e-3),
    ({'multirate_tolerance': 0.0}, 'fixed', 0.0, 0.0),
    ({'multirate_tolerance': 0.0, 'integration_tolerance': 1e-3}, 'adaptive', 1e-3, 0.0),
])
def test_each_integrator_reaches_the_kernel_with_its_tolerance(over, method, tol, mrtol):
    cfg = SimConfig.from_dict(over)
    assert cfg.integration == (method, tol, mrtol)
    sim = TrainSimulator(cfg)
    assert sim.adaptive == (method == 'adaptive')
    assert sim.tolerance == tol and sim.sc[PARAM.MRTOL] == mrtol
    assert sim.sc[PARAM.TOL] == tol
    assert sim.driver is (advance_error_controlled if method == 'adaptive' else advance_fixed)


def test_every_method_has_a_driver():
    assert set(DRIVERS) == set(INTEGRATORS)


def test_the_default_is_multirate_at_1e_3():
    assert PARAMETERS['integrator'].default == 'multirate'
    assert SimConfig.from_dict({}).integration == ('multirate', 0.0, 1e-3)


def test_named_methods_run_exactly_as_the_older_settings_they_name():
    _, fixed = _run({'integrator': 'fixed'})
    _, plain = _run({'multirate_tolerance': 0.0})
    assert np.array_equal(fixed, plain)
    _, adaptive = _run({'integrator': 'adaptive'})
    _, tol = _run({'integration_tolerance': ADAPTIVE_TOLERANCE})
    assert np.array_equal(adaptive, tol)
    # and the methods differ: error control does not take the fixed step's path
    assert not np.array_equal(adaptive, fixed)


@pytest.mark.parametrize('over, words', [
    ({'integrator': 'fixed', 'integration_tolerance': 1e-3},
     'integrator fixed contradicts integration_tolerance 0.001'),
    ({'integrator': 'adaptive', 'wsp': 'builtin'}, 'wheelsets'),
    ({'integrator': 'euler'}, 'one of'),
])
def test_contradictions_are_refused_in_one_line(over, words):
    with pytest.raises(ConfigError, match=words) as info:
        SimConfig.from_dict(over)
    assert '\n' not in str(info.value)


def test_a_contradiction_set_later_is_refused_and_the_old_method_kept():
    cfg = SimConfig.from_dict({'integration_tolerance': 1e-3})
    with pytest.raises(ConfigError, match='contradicts'):
        cfg.replace(integrator='fixed')
    assert cfg.replace(integrator='fixed', integration_tolerance=0.0).integration.method == 'fixed'
    assert cfg.integration.method == 'adaptive'


def test_the_shipped_adaptive_scenario_names_its_method():
    cfg = load_param_file(str(ROOT / 'config' / 'paper_3coach_adaptive.yaml'))
    assert cfg.integrator == 'adaptive' and cfg.integration == ('adaptive', 1e-3, 1e-3)


def _params(tmp_path: Path, extra: str, name: str) -> Path:
    text = (ROOT / 'config' / 'paper_3coach.yaml').read_text()
    marker = '  ros__parameters:\n'
    at = text.index(marker) + len(marker)
    path = tmp_path / name
    path.write_text(text[:at] + f'    {extra}\n' + text[at:])
    return path


def _forces(bag: Path) -> list[tuple[int, list[float]]]:
    return [(t, list(m.effort)) for _, t, m in read_topics(bag, ['couplers'])]


def test_offline_integrator_fixed_equals_the_older_plain_step_setting(tmp_path, capsys):
    bags = {}
    for label, extra in (('named', 'integrator: fixed'), ('older', 'multirate_tolerance: 0.0')):
        params = _params(tmp_path, extra, f'{label}.yaml')
        out = tmp_path / label
        code = offline.main(['simulate', '--params', str(params), '--duration', '2.0',
                             '--output', str(out), '-q'])
        assert code == 0, capsys.readouterr().err
        bags[label] = _forces(out)
    assert len(bags['named']) == 201 and bags['named'] == bags['older']
    assert max(abs(f) for _, row in bags['named'] for f in row) > 1.0e3   # the couplers load


def test_offline_contradiction_is_one_line_exit_2(tmp_path, capsys):
    params = _params(tmp_path, 'integrator: fixed\n    integration_tolerance: 0.001', 'p.yaml')
    code = offline.main(['simulate', '--params', str(params), '--duration', '0.5', '--output',
                         str(tmp_path / 'out'), '-q'])
    err = [ln for ln in capsys.readouterr().err.splitlines()
           if ln.startswith('train-dynamics: error:')]
    assert code == 2 and len(err) == 1, err
    assert 'integrator fixed contradicts integration_tolerance' in err[0]
    assert not (tmp_path / 'out').exists()


def test_sim_node_declares_integrator_from_the_table_and_runs_it(harness):
    from rclpy.parameter import Parameter

    node = harness.start(integrator='adaptive')
    d = node.describe_parameter('integrator')
    assert d.additional_constraints == 'one of: fixed, multirate, adaptive'
    assert 'structural' in d.description and d.description.startswith('Integration method')
    assert node.get_parameter('integrator').value == 'adaptive'
    assert node.simulator.adaptive and node.simulator.tolerance == ADAPTIVE_TOLERANCE
    # a contradiction set later is refused; a consistent change is pending until reset
    (res,) = node.set_parameters([Parameter('integration_tolerance', value=1e-4)])
    assert res.successful
    (res,) = node.set_parameters([Parameter('integrator', value='fixed')])
    assert not res.successful and 'contradicts' in res.reason
    assert node.get_parameter('integrator').value == 'adaptive'


def test_sim_node_refuses_a_contradictory_start(harness):
    with pytest.raises(ConfigError, match='contradicts'):
        harness.start(integrator='fixed', integration_tolerance=1e-3)
