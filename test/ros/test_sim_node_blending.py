"""
sim_node with blending builtin over real rclpy: brake_demand reaches the brake control unit.

A four-car unit (config/consist_flirt_4.yaml): a demand of half of full service brakes with
the ED brake of the motor cars first; an emergency then puts every cylinder at p_max.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

CONSIST = str(Path(__file__).resolve().parents[2] / 'config' / 'consist_flirt_4.yaml')


def _publisher(harness, topic):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    return harness.probe.create_publisher(
        Float64, topic, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))


def test_brake_demand_and_emergency_reach_the_brake_control_unit(harness):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    coaches = harness.collect(JointState, 'coaches')
    blending = harness.collect(JointState, 'brake_blending')
    state = harness.collect(JointState, 'brake_demand/state')
    node = harness.start(consist_file=CONSIST, brake_input='cylinder_per_coach',
                         blending='builtin', initial_speed=30.0, real_time_factor=2.0,
                         full_service_deceleration=1.1)
    demand = _publisher(harness, 'brake_demand')
    emergency = _publisher(harness, 'brake_emergency')
    assert harness.wait_for_subscriber(demand) and harness.wait_for_subscriber(emergency)
    assert harness.wait(lambda: len(coaches) > 5, 20.0)
    demand.publish(Float64(data=0.5))
    bcu = node.simulator.bcu
    # the demand ramps in at the jerk limit (0.55 s), the ED of both motor cars builds up
    assert harness.wait(lambda: bcu.demanded_deceleration == 0.55, 20.0)
    assert harness.wait(lambda: bcu.ed_force()[[0, 3]].min() > 20000.0, 20.0)
    assert bcu.ed_force()[[1, 2]].sum() == 0.0
    # published: the motor cars' ED force per car, the demand and the achieved deceleration
    assert harness.wait(lambda: blending and blending[-1].position[0] > 20000.0, 20.0)
    assert list(blending[-1].name) == [f'coach_{i}' for i in range(1, 5)]
    assert blending[-1].position[1] == 0.0
    assert harness.wait(lambda: state and abs(state[-1].position[1] - 0.55) < 0.02, 20.0)
    emergency.publish(Float64(data=1.0))
    assert harness.wait(lambda: np.all(node.simulator.cylinder_pressure > 0.99 * 380000.0),
                        20.0)
    mass = np.array([34000.0, 26000.0, 26000.0, 34000.0])
    assert harness.wait(lambda: np.allclose(coaches[-1].effort, 0.16 * 9.81 * mass,
                                            rtol=1e-3), 20.0)


def test_track_brake_command_reaches_the_track_brakes_without_the_emergency(harness):
    """``track_brake/command``: applied at 1.0, released at 0.0; the emergency stays off."""
    from std_msgs.msg import Float64

    node = harness.start(consist_file=CONSIST, brake_input='cylinder_per_coach',
                         blending='builtin', initial_speed=30.0, real_time_factor=2.0)
    command = _publisher(harness, 'track_brake/command')
    assert harness.wait_for_subscriber(command)
    track = node.simulator.bcu.track
    command.publish(Float64(data=1.0))
    assert harness.wait(lambda: track.applied_at is not None, 20.0)
    assert not node.simulator.bcu.emergency
    command.publish(Float64(data=0.0))
    assert harness.wait(lambda: track.applied_at is None, 20.0)
    command.publish(Float64(data=float('nan')))           # refused by the row's rule
    assert harness.wait(lambda: node._inputs.rejected['non_finite'] == 1, 20.0)
    assert track.applied_at is None
