"""
``sim_node``'s controller-facing outputs: odometry, distance to go, a target moved live.

The lead vehicle's odometry, the distance to go and the stopping target moved by its input
topic (recorded where it took effect).
"""
from __future__ import annotations

from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

from train_dynamics.recording.bags import read_topics


def _key(msg) -> tuple[int, int]:
    return msg.header.stamp.sec, msg.header.stamp.nanosec


def test_the_node_moves_the_target_and_measures_the_distance_to_go(harness, tmp_path):
    odom = harness.collect(Odometry, 'odom')
    togo = harness.collect(JointState, 'distance_to_go')
    coaches = harness.collect(JointState, 'coaches')
    bag = tmp_path / 'bag'
    node = harness.start(initial_position=100.0, target_stop_position=[2000.0],
                         real_time_factor=2.0, record_bag=str(bag))
    assert harness.wait(lambda: len(togo) >= 5 and len(odom) >= 5, 20.0)
    pub = harness.probe.create_publisher(
        Float64, 'target_stop_position', QoSProfile(depth=10,
                                                    reliability=ReliabilityPolicy.RELIABLE))
    assert harness.wait_for_subscriber(pub, 10.0)
    pub.publish(Float64(data=float('nan')))            # rejected: changes nothing
    pub.publish(Float64(data=2500.0))
    assert harness.wait(lambda: togo and togo[-1].effort[0] == 2500.0, 20.0)
    harness.spin_for(0.2)
    harness.stop(node)
    assert {m.effort[0] for m in togo} == {2000.0, 2500.0}
    # every distance to go is the target minus the odometry's front of vehicle 1, and that
    # front is initial_position + coaches.position[0] of the same instant
    front = {_key(m): m.pose.pose.position.x for m in odom}
    x1 = {_key(m): m.position[0] for m in coaches}
    both = [m for m in togo if _key(m) in front and _key(m) in x1]
    assert len(both) >= 5
    for m in both:
        assert front[_key(m)] == 100.0 + x1[_key(m)]
        assert m.position[0] == m.effort[0] - front[_key(m)]
    assert odom[0].header.frame_id == 'track' and odom[0].child_frame_id == 'coach_1'
    assert odom[-1].twist.twist.linear.x > 0.0
    # the bag holds the accepted target (one message) and the outputs of the new topics
    moved = [m for _, _, m in read_topics(bag, ['target_stop_position'])]
    assert [m.data for m in moved] == [2500.0]
    recorded = {topic for topic, _, _ in read_topics(bag, ['odom', 'distance_to_go'])}
    assert recorded == {'odom', 'distance_to_go'}
