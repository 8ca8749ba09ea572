"""
What the harness does after the loop, and what it leaves out: its cost beyond the loop.

- The figure-less report of a run (the harness's) opens the bag once and reads only the
  topics the metrics need (``couplers``, ``coaches``; the stop-error and blending topics when
  the bag has them), not the figures' curves (``brake_cylinders``, ``vehicle_forces``, the
  head pipe); its numbers are those of ``train-dynamics report``.
- It never imports the plotting library (0.3-0.7 s of CPU, during the loop or after it).
- The block-wise copy of JointState messages into the curves (one array per field for a run
  of messages with the same joints) gives what the message-by-message copy gave: values of a
  field that does not hold one per joint are left out (NaN), columns follow the names.
"""
from __future__ import annotations

import importlib
import json
from pathlib import Path
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from train_dynamics.cli import offline
from train_dynamics.recording import bag_read
from train_dynamics.recording.history import TopicStream
from train_dynamics.testing.summary import run_metrics

ROOT = Path(__file__).resolve().parents[2]
PAPER = ROOT / 'config' / 'paper_3coach.yaml'


@pytest.fixture(scope='module')
def bag(tmp_path_factory) -> Path:
    """3 s of the paper's train (emergency at t = 1 s), written by the offline command."""
    out = tmp_path_factory.mktemp('cost') / 'bag'
    assert offline.main(['simulate', '--params', str(PAPER), '--duration', '3', '--output',
                         str(out), '-q']) == 0
    return out


def test_figure_less_report_opens_the_bag_once_and_reads_what_the_metrics_need(
        bag, tmp_path, monkeypatch):
    opened, decoded = [], set()
    open_reader, read_topics = bag_read._open_reader, bag_read.read_topics

    def counting_open(path):
        opened.append(path)
        return open_reader(path)

    def recording_read(path, topics=None):
        for topic, t_ns, msg in read_topics(path, topics):
            decoded.add(topic)
            yield topic, t_ns, msg
    monkeypatch.setattr(bag_read, '_open_reader', counting_open)
    for module in ('train_dynamics.recording.history',
                   'train_dynamics.recording.metrics_report',
                   'train_dynamics.recording.blending_metrics'):
        monkeypatch.setattr(importlib.import_module(module), 'read_topics', recording_read)
    metrics = run_metrics(bag, tmp_path / 'report')
    assert len(opened) == 1
    assert decoded == {'couplers', 'coaches'}
    assert 'brake_cylinders' in bag_read.bag_info(bag).topics      # there, not read
    # the numbers of train-dynamics report (which reads every topic, for its figures)
    monkeypatch.undo()
    assert offline.main(['report', str(bag), '--output', str(tmp_path / 'full'), '-q']) == 0
    full = json.loads((tmp_path / 'full' / 'summary.json').read_text())
    plain = json.loads((tmp_path / 'report' / 'summary.json').read_text())
    for key in ('train', 'couplers', 'vehicles', 'settings'):
        assert plain[key] == full[key], key
    assert metrics['max_tension'] == full['train']['max_tension'] > 0.0


def test_figure_less_report_never_imports_the_plotting_library(bag, tmp_path):
    code = ('import sys\n'
            'from pathlib import Path\n'
            'from train_dynamics.physics.config import SimConfig\n'
            'from train_dynamics.testing.summary import preload, run_metrics\n'
            'preload(SimConfig.from_dict({}))\n'
            f'run_metrics(Path({str(bag)!r}), Path({str(tmp_path / "r")!r}))\n'
            'print("matplotlib" in sys.modules)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=tmp_path)
    assert out.stdout.strip() == 'False'
    assert (tmp_path / 'r' / 'summary.json').is_file()


def _joint_msg(t: float, names, position, velocity, effort):
    stamp = SimpleNamespace(sec=int(t), nanosec=int(round((t - int(t)) * 1e9)))
    return SimpleNamespace(header=SimpleNamespace(stamp=stamp), name=list(names),
                           position=np.array(position, dtype=float),
                           velocity=np.array(velocity, dtype=float),
                           effort=np.array(effort, dtype=float))


def test_block_copy_of_joint_states_keeps_names_and_leaves_out_ragged_fields():
    blocks = []
    stream = TopicStream('other', limit=None,
                         on_block=lambda topic, t, q, names: blocks.append((t, q, names)))
    stream.add(0, _joint_msg(0.0, ['a', 'b'], [1, 2], [3, 4], [5, 6]))
    stream.add(1, _joint_msg(0.5, ['a', 'b'], [7, 8], [], [9, 10]))       # no velocity
    stream.add(2, _joint_msg(1.0, ['b', 'a'], [11, 12], [13, 14], [15]))  # order; 1 effort
    stream.add(3, _joint_msg(1.5, ['a', 'b', 'c'], [16, 17, 18], [19, 20, 21], [22, 23, 24]))
    stream.flush()
    (t, q, names), = blocks
    nan = np.nan
    assert names == ['a', 'b', 'c']
    np.testing.assert_array_equal(t, [0.0, 0.5, 1.0, 1.5])
    np.testing.assert_array_equal(q[:, 0], [[1, 2, nan], [7, 8, nan], [12, 11, nan],
                                            [16, 17, 18]])
    np.testing.assert_array_equal(q[:, 1], [[3, 4, nan], [nan, nan, nan], [14, 13, nan],
                                            [19, 20, 21]])
    np.testing.assert_array_equal(q[:, 2], [[5, 6, nan], [9, 10, nan], [nan, nan, nan],
                                            [22, 23, 24]])
