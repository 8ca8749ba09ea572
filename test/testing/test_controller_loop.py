"""
A brake controller in the loop: lock-step closed loops over DDS, in separate processes.

The example PI controller (``examples/pi_brake_controller.py``) and its failing twin
(``examples/harsh_brake_controller.py``) run against ``sim_node`` in ``sync_mode`` lockstep at
``real_time_factor`` 0 through the harness (:mod:`train_dynamics.testing`), each process on
its own, as a user's CI would.
"""
from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
import sys

import pytest

from train_dynamics.physics.config import ConfigError
from train_dynamics.recording.bags import read_topics
from train_dynamics.testing import Criterion, harness, run_scenario, Scenario

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / 'examples' / 'stop_from_50kmh.yaml'
PI = [sys.executable, str(ROOT / 'examples' / 'pi_brake_controller.py')]
HARSH = [sys.executable, str(ROOT / 'examples' / 'harsh_brake_controller.py')]

pytest_plugins = ['train_dynamics.testing.fixture']


def _files(bag: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(bag.iterdir())}


@pytest.fixture
def no_report(monkeypatch):
    """
    Skip the harness's run metrics (the bag read again after the run).

    For the tests of the lockstep bags themselves; the report of a harness run is tested
    with the PI controller and its harsh twin below.
    """
    monkeypatch.setattr(harness, '_metrics', lambda bag, out, namespace: {'report': 'skipped'})


def test_lockstep_closed_loop_is_byte_identical_and_loses_no_command(tmp_path, no_report):
    runs = [run_scenario(SCENARIO, PI, tmp_path / f'run{k}') for k in (1, 2)]
    for run in runs:
        assert run.returncode == 0 and not run.error, run.report()
    first, second = (_files(run.bag) for run in runs)
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f'{name} differs between the two runs'

    # every output period's command took effect at its period: one input per output,
    # recorded at the output's time and stamped with it
    outputs, commands = [], []
    for topic, t_ns, msg in read_topics(runs[0].bag, ['coaches', 'brake_pipe/pressure']):
        stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
        (outputs if topic == 'coaches' else commands).append((t_ns, stamp))
    periods = round(Scenario.load(SCENARIO).duration * 100) + 1
    assert len(outputs) == periods
    assert [t for t, _ in outputs] == [t for t, _ in commands]
    assert all(t == stamp for t, stamp in commands)


def test_lockstep_waits_for_traction_commands_and_is_byte_identical(tmp_path, no_report):
    """
    A controller answering each output with the brake pipe and, 5 ms later, a traction command.

    ``lockstep_inputs: [brake, traction]``: every period waits for both, so each traction
    command acts at the output it answers (recorded at that output's time, its value the
    controller's law of that output's speed), and two runs give byte-identical bags.
    """
    from lockstep_traction_controller import command

    scenario = tmp_path / 'traction.yaml'
    scenario.write_text(
        f'parameters_file: {ROOT / "config" / "passenger_loco_12.yaml"}\n'
        'parameters: {initial_speed: 10.0, lockstep_inputs: [brake, traction]}\n'
        'duration: 2.0\n')
    ctl = [sys.executable, str(ROOT / 'test' / 'lockstep_traction_controller.py')]
    runs = [run_scenario(scenario, ctl, tmp_path / f'run{k}') for k in (1, 2)]
    for run in runs:
        assert run.returncode == 0 and not run.error, run.report()
    first, second = (_files(run.bag) for run in runs)
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f'{name} differs between the two runs'

    speeds, commands = {}, []
    for topic, t_ns, msg in read_topics(runs[0].bag, ['coaches', 'coach_1/traction/command']):
        if topic == 'coaches':
            speeds[t_ns] = msg.velocity[0]
        else:
            commands.append((t_ns, msg.data))
    assert len(speeds) == 201
    assert [t for t, _ in commands] == sorted(speeds)      # one per output, at its time
    assert all(c == command(speeds[t], 15.0, 0.5) for t, c in commands)
    assert commands[0][1] == 1.0 and speeds[max(speeds)] > 10.5     # full traction: faster


def test_harness_passes_the_pi_controller_and_fails_its_harsh_twin(train_loop, tmp_path):
    # the PI run at the same time as the harsh one, under its own namespace (lockstep: the
    # outcome does not depend on the load)
    with ThreadPoolExecutor(1) as pool:
        pending = pool.submit(run_scenario, SCENARIO, PI, tmp_path / 'pi', namespace='/pi')
        bad = train_loop(SCENARIO, HARSH)
        good = pending.result()
    assert good.passed, good.report()
    assert good.metrics['stopped'] is True
    assert not bad.passed
    assert bad.error == ''
    assert 'max_deceleration' in bad.failed
    assert 'FAIL max_deceleration <= 0.8' in bad.report()
    assert bad.report().endswith(f'(4 criteria; bag {bad.bag})')


def test_harness_reports_a_silent_controller_as_a_lockstep_timeout(tmp_path):
    # a controller that subscribes and publishes but never answers
    silent = [sys.executable, '-c', (
        'import rclpy, sys\n'
        'from sensor_msgs.msg import FluidPressure, JointState\n'
        'rclpy.init(args=sys.argv)\n'
        'n = rclpy.create_node("silent")\n'
        'n.create_publisher(FluidPressure, "brake_pipe/pressure", 10)\n'
        'n.create_subscription(JointState, "coaches", lambda m: None, 10)\n'
        'try:\n    rclpy.spin(n)\nexcept BaseException:\n    pass\n')]
    run = run_scenario(SCENARIO, silent, tmp_path / 'run', lockstep_timeout=0.5, timeout=60)
    assert run.returncode == 4
    assert not run.passed
    assert 'sim_node exited with status 4' in run.error
    assert 'lockstep' in run.error


def test_criteria_parse_and_check():
    c = Criterion.parse('max_jerk', {'max': 1})
    assert c.check({'max_jerk': 0.5}).passed
    assert not c.check({'max_jerk': 1.5}).passed
    assert not c.check({'max_jerk': None}).passed
    assert 'the run has no max_jerk' in c.check({}).text
    assert Criterion.parse('stopped', {'equals': True}).check({'stopped': True}).passed
    assert not Criterion.parse('max_jerk', {'min': 2, 'max': 3}).check({'max_jerk': 1.0}).passed
    assert not Criterion.parse('stopped', {'equals': True}).check({'stopped': 1}).passed
    for bad in ({}, {'maximum': 1}, {'max': 'high'}, 3):
        with pytest.raises(ConfigError):
            Criterion.parse('max_jerk', bad)


def test_scenario_file_errors_are_one_line(tmp_path):
    path = tmp_path / 's.yaml'
    path.write_text('duration: 5\ncriterion: {}\n')
    with pytest.raises(ConfigError, match='unknown key'):
        Scenario.load(path)
    path.write_text('parameters: {}\n')
    with pytest.raises(ConfigError, match='duration'):
        Scenario.load(path)
