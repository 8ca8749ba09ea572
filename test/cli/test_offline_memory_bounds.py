"""
Offline commands stream; compare keeps its table, zoom and figures correct.

Peak memory is measured in a child process (``resource.getrusage(RUSAGE_CHILDREN)`` after it
ends: ru_maxrss [KiB]) for two durations; the summary of a run is checked against the full
history it replaces (exact table and zoom window, min/max envelope).
"""
from __future__ import annotations

from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from train_dynamics.physics.brake_valve import BrakeValveModel
from train_dynamics.physics.config import SimConfig
from train_dynamics.recording import summary as summary_mod
from train_dynamics.recording.history import sign_changes_per_second
from train_dynamics.recording.sinks import ArraySink
from train_dynamics.recording.summary import RunSummary, Window, zoom_window
from train_dynamics.simulation import runner

REPO = Path(__file__).resolve().parents[2]
CFG = REPO / 'config' / 'paper_3coach.yaml'

PEAK = r"""
import resource, subprocess, sys
subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL)
print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
"""


def peak_rss_mb(*args) -> float:
    """Return the peak RSS [MB] of ``train-dynamics args`` run in a child process."""
    cmd = [sys.executable, '-c', PEAK, sys.executable, '-m', 'train_dynamics.cli.offline',
           *map(str, args)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=True, timeout=300)
    return int(out.stdout.split()[-1]) / 1024.0


def test_compare_memory_is_independent_of_duration(tmp_path):
    common = ['--params', CFG, '--steps', '0.0002', '--scale-factors', '1000', '-q']
    short = peak_rss_mb('compare', '--duration', 4, '--output', tmp_path / 'a', *common)
    long = peak_rss_mb('compare', '--duration', 20, '--output', tmp_path / 'b', *common)
    # the history kept in full grew by ~2 MB per simulated second here (5000 samples/s):
    # ~32 MB more at 20 s than at 4 s
    assert long - short < 15.0, (short, long)


def test_simulate_memory_is_independent_of_duration(tmp_path):
    short = peak_rss_mb('simulate', '--params', CFG, '--duration', 10, '--output',
                        tmp_path / 'a', '-q')
    long = peak_rss_mb('simulate', '--params', CFG, '--duration', 100, '--output',
                       tmp_path / 'b', '-q')
    assert long - short < 15.0, (short, long)


def _full_zoom(t, velocity, width, duration):
    """Return the zoom window as compare chose it from the full history (unstreamed)."""
    best, where, coupler = -1, duration / 2, 0
    for j in range(velocity.shape[1]):
        s = np.sign(velocity[:, j])
        keep = s != 0
        ts, s = t[keep], s[keep]
        tf = ts[1:][s[1:] != s[:-1]]
        if tf.size == 0:
            continue
        counts = np.searchsorted(tf, tf + width) - np.arange(tf.size)
        k = int(np.argmax(counts))
        if counts[k] > best:
            span = tf[k:k + counts[k]]
            best, where, coupler = int(counts[k]), float(span[0] + span[-1]) / 2, j
    return zoom_window(where, coupler, duration, width)


@pytest.mark.parametrize('model, rows, plot_max', [('sign', 7, 400), ('sign', 4096, 20000),
                                                   ('tanh', 33, 400)])
def test_compare_summary_equals_the_full_history(monkeypatch, model, rows, plot_max):
    monkeypatch.setattr(summary_mod, 'BLOCK_ROWS', rows)
    monkeypatch.setattr(summary_mod, 'MAX_PLOT_SAMPLES', plot_max)
    cfg = SimConfig.from_dict({'model_type': model, 'num_coaches': 4,
                               'integration_step': 0.001})
    duration = 3.0
    inputs = runner.InputSchedule('pipe_head', [], BrakeValveModel(schedule=['0.2:emergency']))
    steps = runner.output_steps(duration, 1000.0, 0.001)
    full = ArraySink()
    sim = runner.run_simulation(cfg, duration, inputs, on_sample=full.sample,
                                sample_steps=steps)
    hist = full.history(sim).couplers
    s = RunSummary(4, duration, len(steps), 0.001, track=True,
                   capture=Window(1.0, 1.2, 2))
    runner.run_simulation(cfg, duration, inputs, on_sample=s.sample, sample_steps=steps)
    s.finish()
    table = s.table()
    changes = sign_changes_per_second(hist.t, hist.velocity, tol=0.0)
    for j, (name, fmax, fmin, ch) in enumerate(table):
        assert name == hist.names[j]
        assert fmax == np.max(hist.effort[:, j]) and fmin == np.min(hist.effort[:, j])
        assert ch == pytest.approx(changes[j], rel=1e-12)
    window = _full_zoom(hist.t, hist.velocity, 0.2, duration)
    if model == 'sign':
        assert s.best_window() == window
    t, yd, f = s.zoom_data(window) if model == 'sign' else s.zoom_data(Window(1.0, 1.2, 2))
    w = window if model == 'sign' else Window(1.0, 1.2, 2)
    sel = (hist.t >= w.t0) & (hist.t <= w.t1)
    assert np.array_equal(t, hist.t[sel]) and np.array_equal(yd, hist.velocity[sel, w.j])
    assert np.array_equal(f, hist.effort[sel, w.j])
    curves, decimated = s.history('x')
    assert decimated == (len(steps) > plot_max)
    for fld in ('position', 'velocity', 'effort'):
        got, ref = getattr(curves.couplers, fld), getattr(hist, fld)
        assert got.max() == ref.max() and got.min() == ref.min()
        if not decimated:
            assert np.array_equal(got, ref)
        else:
            assert len(curves.couplers.t) <= plot_max
