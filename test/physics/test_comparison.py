"""The accuracy contract's metrics against signals whose answer is known by construction."""
import numpy as np
import pytest

from train_dynamics.physics import comparison

T = np.arange(0.0, 10.0, 0.01)   # 100 Hz, as the outputs


def _step(t0):
    return np.where(T >= t0, 100.0, 0.0)


def test_tube_forgives_a_shift_within_tau_and_not_beyond():
    ref = _step(5.0)
    early = _step(4.99)
    late = _step(5.03)
    assert comparison.worst_sample(early, ref) == pytest.approx(1.0)
    assert comparison.tube(T, early, ref, tau=0.01) == pytest.approx(0.0)
    assert comparison.tube(T, late, ref, tau=0.01) == pytest.approx(1.0)
    assert comparison.tube(T, late, ref, tau=0.03) == pytest.approx(0.0)


def test_tube_counts_a_wrong_level_in_full():
    ref = 100.0 * np.sin(2 * np.pi * 0.5 * T)
    assert comparison.tube(T, 1.03 * ref, ref, tau=0.01) == pytest.approx(0.03, rel=1e-6)
    # a 5 ms shift of a 0.5 Hz sine (four whole periods, then at rest) stays inside a
    # +-10 ms tube

    def wave(t):
        return np.where((t > 0.0) & (t < 8.0), 100.0 * np.sin(2 * np.pi * 0.5 * t), 0.0)
    ref = wave(T)
    shifted = wave(T - 0.005)
    # all that is left is the crest between two samples of the shifted wave:
    # 100 (1 - cos(2 pi 0.5 0.005)) = 0.0123 N
    crest = 1.0 - np.cos(2 * np.pi * 0.5 * 0.005)
    assert comparison.tube(T, shifted, ref, tau=0.01) == pytest.approx(crest, rel=1e-6)
    assert comparison.worst_sample(shifted, ref) > 0.01


def test_window_and_coupler_envelopes_by_hand():
    ref = np.zeros((T.size, 2))
    ours = np.zeros((T.size, 2))
    ref[150, 0] = 100.0      # a peak of 100 N at t = 1.5 s on coupler 1
    ours[160, 0] = 90.0      # ours peaks 10 % low, 0.1 s later, same 1 s window
    ref[520, 1] = -50.0
    ours[620, 1] = -50.0     # same compression, next window
    assert comparison.window_envelope(T, ours, ref, 1.0) == pytest.approx(0.5)
    assert comparison.coupler_envelope(ours, ref) == pytest.approx(0.1)


def test_del_and_cycle_count_errors():
    ref = 100.0 * np.sin(2 * np.pi * 1.0 * T)[:, None]
    assert comparison.del_error(ref, ref) == 0.0
    assert comparison.del_error(1.02 * ref, ref) == pytest.approx(0.02 * 2.0 * 10 ** 0.25,
                                                                  rel=0.02)
    fewer = ref.copy()
    fewer[T >= 5.0] = 0.0   # half the cycles
    assert comparison.cycle_count_error(fewer, ref) == pytest.approx(-0.5, abs=0.06)


def test_a_zero_reference_is_refused():
    with pytest.raises(ValueError):
        comparison.worst_sample(np.ones(3), np.zeros(3))
