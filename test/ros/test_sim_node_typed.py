"""
``sim_node``'s typed outputs (``train_dynamics_msgs``) beside the JointState ones.

rclpy's classes of the built package read the node's bytes; every typed message of an
instant carries the values of the JointState outputs of that instant, and the bag records the
very bytes published.
"""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import JointState

from train_dynamics.recording.bags import read_topics
from train_dynamics_msgs.msg import BrakeState, CouplerState, TrainState


def _key(msg) -> tuple[int, int]:
    return msg.header.stamp.sec, msg.header.stamp.nanosec


def test_the_node_publishes_the_typed_states_beside_the_joint_states(harness, tmp_path):
    typed = {'train_state': harness.collect(TrainState, 'train_state'),
             'coupler_state': harness.collect(CouplerState, 'coupler_state'),
             'brake_state': harness.collect(BrakeState, 'brake_state')}
    joint = {topic: harness.collect(JointState, topic)
             for topic in ('coaches', 'couplers', 'brake_cylinders', 'vehicle_motion')}
    bag = tmp_path / 'bag'
    node = harness.start(real_time_factor=2.0, record_bag=str(bag))
    assert harness.wait(lambda: all(len(m) >= 20 for m in typed.values()), 20.0)
    harness.stop(node)
    by = {topic: {_key(m): m for m in msgs} for topic, msgs in {**typed, **joint}.items()}
    common = set.intersection(*(set(d) for d in by.values()))
    assert len(common) >= 10
    for k in common:
        train, coaches = by['train_state'][k], by['coaches'][k]
        assert train.header.frame_id == 'track'
        assert list(train.position) == list(by['vehicle_motion'][k].position)
        assert list(train.speed) == list(coaches.velocity)
        assert list(train.braking_force) == list(coaches.effort)
        assert list(train.acceleration) == list(by['vehicle_motion'][k].effort)
        couplers = by['couplers'][k]
        assert list(by['coupler_state'][k].force) == list(couplers.effort)
        assert list(by['coupler_state'][k].stroke) == list(couplers.position)
        brakes = by['brake_state'][k]
        assert list(brakes.cylinder_pressure) == list(by['brake_cylinders'][k].position)
        assert len(brakes.pipe_pressure) == 3 and len(brakes.auxiliary_reservoir_pressure) == 0
    # the bag: the typed topics as published (rosbags reads them from the .msg definitions)
    recorded = {_key(m): m for _, _, m in read_topics(bag, ['train_state'])}
    for k in common & set(recorded):
        np.testing.assert_array_equal(recorded[k].speed, by['train_state'][k].speed)
