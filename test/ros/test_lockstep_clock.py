"""
Lock-step on the simulation clock: a timer-driven controller on ``use_sim_time``, unchanged.

``lockstep_answer: clock``: ``sim_node`` publishes ``/clock`` at every output and waits, every
``lockstep_period``, for the brake input stamped at or after that time. The controller
(``test/lockstep_timer_controller.py``) is an ordinary ROS 2 node: a timer on its clock, the
latest ``coaches`` message, a stamp from ``get_clock().now()``. Both run as processes of their
own through the harness (:mod:`train_dynamics.testing`), as a user's CI would.
"""
from __future__ import annotations

from pathlib import Path
import sys

import pytest

from train_dynamics.recording.bags import read_topics
from train_dynamics.testing import harness, run_scenario

ROOT = Path(__file__).resolve().parents[2]
ATM = 101325.0
PERIOD_NS = 20_000_000      # [ns] the controller's timer and the output period: 0.02 s
DURATION = 3.0              # [s simulated]


@pytest.fixture
def no_report(monkeypatch):
    """Skip the harness's metrics report: these tests look at the bags themselves."""
    monkeypatch.setattr(harness, '_metrics', lambda bag, out, namespace: {'report': 'skipped'})


def _files(bag: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(bag.iterdir())}


def test_timer_driven_controller_on_sim_time_runs_in_lockstep_byte_identical(
        tmp_path, no_report):
    from lockstep_timer_controller import pipe_pressure

    scenario = tmp_path / 'clock.yaml'
    scenario.write_text(
        'parameters: {num_coaches: 3, initial_speed: 20.0, lockstep_answer: clock, '
        'publish_rate: 50.0}\n'
        f'duration: {DURATION}\n')
    ctl = [sys.executable, str(ROOT / 'test' / 'lockstep_timer_controller.py'),
           '--ros-args', '-p', 'period:=0.02', '-p', 'gain:=10000.0']
    runs = [run_scenario(scenario, ctl, tmp_path / f'run{k}') for k in (1, 2)]
    for run in runs:
        assert run.returncode == 0 and not run.error, run.report()
    first, second = (_files(run.bag) for run in runs)
    assert first.keys() == second.keys()
    for name in first:
        assert first[name] == second[name], f'{name} differs between the two runs'

    speeds, commands, clock = {}, [], []
    for topic, t_ns, msg in read_topics(runs[0].bag,
                                        ['coaches', 'brake_pipe/pressure', '/clock', 'clock']):
        if topic == 'coaches':
            speeds[t_ns] = msg.velocity[0]
        elif topic.endswith('clock'):
            clock.append(msg.clock.sec * 1_000_000_000 + msg.clock.nanosec)
        else:
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            commands.append((t_ns, stamp, msg.fluid_pressure))
    assert clock == sorted(speeds)                  # /clock at every output, t = 0 on
    periods = round(DURATION * 1e9 / PERIOD_NS)
    # one command per timer period (none at t = 0: a timer fires one period after its
    # start), acting at its period's time, stamped with it, computed from that period's
    # output: the loop closed period by period
    assert [t for t, _, _ in commands] == [k * PERIOD_NS for k in range(1, periods + 1)]
    assert all(t == stamp for t, stamp, _ in commands)
    for t, _, p in commands:
        assert p == pipe_pressure(speeds[t], 1.0e4) + ATM, t
    assert speeds[max(speeds)] < speeds[0] - 1.0    # the controller's brake acted


def test_lockstep_period_waits_only_at_its_multiples_of_the_clock(harness):
    """
    ``lockstep_period`` 0.05 s at 100 Hz outputs: a wait every fifth output, none at t = 0.

    The probe answers a ``/clock`` at a multiple of 0.05 s with a command stamped there; the
    run reaches its end (0.3 s) on those six answers alone, every output published.
    """
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from sim_node_helpers import fluid

    pub = harness.publisher('brake_pipe/pressure')
    answered = []

    def on_clock(msg):
        t_ns = msg.clock.sec * 1_000_000_000 + msg.clock.nanosec
        if t_ns > 0 and t_ns % 50_000_000 == 0 and t_ns not in answered:
            answered.append(t_ns)
            out = fluid(4.5e5 + ATM)
            out.header.stamp = msg.clock
            pub.publish(out)
    harness.probe.create_subscription(Clock, '/clock', on_clock, 10)
    coaches = harness.collect(JointState, 'coaches')
    node = harness.start(sync_mode='lockstep', lockstep_answer='clock', lockstep_period=0.05,
                         real_time_factor=0.0, duration=0.3)
    assert harness.wait(lambda: node.finished, 60.0)
    assert node.exit_code == 0 and node._control.periods == 6
    assert answered == [k * 50_000_000 for k in range(1, 7)]
    assert harness.wait(lambda: len(coaches) == 31, 60.0)
