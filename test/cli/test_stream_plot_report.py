"""
``plot`` and ``report`` read a bag block-wise; memory independent of its length.

Peak memory is measured in a child process (``ru_maxrss``) for a bag and one 10x longer, with
the figures' sample limit lowered so that both bags are past it (with the default 20000 the
curves grow up to 20000 samples, 200 s of a 100 Hz bag, and then stay). The block-wise
report equals the in-memory one (whole arrays, one ``RunMetrics.add_block``), the bounded
curves equal the full ones up to the limit and keep every minimum and maximum past it.
"""
from __future__ import annotations

import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from train_dynamics.cli import offline
from train_dynamics.cli.report import report_metrics
from train_dynamics.param_files import load_param_file
from train_dynamics.recording import history as history_mod
from train_dynamics.recording import metrics_report as report_mod
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.history import Envelope, load_history, stream_history
from train_dynamics.recording.messages import joint_state

REPO = Path(__file__).resolve().parents[2]
CFG = REPO / 'config' / 'paper_3coach.yaml'

#: run ``train-dynamics`` with a lower figure limit and metrics block, print the peak RSS
PEAK = r"""
import resource, subprocess, sys
code = ('import sys; from train_dynamics.recording import history, metrics_report; '
        'history.MAX_PLOT_SAMPLES = 1000; metrics_report.FEED_ROWS = 1000; '
        'from train_dynamics.cli.offline import main; sys.exit(main(sys.argv[1:]))')
subprocess.run([sys.executable, '-c', code, *sys.argv[1:]], check=True,
               stdout=subprocess.DEVNULL)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
"""


def peak_rss_mb(*args) -> float:
    """Return the peak RSS [MB] of ``train-dynamics args`` (lowered limits), in a child."""
    out = subprocess.run([sys.executable, '-c', PEAK, *map(str, args)], capture_output=True,
                         text=True, check=True, timeout=600)
    return int(out.stdout.split()[-1]) / 1024.0


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    """Paper bags of 30 s and 300 s (3001 and 30001 samples at 100 Hz)."""
    tmp = tmp_path_factory.mktemp('bags')
    for d in (30, 300):
        assert offline.main(['simulate', '--params', str(CFG), '--duration', str(d),
                             '--output', str(tmp / f'p{d}'), '-q']) == 0
    return tmp


@pytest.mark.parametrize('command', ['plot', 'report'])
def test_plot_and_report_memory_is_independent_of_the_bag_length(bags, tmp_path, command):
    short = peak_rss_mb(command, bags / 'p30', '--output', tmp_path / 'a')
    long = peak_rss_mb(command, bags / 'p300', '--output', tmp_path / 'b')
    # loading the whole bag grew by ~0.4 MB per second of bag (27000 more messages here:
    # ~100 MB more); the bounded curves do not grow. What still grows with the bag was
    # measured at 11-17 MB from 30 s to 300 s (reading the bag alone with rosbags: flat); it is
    # not located, so the bound is 25 MB, a quarter of what loading the whole bag costs
    assert long - short < 25.0, (short, long)


def test_block_wise_report_equals_the_in_memory_one(bags, tmp_path, monkeypatch):
    """The report as written (a 300 s bag: metrics in 2 blocks, curves decimated) = in memory."""
    out = tmp_path / 'r'
    assert offline.main(['report', str(bags / 'p300'), '--params', str(CFG), '--output',
                         str(out), '-q']) == 0
    doc = json.loads((out / 'summary.json').read_text())
    hist = load_history(bags / 'p300')
    ref = report_metrics(hist, load_param_file(str(CFG))).result()
    assert_close({k: doc[k] for k in ref}, json.loads(json.dumps(ref)), rel=1e-12)
    # blocks of any size give the same numbers; 30000 samples in one block: bit for bit
    # (the summaries compared; the figures of these two reports are not drawn)
    for name in ('force_envelope', 'worst_force', 'vehicle_figure'):
        monkeypatch.setattr(report_mod, name, lambda *args: args[-1].touch() or args[-1])
    monkeypatch.setattr(report_mod, 'plot_history', lambda hist, out: [])
    for rows, feed, rel in ((7, 333, 1e-12), (4096, 40000, 0.0)):
        monkeypatch.setattr(history_mod, 'BLOCK_ROWS', rows)
        monkeypatch.setattr(report_mod, 'FEED_ROWS', feed)
        assert offline.main(['report', str(bags / 'p300'), '--params', str(CFG), '--output',
                             str(tmp_path / f'r{rows}'), '-q']) == 0
        got = json.loads((tmp_path / f'r{rows}' / 'summary.json').read_text())
        assert_close(got, doc, rel)


def assert_close(a, b, rel: float, path: str = '') -> None:
    """Assert equal nested JSON values; floats to ``rel``."""
    if isinstance(a, dict):
        assert set(a) == set(b), path
        for k in a:
            assert_close(a[k], b[k], rel, f'{path}/{k}')
    elif isinstance(a, list):
        assert len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b)):
            assert_close(x, y, rel, f'{path}[{k}]')
    elif isinstance(a, float) and isinstance(b, float) and rel:
        assert a == pytest.approx(b, rel=rel, abs=1e-9), path
    else:
        assert a == b, path


def test_bounded_curves_equal_the_full_ones_then_keep_the_extremes(bags, monkeypatch):
    full = load_history(bags / 'p30')
    same = stream_history(bags / 'p30')                       # 3001 samples: every one
    assert same.decimated == []
    for attr in ('couplers', 'coaches', 'cylinders'):
        a, b = getattr(full, attr), getattr(same, attr)
        assert a.names == b.names and np.array_equal(a.t, b.t)
        for fld in ('position', 'velocity', 'effort'):
            assert np.array_equal(getattr(a, fld), getattr(b, fld), equal_nan=True)
    assert np.array_equal(full.head_pressure[1], same.head_pressure[1])
    monkeypatch.setattr(history_mod, 'MAX_PLOT_SAMPLES', 400)
    monkeypatch.setattr(history_mod, 'BLOCK_ROWS', 97)
    small = stream_history(bags / 'p30')
    assert set(small.decimated) >= {'couplers', 'coaches', 'brake_pipe/pressure'}
    for attr in ('couplers', 'coaches', 'cylinders'):
        a, b = getattr(full, attr), getattr(small, attr)
        assert len(b) <= 400 and a.names == b.names
        assert a.t[0] <= b.t[0] and b.t[-1] <= a.t[-1] and np.all(np.diff(b.t) >= 0)
        for fld in ('position', 'velocity', 'effort'):
            x, y = getattr(a, fld), getattr(b, fld)
            for op in (np.fmax, np.fmin):         # (NaN: a value the topic does not carry)
                assert np.array_equal(op.reduce(x, axis=0), op.reduce(y, axis=0),
                                      equal_nan=True)


def test_envelope_bins_each_sample_where_it_belongs_and_grows_past_a_low_estimate():
    """Min/max per bin as from the whole curve; a count hint 4x too low merges bins."""
    t = np.arange(5000) * 0.01
    q = np.stack([np.sin(t), np.cos(3 * t), t], axis=1)[:, None, :]     # 1 field, 3 columns
    env = Envelope(3, fields=1, limit=100, count_hint=1200)
    for k in range(0, 5000, 333):
        env.add(t[k:k + 333], q[k:k + 333])
    tb, qb = env.curves()
    assert env.decimated and len(tb) <= 100
    width = env.width
    assert width >= 50.0 / 50                  # 50 s in at most 50 bins
    for k in range(0, len(tb), 2):
        sel = np.floor((t - env.t0) / width) == np.floor((tb[k] - env.t0) / width)
        assert np.array_equal(qb[k], q[sel].min(axis=0))
        assert np.array_equal(qb[k + 1], q[sel].max(axis=0))
    assert np.array_equal(qb.max(axis=0), q.max(axis=0))
    exact = Envelope(3, fields=1, limit=None)
    exact.add(t, q)
    assert not exact.decimated and np.array_equal(exact.curves()[1], q)


def test_report_and_plot_of_a_bag_with_a_reset_take_the_last_run(tmp_path, monkeypatch):
    """A simulator reset during a recording: the last run, as the in-memory history has it."""
    bag = tmp_path / 'reset'
    with BagRecorder(bag) as rec:
        seq = 0
        for steps in (150, 400):                       # 1.5 s, then reset, 4 s
            for k in range(steps + 1):
                t = k * 0.01
                x = np.array([20 * t, 20 * t - 25.01, 20 * t - 50.03]) + 0.001 * np.sin(5 * t)
                v = np.array([20.0, 20.0, 20.0]) - 0.5 * t + 0.005 * np.cos([5 * t, 6 * t, 7 * t])
                y, yd = x[:-1] - x[1:] - 25.0, v[:-1] - v[1:]
                stamp_ns = 10 ** 9 + seq * 10 ** 7
                rec.write_msg('couplers', stamp_ns, joint_state(
                    t, ['coupler_1', 'coupler_2'], y, yd, 2.8e6 * y))
                rec.write_msg('coaches', stamp_ns, joint_state(
                    t, ['coach_1', 'coach_2', 'coach_3'], x, v, [1e4 * t] * 3))
                seq += 1
    monkeypatch.setattr(history_mod, 'BLOCK_ROWS', 64)
    assert offline.main(['report', str(bag), '--output', str(tmp_path / 'r'), '-q']) == 0
    doc = json.loads((tmp_path / 'r' / 'summary.json').read_text())
    hist = load_history(bag)
    assert len(hist.couplers) == 401 and any('backwards' in n for n in hist.notes)
    ref = json.loads(json.dumps(report_metrics(hist, None).result()))
    assert doc['train']['samples'] == 401
    assert_close({k: doc[k] for k in ref}, ref, 1e-12)
    assert doc['source']['notes'] == hist.notes
