"""
The offline bag written in blocks of samples: the same messages as one message at a time.

``BagSink`` stages the outputs of each sample in place into a ``RecordBlock``
(``OutputRows``) and ``BagRecorder`` writes whole blocks. What a reader gets must be what
the per-message path (``OutputEncoder`` + ``BagRecorder.write``, the node's bytes) gives:
every message's topic, bag time and CDR bytes, in the same order per topic, the same files
when the bag is split, the inputs interleaved where they were applied, and the rows filled
before ``close`` in the bag.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics import topics
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.observables import TrainOutputs
from train_dynamics.recording import cdr
from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.recording.outputs import OutputEncoder, OutputRows

FP = 'sensor_msgs/msg/FluidPressure'


class _State:
    """A train state with the fields the outputs read (values that change with ``k``)."""

    def __init__(self, n: int, k: int) -> None:
        rng = np.random.default_rng(k)
        for name in ('x', 'v', 'brake_force', 'cylinder_pressure', 'pipe_pressure',
                     'auxiliary_pressure', 'control_pressure', 'traction_force',
                     'resistance_force', 'gradient_force', 'track_position',
                     'adhesion_available', 'wheel_speed', 'creep_force'):
            setattr(self, name, rng.normal(size=n) * 1e3)
        self.y = self.x[:-1] - self.x[1:]
        self.ydot = self.v[:-1] - self.v[1:]
        self.coupler_force = rng.normal(size=n - 1) * 1e5
        self.cfg = SimConfig()          # the outputs' options (the exact wheel speed)

    def __getattr__(self, name):
        """Return a quantity derived from the ones above, by the simulator's own property."""
        prop = getattr(TrainOutputs, name, None)
        if not isinstance(prop, property):
            raise AttributeError(name)
        return prop.fget(self)


def _raw(bag):
    """Return {topic: [(t_ns, cdr bytes), ...]} of every message of ``bag``."""
    from rosbags.highlevel import AnyReader
    out: dict[str, list] = {}
    with AnyReader([bag]) as reader:
        for conn, t, raw in reader.messages():
            out.setdefault(conn.topic, []).append((t, bytes(raw)))
    return out


@pytest.mark.parametrize('n', [1, 3, 7])
def test_layouts_give_the_encoders_bytes(n):
    names = topics.coach_names(n)
    rng = np.random.default_rng(1)
    for lengths in ((n, n, n), (n, 0, n), (0, 0, 0)):
        lay = cdr.joint_state_layout(names, lengths, 'track')
        arrays = [rng.normal(size=m) if m else None for m in lengths]
        data = bytearray(lay.template)
        t_ns = 12_345_678_901
        data[cdr.STAMP_OFFSET:cdr.STAMP_OFFSET + 8] = np.array(
            divmod(t_ns, 10 ** 9), '<u4').tobytes()
        for at, a in zip(lay.fields, arrays):
            if a is not None:
                data[at:at + 8 * len(a)] = a.astype('<f8').tobytes()
        assert bytes(data) == cdr.encode_joint_state(t_ns, names, *arrays, frame_id='track')
    lay = cdr.fluid_pressure_layout()
    data = bytearray(lay.template)
    data[cdr.STAMP_OFFSET:cdr.STAMP_OFFSET + 8] = np.array([3, 5], '<u4').tobytes()
    data[lay.fields[0]:lay.fields[0] + 8] = np.float64(601325.5).tobytes()
    assert bytes(data) == cdr.encode_fluid_pressure(3_000_000_005, 601325.5)


def _config(n, reservoirs=False, forces=False, wheelsets=False):
    """Return a configuration whose outputs include the optional topics asked for."""
    opts = {'num_coaches': n}
    if reservoirs:
        opts['brake_model'] = 'pneumatic'
    if forces:
        opts['davis_a'] = 1000.0
    if wheelsets:
        opts['wheelsets'] = True
    return SimConfig.from_dict(opts)


def _write_both(tmp_path, n, samples, split=None, reservoirs=True, forces=True, inputs=(),
                wheelsets=False):
    """Write ``samples`` per message and in blocks (small blocks: several per file)."""
    bags = []
    cfg = _config(n, reservoirs, forces, wheelsets)
    for blocks in (False, True):
        bag = tmp_path / ('blocks' if blocks else 'messages')
        rec = BagRecorder(bag, split_seconds=split, atomic=True, file_stem='bag')
        enc = OutputEncoder(cfg)
        for t, msgtype in zip(enc.topics, enc.msgtypes):
            rec.add_topic(t, msgtype)
        rec.add_topic(topics.HEAD_PIPE_TOPIC, FP)
        rec.add_topic('coach_1/brake_cylinder/pressure', FP)
        rows = OutputRows(enc, True, capacity=7)    # many blocks per file
        for k in range(samples):
            t_ns = k * 10_000_000
            sim = _State(n, k)
            head = 101325.0 + 1e3 * k
            if k in inputs:                     # an input between two samples
                t_in = max(t_ns - 1000, 0)
                rec.write('coach_1/brake_cylinder/pressure', t_in,
                          cdr.encode_fluid_pressure(t_in, 2e5 + k))
            if blocks:
                rows.write(rec, t_ns, sim, head)
            else:
                for t, data in zip(enc.topics, enc.encode(t_ns, sim)):
                    rec.write(t, t_ns, data)
                rec.write(topics.HEAD_PIPE_TOPIC, t_ns, cdr.encode_fluid_pressure(t_ns, head))
        rec.close()
        bags.append(bag)
    return bags


def test_blocks_write_the_messages_of_the_per_message_path(tmp_path):
    one, blocks = _write_both(tmp_path, 5, 100, inputs=(0, 13, 14, 50))
    a, b = _raw(one), _raw(blocks)
    assert a == b
    assert len(b['couplers']) == 100 and len(b['coach_1/brake_cylinder/pressure']) == 4
    ia, ib = bag_info(one), bag_info(blocks)
    assert (ia.topics, ia.start_ns, ia.end_ns, ia.message_count) == (
        ib.topics, ib.start_ns, ib.end_ns, ib.message_count)
    outputs = len(OutputEncoder(_config(5, True, True)).topics)
    assert ib.message_count == (outputs + 1) * 100 + 4         # + the head pipe
    # the inputs come between the samples they were written between (bag-time order)
    got = [(topic, t) for topic, t, _ in read_topics(blocks)]
    at = got.index(('coach_1/brake_cylinder/pressure', 13 * 10_000_000 - 1000))
    assert got[at - 1][1] == 12 * 10_000_000 and got[at + 1][1] == 13 * 10_000_000


def test_blocks_write_the_wheelsets_of_the_per_message_path(tmp_path):
    """``wheelsets`` (after ``vehicle_forces``) in blocks: the node's bytes, frame ``track``."""
    for forces in (True, False):
        one, blocks = _write_both(tmp_path / str(forces), 4, 30, forces=forces, wheelsets=True)
        a, b = _raw(one), _raw(blocks)
        assert a == b and len(b[topics.WHEELSETS_TOPIC]) == 30
    msgs = [m for _, _, m in read_topics(blocks, [topics.WHEELSETS_TOPIC])]
    sim = _State(4, 29)
    assert msgs[-1].header.frame_id == topics.TRACK_FRAME
    assert list(msgs[-1].velocity) == list(sim.wheel_speed)
    assert list(msgs[-1].effort) == list(sim.creep_force)


def test_blocks_split_files_at_the_same_samples(tmp_path):
    one, blocks = _write_both(tmp_path, 4, 120, split=0.25, reservoirs=False, forces=False,
                              inputs=(40,))
    files = [sorted(p.name for p in bag.glob('*.mcap')) for bag in (one, blocks)]
    assert files[0] == files[1] and len(files[0]) == 5       # 1.2 s in 0.25 s files
    for name in files[0]:                                    # file by file: the same messages
        assert _raw(one / name) == _raw(blocks / name)


def test_rows_filled_before_close_are_in_the_bag_and_keep_drops_the_open_file(tmp_path):
    enc = OutputEncoder(_config(3))
    per_sample = len(enc.topics)
    for how in ('close', 'keep'):
        bag = tmp_path / how
        rec = BagRecorder(bag, split_seconds=0.1)
        for t, msgtype in zip(enc.topics, enc.msgtypes):
            rec.add_topic(t, msgtype)
        rows = OutputRows(enc, False)
        for k in range(25):                                  # 0.00 .. 0.24 s
            rows.write(rec, k * 10_000_000, _State(3, k))
        assert rows.block.count > 0                          # rows not yet written
        if how == 'close':
            rec.close()
            assert bag_info(bag).message_count == 25 * per_sample
        else:
            rec.keep('disk full')                            # the file 0.20 - 0.24 s is dropped
            info = bag_info(bag)
            assert info.message_count == 20 * per_sample and info.end_ns == 19 * 10_000_000


def test_blocks_keep_the_chunks_of_about_1_mib(tmp_path):
    """A reader holds one chunk's messages at a time: blocks must not make chunks larger."""
    from rosbags.rosbag2.storage_mcap import McapReader
    chunks = []
    for bag in _write_both(tmp_path, 40, 600, reservoirs=False, forces=False):
        reader = McapReader(next(bag.glob('*.mcap')))
        reader.open()
        chunks.append([c.uncompressed_size for c in reader.chunks])
        reader.close()
    # rosbags closes a chunk after the message that takes it past 1 MiB, the blocks after the
    # sample that does (a sample of 40 coaches: 5 messages, about 5 kB)
    assert len(chunks[0]) == len(chunks[1]) >= 3, chunks
    assert max(chunks[0] + chunks[1]) <= 2 ** 20 + 8192, chunks
