"""
The stamped commands of ``train_dynamics_msgs`` beside the Float64 / Int8 ones.

A typed command is its plain twin's input (same rule, setter, vehicles, lock-step family),
from a message with a header: in lock-step it answers the output of its stamp, not the one
published before it arrived. ``sim_node`` in-process, real DDS on loopback; every wait is on
an event with a generous bound.
"""
from __future__ import annotations

from pathlib import Path

from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, JointState
from sim_node_helpers import fluid

from train_dynamics.recording.bags import read_topics
from train_dynamics_msgs.msg import TractionCommand

ATM = 101325.0
ROOT = Path(__file__).resolve().parents[2]
CONSIST = ROOT / 'config' / 'consist_passenger_12.yaml'
RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
WAIT = 60.0          # [s wall] bound of every wait on an event (a loaded machine is slow)


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def test_a_stamped_traction_command_answers_the_output_of_its_stamp(harness, tmp_path):
    """
    Lock-step on brake and traction, the traction from ``TractionCommand`` only.

    Each output is answered by the brake pipe and a typed command stamped with it, except
    the fifth: its command carries the previous output's stamp. That one does not answer the
    fifth output (a Float64 arriving then would have): the period waits until the command of
    the right stamp comes. Each command acts at the output of its stamp, recorded there.
    """
    traction = harness.probe.create_publisher(TractionCommand,
                                              'coach_1/traction/command_stamped', RELIABLE)
    brake = harness.probe.create_publisher(FluidPressure, 'brake_pipe/pressure', RELIABLE)
    seen = []

    def command(stamp, value):
        msg = TractionCommand(command=value)
        msg.header.stamp = stamp
        traction.publish(msg)

    def on_coaches(msg):
        seen.append(msg)
        out = fluid(5e5 + ATM)
        out.header.stamp = msg.header.stamp
        brake.publish(out)
        if len(seen) == 5:
            command(seen[-2].header.stamp, 0.9)        # the previous output's stamp
        else:
            command(msg.header.stamp, 0.1 * (len(seen) % 5))
    harness.probe.create_subscription(JointState, 'coaches', on_coaches, RELIABLE)
    bag = tmp_path / 'bag'
    node = harness.start(consist_file=str(CONSIST), initial_speed=10.0, sync_mode='lockstep',
                         lockstep_inputs=['brake', 'traction'], real_time_factor=0.0,
                         lockstep_timeout=0.0, record_bag=str(bag))
    assert harness.wait(lambda: len(seen) >= 5, WAIT)
    harness.spin_for(1.0)
    assert len(seen) == 5                                      # the fifth period waits
    command(seen[4].header.stamp, 0.4)                        # its own answer releases it
    assert harness.wait(lambda: len(seen) >= 8, WAIT)
    harness.stop(node)
    recorded = [(t, _ns(m.header.stamp), m.command) for _, t, m in
                read_topics(bag, ['coach_1/traction/command_stamped'])]
    outputs = [_ns(m.header.stamp) for m in seen]
    # every command that answered acts (is recorded) at the time of its stamp's output
    answered = [r for r in recorded if r[0] == r[1]]
    assert [t for t, _, _ in answered[:7]] == outputs[:7]
    assert [c for _, _, c in answered[:5]] == [0.1 * k for k in (1, 2, 3, 4)] + [0.4]


def test_on_the_clock_a_stamped_traction_command_answers_its_period(harness, tmp_path):
    """
    ``lockstep_answer: clock``: a controller on the simulation clock, typed traction only.

    The probe answers each ``/clock`` tick with the brake pipe and a ``TractionCommand``
    stamped with that time, as a timer on ``use_sim_time`` would; every period of the run is
    answered and each command is recorded at its stamp.
    """
    traction = harness.probe.create_publisher(TractionCommand,
                                              'coach_1/traction/command_stamped', RELIABLE)
    brake = harness.probe.create_publisher(FluidPressure, 'brake_pipe/pressure', RELIABLE)
    ticks = []

    def on_clock(msg):
        ticks.append(_ns(msg.clock))
        out = fluid(5e5 + ATM)
        out.header.stamp = msg.clock
        brake.publish(out)
        cmd = TractionCommand(command=0.5)
        cmd.header.stamp = msg.clock
        traction.publish(cmd)
    harness.probe.create_subscription(Clock, '/clock', on_clock, RELIABLE)
    bag = tmp_path / 'bag'
    node = harness.start(consist_file=str(CONSIST), initial_speed=10.0, sync_mode='lockstep',
                         lockstep_inputs=['brake', 'traction'], lockstep_answer='clock',
                         real_time_factor=0.0, duration=0.3, record_bag=str(bag))
    assert harness.wait(lambda: node.finished, WAIT)
    assert node.exit_code == 0
    harness.stop(node)                               # the bag closed
    recorded = [(t, _ns(m.header.stamp)) for _, t, m in
                read_topics(bag, ['coach_1/traction/command_stamped'])]
    assert len(recorded) >= 30 and all(t == s for t, s in recorded)
