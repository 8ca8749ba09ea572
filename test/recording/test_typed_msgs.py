"""
The typed outputs (``train_dynamics_msgs``): train, coupler and brake state, offline.

Their definitions are the package's ``.msg`` files, registered in the rosbags typestore (no
rclpy); their values are those of the JointState outputs, field by field, and the
acceleration the speed change over the output period.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from train_dynamics import topics
from train_dynamics.cli import offline as cli
from train_dynamics.recording import typed_msgs
from train_dynamics.recording.bags import BagRecorder, read_topics
from train_dynamics.recording.cdr import encode_fluid_pressure
from train_dynamics.recording.messages import serialize, typestore

REPO = Path(__file__).resolve().parents[2]


def test_the_typestore_has_the_packages_message_definitions():
    folder = REPO / 'msgs' / 'train_dynamics_msgs' / 'msg'
    assert typed_msgs.definition_folder() == folder
    types = typestore().types
    for path in folder.glob('*.msg'):
        assert f'train_dynamics_msgs/msg/{path.stem}' in types, path.name
    assert typed_msgs.array_fields('train_dynamics_msgs/msg/TrainState') == (
        'position', 'speed', 'acceleration', 'braking_force')
    wsp = types['train_dynamics_msgs/msg/WspValve']
    assert (wsp.NORMAL, wsp.HOLD, wsp.VENT) == (0, 1, 2)


def test_a_typed_state_is_the_bytes_rosbags_gives():
    types = typestore().types
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=3, nanosec=250_000_000),
        frame_id='track')
    msg = types['train_dynamics_msgs/msg/BrakeState'](
        header=header, pipe_pressure=np.array([5e5, 4.9e5]),
        cylinder_pressure=np.array([0.0, 1.0]), auxiliary_reservoir_pressure=np.zeros(0),
        control_reservoir_pressure=np.zeros(0))
    arrays = ([5e5, 4.9e5], [0.0, 1.0], None, None)
    assert typed_msgs.typed_bytes(3_250_000_000, arrays) == serialize(msg)


def _by_topic(bag: Path, names):
    return {name: [m for _, _, m in read_topics(bag, [name])] for name in names}


def test_the_typed_outputs_carry_the_joint_state_values(tmp_path):
    out = tmp_path / 'run'
    assert cli.main(['simulate', '--params', 'config/paper_3coach.yaml', '--duration', '2',
                     '--output', str(out), '-q']) == 0
    got = _by_topic(out, ['train_state', 'coupler_state', 'brake_state', 'coaches', 'couplers',
                          'brake_cylinders', 'vehicle_motion'])
    assert len(got['train_state']) == len(got['coaches']) == 201
    train, coaches = got['train_state'], got['coaches']
    assert all((t.header.stamp.sec, t.header.stamp.nanosec, t.header.frame_id)
               == (c.header.stamp.sec, c.header.stamp.nanosec, 'track')
               for t, c in zip(train, coaches))
    pos = np.array([m.position for m in train])
    v = np.array([m.speed for m in train])
    acc = np.array([m.acceleration for m in train])
    # the fronts of the 25 m coaches start at 0, -25 and -50 m (initial_position 0)
    x = np.array([c.position for c in coaches])
    np.testing.assert_array_equal(pos, x + np.array([0.0, -25.0, -50.0]))
    np.testing.assert_array_equal(v, np.array([c.velocity for c in coaches]))
    np.testing.assert_array_equal(np.array([m.braking_force for m in train]),
                                  np.array([c.effort for c in coaches]))
    assert np.all(acc[0] == 0.0)
    np.testing.assert_allclose(acc[1:], np.diff(v, axis=0) / 0.01, rtol=1e-12, atol=1e-12)
    assert acc[-1, 0] < -0.2                   # braking: the emergency applied at t = 1 s
    for typed, joint in zip(got['coupler_state'], got['couplers']):
        np.testing.assert_array_equal(typed.force, joint.effort)
        np.testing.assert_array_equal(typed.stroke, joint.position)
        np.testing.assert_array_equal(typed.stroke_rate, joint.velocity)
    assert len(got['coupler_state'][-1].force) == 2
    for typed, joint in zip(got['brake_state'], got['brake_cylinders']):
        np.testing.assert_array_equal(typed.cylinder_pressure, joint.position)
        np.testing.assert_array_equal(typed.pipe_pressure, joint.effort)
        # the empirical brake models no reservoirs: their arrays are empty
        assert len(typed.auxiliary_reservoir_pressure) == 0
        assert len(typed.control_reservoir_pressure) == 0
    assert got['brake_state'][-1].cylinder_pressure[0] > 1e5     # applied, gauge [Pa]


def test_the_pneumatic_brakes_typed_state_has_the_reservoirs(tmp_path):
    out = tmp_path / 'run'
    assert cli.main(['simulate', '--params', 'config/passenger_pneumatic_40.yaml',
                     '--duration', '0.05', '--output', str(out), '-q']) == 0
    got = _by_topic(out, ['brake_state', 'brake_reservoirs'])
    assert len(got['brake_state']) == len(got['brake_reservoirs']) > 0
    for typed, joint in zip(got['brake_state'], got['brake_reservoirs']):
        assert len(typed.auxiliary_reservoir_pressure) == len(joint.name) > 30
        np.testing.assert_array_equal(typed.auxiliary_reservoir_pressure, joint.position)
        np.testing.assert_array_equal(typed.control_reservoir_pressure, joint.effort)
    # charged: the auxiliary reservoirs near the 5 bar gauge of a released brake
    assert 4.5e5 < got['brake_state'][-1].auxiliary_reservoir_pressure[0] < 5.5e5


def _typed_command(msgtype: str, t_ns: int, **values) -> bytes:
    """Return the CDR bytes of a stamped command of ``msgtype`` (rosbags' encoding)."""
    types = typestore().types
    sec, nanosec = divmod(t_ns, 1_000_000_000)
    header = types['std_msgs/msg/Header'](
        stamp=types['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec), frame_id='')
    return serialize(types[msgtype](header=header, **values))


def test_a_stamped_traction_command_of_an_input_bag_drives_the_locomotive(tmp_path):
    (tmp_path / 'train.yaml').write_text(
        'vehicles:\n  - {type: electric_passenger_locomotive, traction_build_up_time: 1.0}\n'
        '  - {type: passenger_coach, count: 3}\n')
    params = tmp_path / 'p.yaml'
    params.write_text('train_dynamics:\n  ros__parameters:\n    consist_file: train.yaml\n'
                      '    initial_speed: 20.0\n')
    inp = tmp_path / 'in'
    rec = BagRecorder(inp)
    rec.add_topic(topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE)
    rec.add_topic('coach_1/traction/command_stamped', topics.TRACTION_COMMAND)
    rec.write(topics.HEAD_PIPE_TOPIC, 0, encode_fluid_pressure(0, 601325.0))
    rec.write('coach_1/traction/command_stamped', 0,
              _typed_command(topics.TRACTION_COMMAND, 0, command=0.8))
    rec.write('coach_1/traction/command_stamped', 1_000_000_000,          # refused: > 1
              _typed_command(topics.TRACTION_COMMAND, 1_000_000_000, command=7.0))
    rec.close()
    out = tmp_path / 'out'
    assert cli.main(['simulate', '--params', str(params), '--input', str(inp),
                     '--duration', '3', '--output', str(out), '-q']) == 0
    forces = [m for _, _, m in read_topics(out, [topics.VEHICLE_FORCES_TOPIC])][-1]
    # 0.8 of the locomotive's 300 kN, built up over 1 s: more than half of it after 3 s
    assert forces.position[0] > 0.5 * 300e3 * 0.8 and forces.position[1] == 0.0
    recorded = [(t, m.command) for _, t, m in
                read_topics(out, ['coach_1/traction/command_stamped'])]
    assert recorded == [(0, 0.8)]
