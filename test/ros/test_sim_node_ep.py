"""sim_node's EP / ECP input brake_ep/command, real rclpy."""
from __future__ import annotations

import numpy as np

from sim_node_helpers import diag_values

INPUT = 'train_dynamics: brake input'


def test_ep_command_applied_validated_and_train_line_supervised(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(num_coaches=4, brake_model='pneumatic', brake_system='ep',
                         initial_speed=20.0, real_time_factor=2.0, input_timeout=1.5)
    pub = harness.probe.create_publisher(
        Float64, 'brake_ep/command', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    assert harness.wait_for_subscriber(pub)
    for value in (float('nan'), 1.5, 0.5):
        pub.publish(Float64(data=value))
        harness.spin_for(0.05)
    assert harness.wait(lambda: node.simulator.pneu.ep_command_received == 0.5, 5.0)

    send = harness.every(0.02, lambda: pub.publish(Float64(data=0.5)))

    def held():          # the controller keeps sending at 50 Hz: the train line stays healthy
        send()
        return np.all(np.abs(node.simulator.cylinder_pressure - 1.9e5) < 0.05e5)
    assert harness.wait(held, 20.0)
    assert node.simulator.pneu.train_line
    assert harness.wait(lambda: (diag_values(diags, INPUT) or {}).get(
        'rejected_out_of_range') == '1', 5.0)
    assert int(diag_values(diags, INPUT)['rejected_non_finite']) >= 1
    # no command for input_timeout: the train line is lost, the pipe brakes instead
    assert harness.wait(lambda: not node.simulator.pneu.train_line, 5.0)
    assert harness.wait(lambda: node.simulator.pneu.pipe_pressure[0] < 4.4e5, 5.0)
    pub.publish(Float64(data=0.0))
    assert harness.wait(lambda: node.simulator.pneu.train_line, 5.0)


def test_lockstep_waits_for_each_ep_command_and_applies_it_at_its_output(harness, tmp_path):
    """
    ``lockstep_inputs: [ep]``: one ``brake_ep/command`` per output releases each period.

    The probe answers every ``coaches`` output with a command; the bag holds one command per
    output, recorded at that output's time (it acted there), and the run reaches its end.
    """
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64
    from train_dynamics.recording.bags import read_topics

    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pub = harness.probe.create_publisher(Float64, 'brake_ep/command', qos)
    harness.probe.create_subscription(
        JointState, 'coaches', lambda msg: pub.publish(Float64(data=0.5)), qos)
    bag = tmp_path / 'bag'
    node = harness.start(num_coaches=4, brake_model='pneumatic', brake_system='ep',
                         initial_speed=20.0, sync_mode='lockstep', lockstep_inputs=['ep'],
                         real_time_factor=0.0, duration=0.3, record_bag=str(bag))
    assert harness.wait(lambda: node.finished, 30.0)
    assert node.simulator.pneu.ep_command_received == 0.5
    harness.stop(node)
    outputs, commands = [], []
    for topic, t_ns, _ in read_topics(bag, ['coaches', 'brake_ep/command']):
        (outputs if topic == 'coaches' else commands).append(t_ns)
    assert outputs == [k * 10_000_000 for k in range(31)]
    assert commands == outputs
