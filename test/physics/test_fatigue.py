"""Rainflow counting and the damage-equivalent load against hand-counted sequences."""
import numpy as np
import pytest

from train_dynamics.physics.fatigue import (
    cycle_count, damage_equivalent_load, rainflow, turning_points)

#: ASTM E1049-85 (2017), Fig. 6 / section 5.4.4: the worked example of rainflow counting
ASTM_EXAMPLE = [-2.0, 1.0, -3.0, 5.0, -1.0, 3.0, -4.0, 4.0, -2.0]
#: its published result (Table 4 of the standard): range -> cycles
ASTM_RESULT = {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}


def _histogram(cycles):
    out = {}
    for r, n in zip(cycles.ranges, cycles.counts):
        out[float(r)] = out.get(float(r), 0.0) + float(n)
    return out


def test_rainflow_reproduces_the_standards_worked_example():
    assert _histogram(rainflow(ASTM_EXAMPLE)) == ASTM_RESULT


def test_rainflow_ignores_samples_between_the_turning_points():
    # the same history sampled finely (linear ramps between the points, plateaus) counts the same
    fine = np.concatenate([np.linspace(a, b, 7)[:-1] for a, b in
                           zip(ASTM_EXAMPLE[:-1], ASTM_EXAMPLE[1:])] + [[ASTM_EXAMPLE[-1]] * 3])
    assert _histogram(rainflow(fine)) == ASTM_RESULT
    np.testing.assert_array_equal(turning_points(fine), ASTM_EXAMPLE)


def test_hysteresis_gates_out_small_reversals():
    noisy = [0.0, 10.0, 9.9, 10.05, 0.0]
    plain = rainflow(noisy)
    # the 0.1 dip is a full cycle; the 10.05 excursion is counted twice as a half cycle
    np.testing.assert_allclose(sorted(plain.ranges), [0.15 - 0.05, 10.05, 10.05])
    np.testing.assert_allclose(plain.counts[np.argsort(plain.ranges)], [1.0, 0.5, 0.5])
    gated = rainflow(noisy, hysteresis=0.5)
    assert _histogram(gated) == {10.05: 1.0}


def test_damage_equivalent_load_by_hand():
    # a constant-amplitude history: 10 full cycles of range 2 -> DEL over 10 cycles is 2
    signal = [0.0] + [2.0, 0.0] * 10
    cycles = rainflow(signal)
    assert np.sum(cycles.counts) == pytest.approx(10.0)
    assert damage_equivalent_load(cycles, m=4.0, n_eq=10.0) == pytest.approx(2.0)
    # the ASTM spectrum, m = 4, N_eq = 1: (0.5*3^4 + 1.5*4^4 + 0.5*6^4 + 8^4 + 0.5*9^4)^(1/4)
    expected = (0.5 * 81 + 1.5 * 256 + 0.5 * 1296 + 4096 + 0.5 * 6561) ** 0.25
    assert damage_equivalent_load(rainflow(ASTM_EXAMPLE), m=4.0) == pytest.approx(expected)
    assert cycle_count(rainflow(ASTM_EXAMPLE), above=5.0) == pytest.approx(2.0)


def test_rainflow_refuses_nan():
    with pytest.raises(ValueError):
        rainflow([0.0, float('nan'), 1.0])


def test_block_fed_fatigue_equals_the_whole_history_counted_at_once():
    from train_dynamics.physics.fatigue import FatigueFeed
    rng = np.random.default_rng(4)
    forces = np.cumsum(rng.normal(size=(5000, 3)), axis=0) * 1e3   # three random walks [N]
    feed = FatigueFeed(['coupler_1', 'coupler_2', 'coupler_3'])
    for start in range(0, 5000, 777):          # blocks that cut through excursions
        feed.add(forces[start:start + 777])
    found = feed.result()
    above = 0.1 * np.abs(forces).max()
    for j, name in enumerate(feed.names):
        whole = rainflow(forces[:, j])
        assert found['couplers'][name]['del'] == pytest.approx(
            damage_equivalent_load(whole, 4.0), rel=1e-12)
        assert found['couplers'][name]['cycles'] == cycle_count(whole, above)
    assert found['max_del'] == max(c['del'] for c in found['couplers'].values())
