"""
The output topics declared once (``recording/output_specs.py``), and what they carry.

The docs' topics table is the table's; every row's messages are the bytes ``rosbags`` gives
for the same values; the lead vehicle's odometry, the distance to go and the stop error of
``report`` against hand-computed figures.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.param_files import load_param_file
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.bags import bag_info, read_topics
from train_dynamics.recording.messages import deserialize, header, serialize, typestore
from train_dynamics.recording.output_specs import (active, markdown_table, output_bytes_per_sample,
                                                   OUTPUTS)
from train_dynamics.recording.outputs import output_topics, OutputEncoder

REPO = Path(__file__).resolve().parents[2]


def test_the_docs_show_the_generated_outputs_table():
    page = (REPO / 'docs' / 'ros_interface.md').read_text(encoding='utf-8')
    assert markdown_table() in page, 'regenerate: python -m train_dynamics.recording.output_specs'


def test_a_run_has_the_rows_whose_condition_holds_in_table_order():
    plain = SimConfig.from_dict({})
    always = tuple(s.topic for s in OUTPUTS if not s.when_text)
    assert output_topics(plain) == always
    assert always[:3] == ('couplers', 'coaches', 'brake_cylinders')      # the contract's
    assert {'vehicle_motion', 'odom'} <= set(always)
    rich = SimConfig.from_dict({'brake_model': 'pneumatic', 'brake_system': 'ep',
                                'davis_a': 1000.0, 'wheelsets': True,
                                'target_stop_position': [800.0]})
    unit_only = ('distributed_power/state', 'brake_blending', 'brake_demand/state')
    assert [s.topic for s in active(rich)] == [s.topic for s in OUTPUTS
                                               if s.topic not in unit_only]
    assert output_topics(rich).index('brake_reservoirs') == 3


def _messages(cfg: SimConfig, t: float):
    """Run ``cfg`` to ``t`` [s]; return the simulator and its outputs, decoded."""
    sim = TrainSimulator(cfg)
    sim.advance_to(t)
    enc = OutputEncoder(cfg)
    t_ns = int(round(sim.t * 1e9))
    data = enc.encode(t_ns, sim)
    return sim, t_ns, {topic: (raw, deserialize(raw, msgtype))
                       for topic, msgtype, raw in zip(enc.topics, enc.msgtypes, data)}


def test_every_output_is_the_bytes_rosbags_gives_for_its_values():
    cfg = SimConfig.from_dict({'brake_model': 'pneumatic', 'brake_system': 'ecp',
                               'davis_a': 1000.0, 'wheelsets': True,
                               'target_stop_position': [800.0], 'num_coaches': 4})
    _, _, out = _messages(cfg, 0.5)
    assert set(out) == set(output_topics(cfg)) and len(out) == len(OUTPUTS) - 3   # not DP
    for topic, (raw, msg) in out.items():                         # nor the unit's two
        assert serialize(msg) == raw, topic
        assert msg.header.frame_id == topics.TRACK_FRAME


def test_a_multiple_unit_has_the_brake_control_units_outputs_as_rosbags_encodes_them():
    cfg = load_param_file(str(REPO / 'config' / 'emu_flirt_4.yaml'))
    sim, _, out = _messages(cfg, 0.5)
    assert {'brake_blending', 'brake_demand/state'} <= set(out)
    for topic in ('brake_blending', 'brake_demand/state'):
        raw, msg = out[topic]
        assert serialize(msg) == raw, topic
    per_car = out['brake_blending'][1]
    np.testing.assert_array_equal(per_car.velocity, sim.brake_force)
    assert list(out['brake_demand/state'][1].name) == ['demand', 'achieved']


def test_odometry_is_the_lead_vehicle_along_the_track():
    # no brake applied, no resistance: the train coasts at 20 m/s; after 1 s the front of
    # vehicle 1 is at 250 + 20 = 270 m
    cfg = SimConfig.from_dict({'initial_position': 250.0, 'initial_speed': 20.0})
    sim, t_ns, out = _messages(cfg, 1.0)
    raw, odom = out['odom']
    assert (odom.header.stamp.sec, odom.header.stamp.nanosec) == divmod(t_ns, 10 ** 9)
    assert odom.header.frame_id == 'track' and odom.child_frame_id == 'coach_1'
    p, q = odom.pose.pose.position, odom.pose.pose.orientation
    assert p.x == pytest.approx(270.0, abs=1e-9) and (p.y, p.z) == (0.0, 0.0)
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, 0.0, 1.0)
    lin, ang = odom.twist.twist.linear, odom.twist.twist.angular
    assert lin.x == pytest.approx(20.0, abs=1e-12) and (lin.y, lin.z) == (0.0, 0.0)
    assert (ang.x, ang.y, ang.z) == (0.0, 0.0, 0.0)
    assert not np.any(odom.pose.covariance) and not np.any(odom.twist.covariance)
    types = typestore().types
    expected = types[topics.ODOMETRY](
        header=header(t_ns * 1e-9, 'track'), child_frame_id='coach_1',
        pose=types['geometry_msgs/msg/PoseWithCovariance'](
            pose=types['geometry_msgs/msg/Pose'](
                position=types['geometry_msgs/msg/Point'](x=p.x, y=0.0, z=0.0),
                orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0,
                                                                  w=1.0)),
            covariance=np.zeros(36)),
        twist=types['geometry_msgs/msg/TwistWithCovariance'](
            twist=types['geometry_msgs/msg/Twist'](
                linear=types['geometry_msgs/msg/Vector3'](x=lin.x, y=0.0, z=0.0),
                angular=types['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0)),
            covariance=np.zeros(36)))
    assert serialize(expected) == raw


def test_distance_to_go_is_the_target_minus_the_lead_front():
    # coasting at 20 m/s from 250 m: at 1 s the front is at 270 m, 600 - 270 = 330 m to go
    cfg = SimConfig.from_dict({'initial_position': 250.0, 'initial_speed': 20.0,
                               'target_stop_position': [600.0]})
    _, _, out = _messages(cfg, 1.0)
    msg = out['distance_to_go'][1]
    assert list(msg.name) == ['coach_1']
    assert msg.position[0] == pytest.approx(330.0, abs=1e-9)
    assert msg.velocity[0] == pytest.approx(20.0, abs=1e-12)
    assert msg.effort[0] == 600.0


def test_a_run_without_a_target_has_no_distance_to_go():
    assert 'distance_to_go' not in output_topics(SimConfig.from_dict({}))
    with pytest.raises(ConfigError, match='target_stop_position'):
        SimConfig.from_dict({'target_stop_position': [1.0, 2.0]})
    with pytest.raises(ConfigError, match='target_stop_position'):
        SimConfig.from_dict({'target_stop_position': [float('nan')]})


def _stopping_metrics(final_speed: float, **kwargs) -> RunMetrics:
    """Two vehicles from 0 m to 390 m (the last sample at ``final_speed``)."""
    m = RunMetrics(2, **kwargs)
    zeros = np.zeros(1)
    m.add(0.0, zeros, zeros, zeros, [0.0, 0.0], [10.0, 10.0], [0.0, 0.0])
    m.add(60.0, zeros, zeros, zeros, [390.0, 390.0], [final_speed] * 2, [1e4, 1e4])
    return m


def test_stop_error_is_the_final_front_position_minus_the_target():
    # the front starts at 100 m, stops after 390 m: at 490 m, 10 m short of 500 m
    at_rest = _stopping_metrics(0.0, target_stop_position=500.0, track_origin=100.0)
    assert at_rest.flat()['stop_error'] == pytest.approx(-10.0, abs=1e-12)
    moving = _stopping_metrics(1.0, target_stop_position=500.0, track_origin=100.0)
    assert moving.flat()['stop_error'] is None          # no stop to judge
    assert _stopping_metrics(0.0).flat()['stop_error'] is None      # no target


def test_report_gives_the_stop_error_of_a_braked_run(tmp_path):
    params = tmp_path / 'stop.yaml'
    params.write_text(
        '/**/train_dynamics:\n  ros__parameters:\n    initial_speed: 5.0\n'
        '    initial_position: 10.0\n    target_stop_position: [30.0]\n'
        '/**/brake_valve:\n  ros__parameters:\n    schedule: ["0.0:emergency"]\n')
    bag, rep = tmp_path / 'bag', tmp_path / 'report'
    assert cli.main(['simulate', '--params', str(params), '--duration', '20', '--output',
                     str(bag), '-q']) == 0
    assert 'distance_to_go' in bag_info(bag).topics
    coaches = [m for _, _, m in read_topics(bag, ['coaches'])]
    togo = [m for _, _, m in read_topics(bag, ['distance_to_go'])]
    assert coaches[-1].velocity[0] == 0.0
    front = 10.0 + coaches[-1].position[0]            # the front of vehicle 1 at the end
    assert togo[-1].position[0] == pytest.approx(30.0 - front, abs=1e-9)
    assert cli.main(['report', str(bag), '--output', str(rep), '-q']) == 0
    train = json.loads((rep / 'summary.json').read_text())['train']
    assert train['stopped'] and train['stop_error'] == pytest.approx(front - 30.0, abs=1e-9)
    # the run's own parameters give the same figure (the sweep's and the node's metrics)
    assert cli.main(['report', str(bag), '--output', str(tmp_path / 'r2'), '--params',
                     str(params), '-q']) == 0
    again = json.loads((tmp_path / 'r2' / 'summary.json').read_text())['train']
    assert again['stop_error'] == pytest.approx(front - 30.0, abs=1e-9)


def test_the_disk_estimate_counts_every_message_of_a_sample_exactly(tmp_path):
    cfg = SimConfig.from_dict({'target_stop_position': [100.0], 'num_coaches': 12})
    sizes = [len(data) for data in OutputEncoder(cfg).encode(0, TrainSimulator(cfg))]
    assert output_bytes_per_sample(cfg) == sum(sizes) + 48 * len(sizes)


def test_train_brake_force_is_the_sum_of_the_vehicles_braking_forces():
    # emergency from t = 0: after 10 s every cylinder is at p_max, so each of the three
    # 45 t coaches brakes with mu_a m g = 0.1 * 45000 * 9.81 = 44145 N (eq. 13): 132435 N
    cfg = SimConfig.from_dict({})
    sim = TrainSimulator(cfg)
    sim.set_head_pipe_pressure(0.0)
    sim.advance_to(10.0)
    enc = OutputEncoder(cfg)
    data = dict(zip(enc.topics, enc.encode(int(round(sim.t * 1e9)), sim)))
    msg = deserialize(data['train_brake_force'], topics.JOINT_STATE)
    assert list(msg.name) == ['train'] and len(msg.position) == len(msg.velocity) == 0
    assert msg.effort[0] == pytest.approx(3 * 0.1 * 45000.0 * 9.81, rel=1e-12)
