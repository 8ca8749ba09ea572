"""
``record_bag`` on a full disk: the node reports what the bag holds and exits non-zero.

A write that fails (ENOSPC, simulated by making the bag recorder's file finishing fail
after a few files) stops the recording; the bag keeps its finished files; the node's
"bag closed" count is what is on disk, never more, and ``sim_node`` exits with status 1.
"""
from __future__ import annotations

import errno
import logging
import os
from pathlib import Path
import subprocess
import sys

from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.ros.recorder import BagWriter

ROOT = Path(__file__).resolve().parents[2]

#: ``sim_node`` whose bag recorder finishes two MCAP files, then hits a full disk
FULL_DISK_NODE = r"""
import errno, sys
from train_dynamics.recording import bags
finish = bags.BagRecorder._finish_segment
def full_after_two(self):
    if self.finished_files >= 2:
        raise OSError(errno.ENOSPC, 'No space left on device')
    finish(self)
bags.BagRecorder._finish_segment = full_after_two
from train_dynamics.ros.sim_node import main
sys.exit(main())
"""


class _FullAfter(BagRecorder):
    """A bag recorder whose disk is full once ``files`` MCAP files are finished."""

    files = 2

    def _finish_segment(self) -> None:
        if self.finished_files >= self.files:
            raise OSError(errno.ENOSPC, 'No space left on device')
        super()._finish_segment()


def messages_on_disk(bag: Path) -> int:
    return sum(1 for _ in read_topics(bag))


def test_bag_writer_counts_what_the_bag_holds_after_a_full_disk(tmp_path):
    bag = tmp_path / 'bag'
    rec = _FullAfter(bag)
    rec.add_topic('x', 'std_msgs/msg/Float64')
    writer = BagWriter(rec, logging.getLogger('test'), flush_period=0.0)
    data = bytes(rec_cdr())
    for k in range(3000):
        writer.write('x', 'std_msgs/msg/Float64', k * 10_000_000, data)
    writer.close()
    assert writer.error is not None and 'No space left' in writer.error
    held = messages_on_disk(bag)
    assert 0 < held < writer.written <= writer.given == 3000
    assert writer.saved == held == bag_info(bag).message_count
    line = writer.closed_message()
    assert f'the bag holds {held} of the {writer.given} messages' in line, line   # all given
    assert 'failed' in line


def rec_cdr() -> bytes:
    from train_dynamics.recording.messages import typestore
    types = typestore()
    msg = types.types['std_msgs/msg/Float64'](data=1.0)
    return types.serialize_cdr(msg, 'std_msgs/msg/Float64')


def test_sim_node_full_disk_reports_what_was_written_and_exits_nonzero(tmp_path):
    bag = tmp_path / 'bag'
    proc = subprocess.run(
        [sys.executable, '-c', FULL_DISK_NODE, '--ros-args', '-p', f'record_bag:={bag}',
         '-p', 'real_time_factor:=2.0', '-p', 'duration:=3.0', '-p',
         'record_flush_period:=0.1'], cwd=tmp_path, capture_output=True, text=True,
        timeout=300, env={**os.environ, 'PYTHONPATH': str(ROOT)})     # this checkout's code
    err = proc.stderr
    assert proc.returncode == 1, err                      # was 0
    held = messages_on_disk(bag)
    assert held > 0
    closed = [ln for ln in err.splitlines() if f'recording to {bag}' in ln and 'holds' in ln]
    assert len(closed) == 1, err
    assert f'the bag holds {held} of the ' in closed[0], closed   # was: "bag closed (N)", N > held
    assert not any('bag closed' in ln for ln in err.splitlines()), err
