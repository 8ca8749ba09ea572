"""Bag I/O: what BagRecorder writes, rosbags (and so ros2 bag) reads back, also after a kill."""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.rosbag2 import StoragePlugin, Writer
from sensor_msgs.msg import JointState

from train_dynamics.recording import cdr, messages
from train_dynamics.recording.bags import bag_info, BagError, BagRecorder, read_topics

JS = 'sensor_msgs/msg/JointState'
FP = 'sensor_msgs/msg/FluidPressure'
REPO = Path(__file__).resolve().parents[2]


def _couplers(t: float, k: int):
    return messages.joint_state(t, ['coupler_1', 'coupler_2'], [0.001 * k, -0.002 * k],
                                [0.1, -0.1], [1.0e5 * k, -2.0e5])


def test_write_read_roundtrip(tmp_path):
    bag = tmp_path / 'b'
    with BagRecorder(bag) as rec:
        rec.add_topic('couplers', JS)
        rec.add_topic('couplers', JS)                       # idempotent
        for k in range(50):
            rec.write_msg('couplers', k * 10_000_000, _couplers(k * 0.01, k))
        rec.write_msg('/brake_pipe/pressure', 123, messages.fluid_pressure(1.25, 101325.0 + 5e5))
    got = list(read_topics(bag))
    # time order: couplers at 0 ns, the pressure (written last) at 123 ns, couplers ...
    assert [t for t, _, _ in got] == ['couplers', 'brake_pipe/pressure'] + ['couplers'] * 49
    topic, t_ns, msg = got[1]
    assert t_ns == 123
    assert msg.fluid_pressure == pytest.approx(601325.0)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 250_000_000)
    _, t_ns, msg = got[-1]
    assert t_ns == 490_000_000
    assert list(msg.name) == ['coupler_1', 'coupler_2']
    np.testing.assert_allclose(msg.position, [0.049, -0.098])
    np.testing.assert_allclose(msg.effort, [4.9e6, -2.0e5])
    # topic filter accepts names with or without the leading '/'
    assert len(list(read_topics(bag, ['/couplers']))) == 50
    assert len(list(read_topics(bag, ['brake_pipe/pressure']))) == 1
    info = bag_info(bag)
    assert info.topics == {'couplers': (JS, 50), 'brake_pipe/pressure': (FP, 1)}
    assert (info.start_ns, info.end_ns, info.message_count) == (0, 490_000_000, 51)


def test_raw_cdr_from_rclpy_roundtrips(tmp_path):
    m = JointState()
    m.header.stamp.sec, m.header.stamp.nanosec = 7, 25
    m.name = ['coupler_1', 'coupler_2']
    m.position, m.velocity, m.effort = [0.01, -0.02], [0.5, -0.5], [1.5e5, -3.0e5]
    bag = tmp_path / 'raw'
    with BagRecorder(bag) as rec:
        rec.add_topic('couplers', JS)
        rec.write('couplers', 7_000_000_025, serialize_message(m))
    [(topic, t_ns, msg)] = list(read_topics(bag))
    assert (topic, t_ns) == ('couplers', 7_000_000_025)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (7, 25)
    assert list(msg.name) == m.name
    np.testing.assert_array_equal(msg.position, m.position)
    np.testing.assert_array_equal(msg.velocity, m.velocity)
    np.testing.assert_array_equal(msg.effort, m.effort)


def test_refuses_existing_path_and_bad_use(tmp_path):
    (tmp_path / 'x').mkdir()
    with pytest.raises(FileExistsError):
        BagRecorder(tmp_path / 'x')
    rec = BagRecorder(tmp_path / 'y')
    rec.add_topic('couplers', JS)
    with pytest.raises(ValueError):
        rec.add_topic('couplers', FP)                       # another type on the same topic
    with pytest.raises(KeyError):
        rec.write('coaches', 0, b'\x00\x01\x00\x00')         # not added
    with pytest.raises(KeyError):
        rec.add_topic('z', 'no_pkg/msg/Nothing')
    rec.close()
    rec.close()                                             # idempotent
    with pytest.raises(BagError):
        rec.write_msg('couplers', 0, _couplers(0, 0))
    assert bag_info(tmp_path / 'y').topics == {'couplers': (JS, 0)}   # empty, topics recorded


def test_custom_data_one_by_one_or_at_once(tmp_path):
    rec = BagRecorder(tmp_path / 'c', atomic=True)
    rec.set_custom_data('model_type', 'tanh')
    rec.update_custom_data({'integration_step': '0.001', 'model_type': 'sign', 'z': ''})
    with pytest.raises(TypeError):
        rec.update_custom_data({'publish_rate': 100.0})      # values are strings
    with pytest.raises(TypeError):
        rec.set_custom_data('publish_rate', 100.0)
    rec.close()
    assert bag_info(tmp_path / 'c').custom_data == {
        'model_type': 'sign', 'integration_step': '0.001', 'z': ''}


def test_reads_sqlite3_and_bare_mcap(tmp_path):
    db = tmp_path / 'db'
    with Writer(db, version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection('/coach_1/brake_cylinder/pressure', FP,
                                typestore=messages.typestore())
        for k in range(3):
            w.write(conn, 10 ** 9 + k, messages.serialize(messages.fluid_pressure(k, 1e5 * k)))
    got = list(read_topics(db, ['coach_1/brake_cylinder/pressure']))
    assert [(t, n, m.fluid_pressure) for t, n, m in got] == [
        ('coach_1/brake_cylinder/pressure', 10 ** 9 + k, 1e5 * k) for k in range(3)]
    with BagRecorder(tmp_path / 'm', file_stem='m') as rec:
        rec.write_msg('couplers', 5, _couplers(0, 1))
    mcap = tmp_path / 'm' / 'm_0.mcap'
    assert mcap.is_file()
    assert [t for t, _, _ in read_topics(mcap)] == ['couplers']


@pytest.mark.parametrize('damage', ['missing', 'garbage_metadata', 'truncated_mcap', 'no_bag'])
def test_unreadable_bags_raise_one_line_bag_error(tmp_path, damage):
    bag = tmp_path / 'b'
    if damage != 'missing':
        with BagRecorder(bag, file_stem='b') as rec:
            for k in range(20):
                rec.write_msg('couplers', k, _couplers(0, k))
    if damage == 'garbage_metadata':
        (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [1, 2\n')
    elif damage == 'truncated_mcap':
        data = (bag / 'b_0.mcap').read_bytes()
        (bag / 'b_0.mcap').write_bytes(data[: len(data) // 2])
    elif damage == 'no_bag':
        bag = tmp_path / 'plain'
        bag.mkdir()
        (bag / 'notes.txt').write_text('hello')
    with pytest.raises(BagError) as err:
        list(read_topics(bag))
    assert '\n' not in str(err.value) and str(err.value)
    with pytest.raises(BagError):
        bag_info(bag)


def test_split_files_readable_while_recording(tmp_path):
    bag = tmp_path / 's'
    rec = BagRecorder(bag, split_seconds=1.0)
    for k in range(35):                                     # 0 .. 3.4 s at 10 Hz
        rec.write_msg('couplers', k * 100_000_000, _couplers(k * 0.1, k))
    # still open: the three finished files (0-0.9 s, 1-1.9 s, 2-2.9 s) are readable now
    assert [n for _, n, _ in read_topics(bag)] == [k * 100_000_000 for k in range(30)]
    rec.close()
    assert sorted(p.name for p in bag.iterdir()) == ['metadata.yaml'] + [
        f's_{i}.mcap' for i in range(4)]
    assert [n for _, n, _ in read_topics(bag)] == [k * 100_000_000 for k in range(35)]
    assert bag_info(bag).topics == {'couplers': (JS, 35)}


def test_sigkill_loses_at_most_the_current_file(tmp_path):
    script = textwrap.dedent("""
        import sys, time
        from train_dynamics.recording.bags import BagRecorder
        from train_dynamics.recording.messages import joint_state
        rec = BagRecorder(sys.argv[1], split_seconds=0.5)
        k = 0
        while True:
            rec.write_msg('couplers', k * 10_000_000, joint_state(
                k * 0.01, ['coupler_1'], [0.0], [0.0], [float(k)]))
            k += 1
            if k == 200:
                print('ready', flush=True)
            time.sleep(0.0005)
    """)
    bag = tmp_path / 'killed'
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get('PYTHONPATH', '')]))
    proc = subprocess.Popen([sys.executable, '-c', script, str(bag)], stdout=subprocess.PIPE,
                            env=env, text=True)
    try:
        assert proc.stdout.readline().strip() == 'ready'
        time.sleep(0.3)
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    msgs = list(read_topics(bag))
    assert len(msgs) >= 150                                 # files of 0.5 s = 50 messages each
    assert len(msgs) % 50 == 0
    efforts = [m.effort[0] for _, _, m in msgs]
    assert efforts == [float(k) for k in range(len(msgs))]  # complete, in order, no gaps


def test_atomic_and_abort_leave_nothing(tmp_path):
    bag = tmp_path / 'out'
    rec = BagRecorder(bag, atomic=True)
    rec.write_msg('couplers', 0, _couplers(0, 0))
    assert not bag.exists()
    rec.abort()
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(RuntimeError):
        with BagRecorder(bag, atomic=True) as rec:
            rec.write_msg('couplers', 0, _couplers(0, 0))
            raise RuntimeError('boom')
    assert list(tmp_path.iterdir()) == []
    with BagRecorder(bag, atomic=True) as rec:
        rec.write_msg('couplers', 0, _couplers(0, 0))
    assert [p.name for p in tmp_path.iterdir()] == ['out']


def test_same_messages_give_identical_bytes(tmp_path):
    for name in ('a', 'b'):
        with BagRecorder(tmp_path / name, file_stem='out') as rec:
            for k in range(500):
                rec.write_msg('couplers', k * 10_000_000, _couplers(k * 0.01, k))
                rec.write_msg('brake_pipe/pressure', k * 10_000_000,
                              messages.fluid_pressure(k * 0.01, 101325.0))
    for f in ('out_0.mcap', 'metadata.yaml'):
        assert (tmp_path / 'a' / f).read_bytes() == (tmp_path / 'b' / f).read_bytes()


def test_stamp_helpers():
    s = messages.stamp(1.5)
    assert (s.sec, s.nanosec) == (1, 500_000_000)
    s = messages.stamp(2.999999999)
    assert (s.sec, s.nanosec) == (2, 999_999_999)
    assert messages.stamp_to_sec(messages.stamp(12.25)) == 12.25
    assert messages.time_to_ns(0.1) == 100_000_000
    with pytest.raises(ValueError):
        messages.time_to_ns(float('nan'))
    c = messages.clock(3.0)
    assert (c.clock.sec, c.clock.nanosec) == (3, 0)
    status = messages.diagnostic_status('train_dynamics: rtf', 1, 'slow', values={'rtf': 0.5})
    d = messages.diagnostic_array(1.0, [status])
    raw = messages.serialize(d)
    back = messages.deserialize(raw, 'diagnostic_msgs/msg/DiagnosticArray')
    assert back.status[0].level == 1 and back.status[0].values[0].value == '0.5'


def test_direct_cdr_encoders_match_rosbags():
    rng = np.random.default_rng(7)
    types = messages.typestore().types
    for _ in range(200):
        n = int(rng.integers(0, 6))
        names = ['c' * int(rng.integers(0, 9)) + str(i) for i in range(n)]
        t_ns = int(rng.integers(0, 10 ** 12))
        arrays = [None if rng.random() < 0.3 else rng.normal(size=int(rng.integers(0, 5)))
                  for _ in range(3)]
        frame = 'f' * int(rng.integers(0, 7))
        hdr = types['std_msgs/msg/Header'](stamp=messages.stamp(t_ns, ns=True), frame_id=frame)
        ref = types['sensor_msgs/msg/JointState'](
            header=hdr, name=names, **{k: np.zeros(0) if a is None else a for k, a in
                                       zip(('position', 'velocity', 'effort'), arrays)})
        assert cdr.encode_joint_state(t_ns, names, *arrays, frame_id=frame) == \
            messages.serialize(ref)
        assert cdr.JointStateEncoder(names, frame)(t_ns, *arrays) == messages.serialize(ref)
        p = float(rng.normal() * 1e5)
        fp = types['sensor_msgs/msg/FluidPressure'](header=hdr, fluid_pressure=p, variance=0.25)
        assert cdr.encode_fluid_pressure(t_ns, p, 0.25, frame_id=frame) == messages.serialize(fp)


def test_encoder_bytes_read_by_rclpy_typesupport():
    """
    Check that rclpy's (Fast-CDR) typesupport reads JointStateEncoder bytes back exactly.

    sim_node publishes these bytes straight to DDS; empty sequences included (brake_cylinders
    has no velocity; Fast-CDR pads empty float64 sequences differently from rosbags).
    """
    rng = np.random.default_rng(11)
    for n in (0, 1, 2, 3, 7, 300):
        names = [f'coach_{i}' for i in range(1, n + 1)]
        enc = cdr.JointStateEncoder(names)
        for empty in (None, 0, 1, 2):
            arrays = [rng.normal(size=n) * 1e5 for _ in range(3)]
            if empty is not None:
                arrays[empty] = None
            t_ns = int(rng.integers(0, 10 ** 12))
            msg = deserialize_message(enc(t_ns, *arrays), JointState)
            assert list(msg.name) == names
            assert msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec == t_ns
            for got, want in zip((msg.position, msg.velocity, msg.effort), arrays):
                np.testing.assert_array_equal(np.asarray(got), np.zeros(0) if want is None
                                              else want)
