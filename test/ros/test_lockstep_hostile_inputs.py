"""
Lock-step against hostile or broken controllers: what is refused, what is bounded, and how.

Read as a list (``sim_node`` in ``sync_mode`` lockstep, in-process, real DDS on loopback):

- no controller at all: the start waits ``lockstep_timeout``, then names what is missing
  (the input topics without a publisher, no reader of the outputs); ``stop`` ends the run
  with status 4 at t = 0;
- a controller that pauses longer than ``input_timeout`` under ``on_input_timeout``
  emergency: the fail-safe acts, and its next answer releases the period again;
- a controller that answers an output twice: the first answer is used, the second is not,
  counted (``/diagnostics`` ``lockstep_duplicate_answers``, the run's summary) and warned;
  traction commands sent twice per output are counted the same way;
- a second publisher on a lock-step input, or a best-effort one (lock-step inputs are
  subscribed reliable): the run ends before its first period (status 4);
- a declared lock-step input the train does not have (``lockstep_inputs: [ep]`` without an EP
  brake): a configuration error (one line, status 2; a live change to it is rejected);
- a pause (``~/pause``) or a lock-step wait at ``real_time_factor`` 1: not counted as lag.

Every wait here is on an event with a generous bound; no verdict depends on timing.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from diagnostic_msgs.msg import DiagnosticArray
import pytest
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from sim_node_helpers import diag_values, fluid, stamp_s
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from train_dynamics.physics.config import ConfigError
from train_dynamics.ros.run_control import EXIT_LOCKSTEP_TIMEOUT
from train_dynamics.ros.sim_node import SimNode

ATM = 101325.0
ROOT = Path(__file__).resolve().parents[2]
RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
SIMULATION = 'train_dynamics: simulation'
WAIT = 60.0          # [s wall] bound of every wait on an event (a loaded machine is slow)


def _controller(harness, answers=lambda msg: [4.5e5], topic='brake_pipe/pressure',
                reliability=ReliabilityPolicy.RELIABLE):
    """Return (publisher, outputs seen): a probe answering each ``coaches`` output."""
    pub = harness.probe.create_publisher(FluidPressure, topic,
                                         QoSProfile(depth=10, reliability=reliability))
    seen = []

    def on_coaches(msg):
        seen.append(msg)
        for gauge in answers(msg):
            out = fluid(gauge + ATM)
            out.header.stamp = msg.header.stamp
            pub.publish(out)
    harness.probe.create_subscription(JointState, 'coaches', on_coaches, RELIABLE)
    return pub, seen


def test_no_controller_times_out_at_t0_naming_the_missing_inputs_then_stops(harness):
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0, lockstep_timeout=0.5)
    assert harness.wait(lambda: (diag_values(diags, SIMULATION) or {})
                        .get('lockstep_timeouts') == '1', WAIT)
    d = diag_values(diags, SIMULATION)
    assert 'the controller to connect' in d['_message']
    assert 'a publisher on /brake_pipe/pressure' in d['_message']
    assert 'a subscriber on the outputs' in d['_message']
    assert node.sim_time == 0.0 and not node.finished          # wait: reported, waits on
    harness.stop(node)

    stopping = harness.start(sync_mode='lockstep', real_time_factor=0.0, lockstep_timeout=0.5,
                             lockstep_on_timeout='stop')
    assert harness.wait(lambda: stopping.finished, WAIT)
    assert stopping.exit_code == EXIT_LOCKSTEP_TIMEOUT and stopping.sim_time == 0.0


def test_an_answer_after_the_input_timeout_fail_safe_releases_the_period(harness):
    """
    The controller falls silent after five outputs for longer than ``input_timeout``.

    ``on_input_timeout`` emergency vents the pipe meanwhile; its late answer makes the input
    fresh again and must release the period (it used to hang for ever; with ``stop`` the run
    ended blaming the controller that had answered).
    """
    silent = []
    pub, seen = _controller(harness, answers=lambda msg: [] if silent else [4.5e5])
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0, duration=0.2,
                         input_timeout=0.3, on_input_timeout='emergency',
                         lockstep_timeout=30.0, lockstep_on_timeout='stop')

    def go_silent():
        if len(seen) >= 5:
            silent.append(True)
        return silent
    assert harness.wait(go_silent, WAIT)
    assert harness.wait(lambda: node._inputs.emergency, WAIT)     # the fail-safe acts
    assert len(seen) == 5 or len(seen) == 6
    silent.clear()
    out = fluid(4.5e5 + ATM)
    out.header.stamp = seen[-1].header.stamp
    pub.publish(out)
    assert harness.wait(lambda: node.finished, WAIT)
    assert node.exit_code == 0 and round(node.sim_time, 9) == 0.2
    assert [round(stamp_s(m), 9) for m in seen] == [k / 100 for k in range(21)]


def test_a_controller_answering_twice_has_its_first_answer_used_and_the_second_counted(
        harness, tmp_path):
    from train_dynamics.recording.bags import read_topics

    bag = tmp_path / 'bag'
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    _controller(harness, answers=lambda msg: [4.5e5, 3.0e5])      # first, then a second
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0, duration=0.5,
                         record_bag=str(bag))
    assert harness.wait(lambda: node.finished, WAIT)
    assert harness.wait(lambda: node._inputs.duplicates >= 50, WAIT)
    assert 'duplicate answers not used' in node._control.summary()
    assert harness.wait(lambda: int((diag_values(diags, SIMULATION) or {})
                                    .get('lockstep_duplicate_answers', 0)) >= 50, WAIT)
    harness.stop(node)
    pressures = [m.fluid_pressure for _, _, m in read_topics(bag, ['brake_pipe/pressure'])]
    assert len(pressures) == 51 and set(pressures) == {4.5e5 + ATM}    # only the first


def test_traction_commands_sent_twice_per_output_are_counted_as_duplicates(harness):
    """
    A controller sends two traction commands per output, then the brake answer.

    A period waits for both (``lockstep_inputs: [brake, traction]``) and uses one command;
    the others are not used and counted. (A ``Float64`` has no stamp: which of the two
    answers depends on arrival, so only the count is certain; one command per output.)
    """
    consist = ROOT / 'config' / 'consist_passenger_12.yaml'
    traction = harness.probe.create_publisher(Float64, 'coach_1/traction/command', RELIABLE)
    brake = harness.probe.create_publisher(FluidPressure, 'brake_pipe/pressure', RELIABLE)
    seen = []

    def on_coaches(msg):
        seen.append(msg)
        traction.publish(Float64(data=0.5))
        traction.publish(Float64(data=0.25))     # a second command: not used
        out = fluid(5e5 + ATM)
        out.header.stamp = msg.header.stamp
        brake.publish(out)
    harness.probe.create_subscription(JointState, 'coaches', on_coaches, RELIABLE)
    node = harness.start(consist_file=str(consist), initial_speed=10.0, sync_mode='lockstep',
                         lockstep_inputs=['brake', 'traction'], real_time_factor=0.0,
                         duration=0.3)
    assert harness.wait(lambda: node.finished, WAIT)
    assert node._control.periods == 31
    assert harness.wait(lambda: node._inputs.duplicates >= 15, WAIT)


@pytest.mark.parametrize('second', ['publisher', 'best_effort'])
def test_a_second_or_best_effort_publisher_on_a_lockstep_input_ends_the_run_at_t0(
        harness, second):
    pub, seen = _controller(harness, reliability=ReliabilityPolicy.RELIABLE
                            if second == 'publisher' else ReliabilityPolicy.BEST_EFFORT)
    if second == 'publisher':
        harness.publisher('brake_pipe/pressure')           # e.g. a brake valve left running
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0, lockstep_timeout=30.0)
    assert harness.wait(lambda: node.finished, WAIT)
    assert node.exit_code == EXIT_LOCKSTEP_TIMEOUT
    assert node.sim_time == 0.0 and not seen                   # no period ran


def test_a_declared_lockstep_input_the_train_lacks_is_a_configuration_error(harness):
    with pytest.raises(ConfigError, match='lockstep_inputs ep: the train has no such input'):
        SimNode(parameter_overrides=[Parameter('sync_mode', value='lockstep'),
                                     Parameter('lockstep_inputs', value=['ep'])])
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0)
    result = node.set_parameters([Parameter('lockstep_inputs', value=['brake', 'traction'])])
    assert not result[0].successful and 'no locomotive' in result[0].reason
    assert list(node.get_parameter('lockstep_inputs').value) == ['brake']
    free = node.set_parameters([Parameter('sync_mode', value='free')])[0]
    assert free.successful                                     # free mode waits for nothing


def test_sim_node_exits_2_with_one_line_for_a_lockstep_input_the_train_lacks():
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]))
    proc = subprocess.run(
        [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args', '-p',
         'sync_mode:=lockstep', '-p', 'lockstep_inputs:=[ep]'],
        capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and 'lockstep_inputs ep' in lines[0], proc.stderr


def _call(harness, name: str) -> None:
    resp = harness.call(Trigger, f'/train_dynamics/{name}', Trigger.Request())
    assert resp.success, resp.message


def test_paused_time_is_not_counted_as_lag(harness):
    node = harness.start(real_time_factor=1.0)
    assert harness.wait(lambda: node.sim_time > 0.1, WAIT)
    _call(harness, 'pause')
    t_paused = node.sim_time
    harness.spin_for(2.0)                      # longer than the lag the pacing drops (1 s)
    assert node.sim_time == t_paused
    _call(harness, 'resume')
    assert harness.wait(lambda: node.sim_time > t_paused + 0.2, WAIT)
    assert node._pacer.lag_events == 0 and node._pacer.lag_dropped == 0.0


def test_a_lockstep_wait_at_real_time_is_not_counted_as_lag(harness):
    silent = []
    pub, seen = _controller(harness, answers=lambda msg: [] if len(seen) > 3 and not silent
                            else [4.5e5])
    node = harness.start(sync_mode='lockstep', real_time_factor=1.0, duration=0.1)
    assert harness.wait(lambda: len(seen) >= 4, WAIT)
    harness.spin_for(2.0)                      # the node waits for the answer meanwhile
    silent.append(True)
    out = fluid(4.5e5 + ATM)
    out.header.stamp = seen[-1].header.stamp
    pub.publish(out)
    assert harness.wait(lambda: node.finished, WAIT)
    assert node._pacer.lag_events == 0 and node._pacer.lag_dropped == 0.0
