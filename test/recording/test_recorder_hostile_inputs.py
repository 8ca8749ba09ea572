"""
The recorder under hostile conditions: what it refuses, and what it reports.

A list a reviewer can read (``record_bag`` of ``sim_node``: :class:`BagWriter` on a
:class:`BagRecorder`; the offline command writes through the same recorder):

- a flush (finishing an MCAP file) that takes longer than ``record_flush_period`` is followed
  by a period of writing, never by another flush at every message (was: one file per message,
  most messages lost);
- ``sim_node -p record_flush_period:=0.1`` (its least) as fast as possible records every output;
- closing waits until every message given is written; a writer that makes no progress for
  the stall bound is given up, and then the bag is reported incomplete (what it holds of what
  was recorded), never "closed" (was: gave up after 30 s and reported success);
- a bag that holds fewer messages than it was given is a failure, not "bag closed";
- a full disk leaves a readable bag of the finished files and no ``.staging`` folder, on
  every path (failed write, failed close, abort);
- a ``metadata.yaml`` that cannot be written never counts the file it would have listed;
- the node's and the offline command's failure lines say the same thing (one wording);
- a file finished the fast way (libyaml) carries the metadata rosbags' own writer writes.
"""
from __future__ import annotations

import errno
import logging
import os
from pathlib import Path
import subprocess
import sys
import threading
import time

import pytest
from ruamel.yaml import YAML

from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics, recording_failed
from train_dynamics.recording.messages import typestore
from train_dynamics.ros import recorder as recorder_mod
from train_dynamics.ros.recorder import BagWriter

ROOT = Path(__file__).resolve().parents[2]
FLOAT64 = 'std_msgs/msg/Float64'
LOG = logging.getLogger('test_recorder')


def cdr(value: float = 1.0) -> bytes:
    types = typestore()
    return bytes(types.serialize_cdr(types.types[FLOAT64](data=value), FLOAT64))


def on_disk(bag: Path) -> int:
    return sum(1 for _ in read_topics(bag))


class FakeClock:
    """A monotonic clock that moves only when told (the writer's flush timer reads it)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_a_slow_flush_is_followed_by_writing_not_by_a_flush_per_message(tmp_path, monkeypatch):
    clock = FakeClock()
    monkeypatch.setattr(recorder_mod.time, 'monotonic', clock)

    class SlowFlush(BagRecorder):

        def flush(self) -> None:
            super().flush()
            clock.now += 1.0              # a flush of 1 s, ten times the period

    rec = SlowFlush(tmp_path / 'bag')
    writer = BagWriter(rec, LOG, flush_period=0.1)
    data = cdr()
    clock.now += 0.2                      # the first message is due a flush
    for k in range(300):
        writer.write('x', FLOAT64, k * 10_000_000, data)
    writer.close()
    assert writer.error is None, writer.error
    # one flush after the first message, the rest at close (was: one file per message)
    assert rec.finished_files == 2
    assert writer.saved == writer.given == on_disk(tmp_path / 'bag') == 300
    assert writer.closed_message() == f'bag closed: {tmp_path / "bag"} (300 messages)'


def test_sim_node_with_a_short_flush_period_records_every_output(tmp_path):
    bag = tmp_path / 'bag'
    proc = subprocess.run(
        [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args',
         '-p', f'record_bag:={bag}', '-p', 'real_time_factor:=0.0', '-p', 'duration:=20.0',
         '-p', 'record_flush_period:=0.1'], cwd=tmp_path, capture_output=True, text=True,
        timeout=600, env={**os.environ, 'PYTHONPATH': str(ROOT)})
    assert proc.returncode == 0, proc.stderr
    info = bag_info(bag)
    # outputs at 100 Hz from t = 0 to 20 s: 2001 of each (was: a few hundred in all)
    for topic in ('couplers', 'coaches', 'brake_cylinders', 'vehicle_motion'):
        assert info.topics[topic][1] == 2001, (topic, info.topics)
    closed = [ln for ln in proc.stderr.splitlines() if 'bag closed' in ln]
    assert len(closed) == 1 and f'({info.message_count} messages)' in closed[0], proc.stderr


def test_close_gives_up_on_a_stalled_writer_and_reports_what_the_bag_holds(tmp_path):
    release = threading.Event()

    class Stalls(BagRecorder):

        def write(self, topic, t_ns, data) -> None:
            if self.given >= 50:
                release.wait(60)          # a disk that stops answering
            super().write(topic, t_ns, data)

    rec = Stalls(tmp_path / 'bag')
    writer = BagWriter(rec, LOG, flush_period=1e9)
    for k in range(200):
        writer.write('x', FLOAT64, k * 10_000_000, cdr())
    try:
        writer.close(stall_timeout=0.5)
    finally:
        release.set()
    assert writer.error is not None and 'no progress for 0.5 s' in writer.error
    line = writer.closed_message()
    # was: "bag closed" after the 30 s join timed out, the thread still writing
    assert 'failed' in line and 'bag closed' not in line
    assert f'the bag holds {writer.saved} of the 200 messages recorded' in line, line


def test_a_bag_holding_fewer_messages_than_given_is_a_failure(tmp_path):
    class Drops(BagRecorder):

        def write(self, topic, t_ns, data) -> None:
            if t_ns % 3:                  # loses two messages in three, silently
                return
            super().write(topic, t_ns, data)

    writer = BagWriter(Drops(tmp_path / 'bag'), LOG, flush_period=1e9)
    for k in range(30):
        writer.write('x', FLOAT64, k, cdr())
    writer.close()
    assert writer.error is not None and '20 message(s) not written' in writer.error
    assert 'the bag holds 10 of the 30 messages recorded' in writer.closed_message()


def test_messages_given_after_close_are_counted_not_silently_queued(tmp_path):
    writer = BagWriter(BagRecorder(tmp_path / 'bag'), LOG, flush_period=1e9)
    writer.write('x', FLOAT64, 0, cdr())
    writer.close()
    writer.write('x', FLOAT64, 1, cdr())
    assert writer.error is None and writer.late == 1
    assert writer.closed_message().endswith(
        '(1 messages); 1 message(s) given after closing were not recorded')


class _DiskFullAfter(BagRecorder):
    """A disk that fills up at the ``full_at``-th message and stays full."""

    full_at = 120

    def write(self, topic, t_ns, data) -> None:
        super().write(topic, t_ns, data)             # the message goes into the open file
        if self.given >= self.full_at:
            raise OSError(errno.ENOSPC, 'No space left on device')

    def _finish_segment(self) -> None:
        if self.given >= self.full_at:
            raise OSError(errno.ENOSPC, 'No space left on device')
        super()._finish_segment()


def test_full_disk_in_the_node_recorder_leaves_a_readable_bag_and_no_staging(tmp_path):
    bag = tmp_path / 'bag'
    rec = _DiskFullAfter(bag)
    writer = BagWriter(rec, LOG, flush_period=1e9, sim_time_split=False)
    for k in range(100):
        writer.write('x', FLOAT64, k * 10_000_000, cdr())
    end = time.monotonic() + 120
    while writer.written < 100 and time.monotonic() < end:     # the writer thread took them
        time.sleep(0.01)
    rec.flush()                                      # 100 messages in a finished file
    for k in range(100, 300):
        writer.write('x', FLOAT64, k * 10_000_000, cdr())
    writer.close()
    assert 'No space left on device' in (writer.error or '')
    assert not (bag / '.staging').exists()           # was left behind
    assert sorted(p.name for p in bag.iterdir()) == ['bag_0.mcap', 'metadata.yaml']
    info = bag_info(bag)
    assert info.message_count == on_disk(bag) == writer.saved == 100
    assert 'No space left' in info.custom_data['incomplete']
    assert writer.closed_message() == recording_failed(
        bag, writer.error, 100, 300, 990_000_000)
    assert 'the bag holds 100 of the 300 messages recorded, up to t = 0.990 s' in \
        writer.closed_message()


def test_abort_of_a_bag_keeps_its_finished_files_and_removes_the_unfinished_one(tmp_path):
    bag = tmp_path / 'bag'
    rec = BagRecorder(bag)
    rec.add_topic('x', FLOAT64)
    rec.write('x', 0, cdr())
    rec.flush()
    rec.write('x', 10, cdr())                        # in the unfinished file (.staging)
    assert (bag / '.staging').exists()
    rec.abort()
    assert sorted(p.name for p in bag.iterdir()) == ['bag_0.mcap', 'metadata.yaml']
    assert on_disk(bag) == bag_info(bag).message_count == 1


def test_a_metadata_write_that_fails_does_not_count_the_file_it_would_list(
        tmp_path, monkeypatch):
    bag = tmp_path / 'bag'
    rec = BagRecorder(bag)
    rec.add_topic('x', FLOAT64)
    rec.write('x', 0, cdr())
    rec.flush()
    rec.write('x', 10, cdr())

    def full(self):
        raise OSError(errno.ENOSPC, 'No space left on device')

    monkeypatch.setattr(type(rec._meta), 'write', full)
    with pytest.raises(OSError):
        rec.flush()
    assert rec.saved == 1 and rec.finished_files == 1
    assert not (bag / 'bag_1.mcap').exists() and not (bag / 'metadata.yaml.tmp').exists()
    monkeypatch.undo()
    rec.abort()
    assert on_disk(bag) == bag_info(bag).message_count == 1


def test_metadata_lists_every_file_as_rosbag2_reads_it(tmp_path):
    bag = tmp_path / 'bag'
    rec = BagRecorder(bag)
    rec.add_topic('a', FLOAT64)
    rec.add_topic('b: odd name', FLOAT64)
    rec.set_custom_data('note', 'a value: with "quotes"\nand a second line')
    for k in range(5):
        rec.write('a', k * 10, cdr())
        rec.write('b: odd name', k * 10 + 1, cdr())
        rec.flush()
    rec.close()
    text = (bag / 'metadata.yaml').read_text()
    info = YAML(typ='safe').load(text)['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['relative_file_paths'] == [f'bag_{k}.mcap' for k in range(5)]
    assert [f['message_count'] for f in info['files']] == [2] * 5
    assert info['message_count'] == 10
    assert info['starting_time']['nanoseconds_since_epoch'] == 0
    assert info['duration']['nanoseconds'] == 41
    counts = {e['topic_metadata']['name']: e['message_count']
              for e in info['topics_with_message_count']}
    assert counts == {'a': 5, 'b: odd name': 5}
    assert info['custom_data'] == {'note': 'a value: with "quotes"\nand a second line'}
    assert bag_info(bag).message_count == on_disk(bag) == 10


def test_a_file_closed_fast_carries_the_metadata_rosbags_writes(tmp_path):
    from rosbags.highlevel import AnyReader
    from rosbags.rosbag2 import StoragePlugin, Writer

    from train_dynamics.recording.bag_metadata import offered_qos
    from train_dynamics.recording.mcap_rows import BlockWriter

    meta = {}
    for cls in (Writer, BlockWriter):
        path = tmp_path / cls.__name__
        writer = cls(path, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        conns = [writer.add_connection(topic, FLOAT64, typestore=typestore(),
                                       offered_qos_profiles=qos)
                 for topic, qos in (('a', [offered_qos(True, 10)]), ('/ns/long_topic', []))]
        for k in range(5):
            writer.write(conns[k % 2], 1_000_000_000 + k, cdr(k))
        writer.close()
        meta[cls] = YAML(typ='safe').load((path / 'metadata.yaml').read_text())
        with AnyReader([path]) as reader:            # the MCAP file's own metadata record
            assert [(c.topic, t) for c, t, _ in reader.messages()] == [
                ('a', 1_000_000_000), ('/ns/long_topic', 1_000_000_001),
                ('a', 1_000_000_002), ('/ns/long_topic', 1_000_000_003),
                ('a', 1_000_000_004)]
        mcap = (path / f'{cls.__name__}.mcap').read_bytes()
        at = mcap.index(b'serialized_metadata') + len('serialized_metadata') + 4
        end = mcap.index(b'version: 9', at) + len('version: 9')    # the keys are sorted
        meta[cls, 'record'] = YAML(typ='safe').load(mcap[at:end].decode())
        assert set(meta[cls, 'record']) == set(meta[cls]['rosbag2_bagfile_information'])
    for key in (Writer, (Writer, 'record')):
        fast = BlockWriter if key is Writer else (BlockWriter, 'record')
        expect = meta[key]
        info = expect.get('rosbag2_bagfile_information', expect)
        info['relative_file_paths'] = ['BlockWriter.mcap']
        info['files'][0]['path'] = 'BlockWriter.mcap'
        assert meta[fast] == expect
