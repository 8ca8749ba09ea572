"""
The traced copy of the error-controlled driver (``kernel/adaptive_trace.py``) is the driver.

``trace_adaptive`` writes the driver's chain loop out to log every attempted step; with the
kernel's controller constants and error norm (``default_ctl(0)``) it must leave the very state
``advance_adaptive`` leaves, bit for bit, and log one row per chain step the kernel counts.
"""
import numpy as np
import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import adaptive_trace
from train_dynamics.physics.train import TrainSimulator


def _drive(sim, seconds: float) -> None:
    """Run pipe_head braking: released for 0.5 s, then an emergency, output period by period."""
    for k in range(int(round(seconds / 0.01))):
        if k == 50:
            sim.set_head_pipe_pressure(0.0)
        sim.advance_to((k + 1) * 0.01)


@pytest.fixture(scope='module')
def compiled():
    """
    Compile the traced driver and the error-controlled kernel (or load them from the cache).

    Once per code version they compile (tens of seconds of CPU, minutes on a loaded machine):
    a fixture, outside the test's timeout (``func_only``), which guards the run, not numba.
    """
    cfg = SimConfig.from_dict({'integration_tolerance': 1e-3})
    kernel, copy = TrainSimulator(cfg), TrainSimulator(cfg)
    adaptive_trace.traced(copy, adaptive_trace.default_ctl(0), max_log=10)
    for sim in (kernel, copy):
        sim.advance_to(0.01)


@pytest.mark.timeout(600, func_only=True)
@pytest.mark.parametrize('extra', [{}, {'num_coaches': 6, 'davis_a': 500.0,
                                        'track_gradient_positions': [0.0],
                                        'track_gradients': [2.0]}])
def test_traced_driver_matches_the_kernel_bit_for_bit(compiled, extra):
    cfg = SimConfig.from_dict({'integration_tolerance': 1e-3, **extra})
    kernel, copy = TrainSimulator(cfg), TrainSimulator(cfg)
    log = adaptive_trace.traced(copy, adaptive_trace.default_ctl(0), max_log=200_000)
    _drive(kernel, 3.0)
    _drive(copy, 3.0)
    for name in ('coach', 'sc', 'iv', 'ws', 'ring', 'tick_fb', 'tick_te'):
        a, b = getattr(kernel, name), getattr(copy, name)
        assert a.tobytes() == b.tobytes(), name
    stats = kernel.integration_stats
    rows = log()
    assert stats['steps'] > 100
    assert int((rows[:, adaptive_trace.ACC] == 1.0).sum()) == stats['steps']
    assert int((rows[:, adaptive_trace.ACC] == 0.0).sum()) == stats['rejected']
    assert np.all(np.isfinite(kernel.coupler_force))
