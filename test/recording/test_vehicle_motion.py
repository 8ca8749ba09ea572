"""
``vehicle_motion``: track position, speed and acceleration per vehicle, offline and live.

The offline command and ``sim_node`` write the same bytes (one encoder); the acceleration is
the speed change over the last output period, the position the front's place on the track.
Every JointState output carries the frame_id ``track``.
"""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import JointState

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.param_files import load_param_file
from train_dynamics.recording.bags import read_topics
from train_dynamics.recording.output_specs import active


def test_offline_motion_is_track_position_speed_and_acceleration(tmp_path):
    out = tmp_path / 'run'
    assert cli.main(['simulate', '--params', 'config/paper_3coach.yaml', '--duration', '2',
                     '--output', str(out), '-q']) == 0
    motion = [m for _, _, m in read_topics(out, ['vehicle_motion'])]
    coaches = [m for _, _, m in read_topics(out, ['coaches'])]
    assert len(motion) == len(coaches) == 201
    assert all(m.header.frame_id == 'track' and m.header.stamp == c.header.stamp
               for m, c in zip(motion, coaches))
    x = np.array([c.position for c in coaches])
    v = np.array([c.velocity for c in coaches])
    pos = np.array([m.position for m in motion])
    acc = np.array([m.effort for m in motion])
    # initial_position 0: the fronts of the 25 m coaches start at 0, -25 and -50 m
    assert np.array_equal(pos, x + np.array([0.0, -25.0, -50.0]))
    assert np.array_equal(np.array([m.velocity for m in motion]), v)
    assert np.all(acc[0] == 0.0)
    assert np.allclose(acc[1:], np.diff(v, axis=0) / 0.01, rtol=1e-12, atol=1e-12)
    assert acc[-1, 0] < -0.2                # braking: the emergency applied at t = 1 s


def test_every_joint_state_output_is_in_the_track_frame(tmp_path):
    out = tmp_path / 'run'
    assert cli.main(['simulate', '--params', 'config/passenger_pneumatic_40.yaml',
                     '--duration', '0.05', '--output', str(out), '-q']) == 0
    frames = {}
    for topic, _, msg in read_topics(out):
        if hasattr(msg, 'name'):
            frames.setdefault(topic, set()).add(msg.header.frame_id)
    cfg = load_param_file('config/passenger_pneumatic_40.yaml')
    joint_states = [s.topic for s in active(cfg) if s.msgtype == topics.JOINT_STATE]
    assert {'couplers', 'coaches', 'brake_cylinders', 'brake_reservoirs', 'vehicle_forces',
            'vehicle_motion'} <= set(joint_states)
    assert frames == dict.fromkeys(joint_states, {'track'})


def test_the_node_publishes_vehicle_motion(harness):
    outputs = {topic: harness.collect(JointState, topic)
               for topic in ('couplers', 'coaches', 'brake_cylinders', 'vehicle_motion')}
    motion = outputs['vehicle_motion']
    node = harness.start(real_time_factor=2.0)
    assert harness.wait(lambda: all(len(m) >= 20 for m in outputs.values()), 10.0)
    assert all(m[0].header.frame_id == 'track' for m in outputs.values())
    assert list(motion[0].name) == ['coach_1', 'coach_2', 'coach_3']
    assert node.sim_time > 0
