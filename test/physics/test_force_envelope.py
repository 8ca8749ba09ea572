"""
The in-train force envelope.

Each coupler's largest tension and compression over every integration step, which the
output samples can miss at a buffer-blocking impact.
"""
import numpy as np
import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.train import TrainSimulator

#: 60 coaches of the paper, head pipe vented at t = 0: the run-in blocks the buffers (~5 s)
N = 60
T_END = 7.0


def _run(rate, **extra):
    """Return (simulator, sampled forces (K, N-1)) of the run-in at ``rate`` Hz outputs."""
    cfg = SimConfig.from_dict({'num_coaches': N, 'publish_rate': rate, **extra})
    sim = TrainSimulator(cfg)
    sim.set_head_pipe_pressure(0.0)
    per = int(round(1.0 / (rate * sim.h)))
    rows = [sim.coupler_force]
    while sim.t < T_END - 1e-9:
        sim.advance(per)
        rows.append(sim.coupler_force)
    return sim, np.array(rows)


@pytest.fixture(scope='module')
def every_step():
    return _run(500.0)       # an output at every 2 ms step


def test_envelope_is_the_extreme_of_every_step(every_step):
    """
    Plain fixed step: the envelope is the extreme of every step's forces, exactly.

    At the default the multirate sub-steps widen it too: at least every step's extreme, equal
    to it for each coupler that never took a sub-step, wider for some that did.
    """
    plain, F = _run(500.0, multirate_tolerance=0.0)
    tension, compression = plain.coupler_force_envelope
    np.testing.assert_array_equal(tension, np.maximum(F.max(axis=0), 0.0))
    np.testing.assert_array_equal(compression, np.maximum(-F.min(axis=0), 0.0))
    assert compression.max() > 1e6          # the buffers blocked (K_b = 1e8 N/m)
    sim, F = every_step
    tension, compression = sim.coupler_force_envelope
    steps_t, steps_c = np.maximum(F.max(axis=0), 0.0), np.maximum(-F.min(axis=0), 0.0)
    assert np.all(tension >= steps_t) and np.all(compression >= steps_c)
    untouched = sim.substeps_per_coupler == 0
    np.testing.assert_array_equal(tension[untouched], steps_t[untouched])
    np.testing.assert_array_equal(compression[untouched], steps_c[untouched])
    assert np.any(compression > steps_c)    # a sub-step's force between two steps


def test_envelope_does_not_depend_on_the_output_rate_and_beats_the_samples(every_step):
    sim, _ = every_step
    slow, F = _run(100.0)
    np.testing.assert_array_equal(slow.coupler_force_envelope[0], sim.coupler_force_envelope[0])
    np.testing.assert_array_equal(slow.coupler_force_envelope[1], sim.coupler_force_envelope[1])
    sampled = -F.min(axis=0)
    envelope = slow.coupler_force_envelope[1]
    assert np.all(envelope >= sampled)
    # the 10 ms samples miss the blocking impacts' peaks by several per cent
    assert np.max((envelope - sampled) / envelope.max()) > 0.05     # 12.6 % here


def test_error_controlled_envelope_and_reset():
    sim, F = _run(100.0, integration_tolerance=1e-2)
    tension, compression = sim.coupler_force_envelope
    assert np.all(tension >= F.max(axis=0)) and np.all(compression >= -F.min(axis=0))
    sim.reset()
    assert not np.any(sim.coupler_force_envelope[0]) and not np.any(sim.coupler_force_envelope[1])


def test_run_metrics_report_the_envelope(every_step):
    sim, F = every_step
    metrics = RunMetrics(N)
    assert metrics.flat()['max_compression_every_step'] is None
    metrics.set_envelope(*sim.coupler_force_envelope)
    zeros = np.zeros(N)
    metrics.add(T_END, np.zeros(N - 1), np.zeros(N - 1), F[-1], zeros, zeros, zeros)
    flat = metrics.flat()
    assert flat['max_compression_every_step'] == sim.coupler_force_envelope[1].max()
    assert flat['max_tension_every_step'] == sim.coupler_force_envelope[0].max()
    rows = metrics.result()['couplers']
    assert [r['max_compression_every_step'] for r in rows] == list(
        sim.coupler_force_envelope[1])
