"""The brake system: pipe propagation, distributors, UIC cylinder times, eqs. (12)-(13)."""
import numpy as np
import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import brakes
from train_dynamics.physics.reference import HeadVentBraking
from train_dynamics.physics.train import TrainSimulator

P_MAX = 380000.0
BAR = 1e5


def make(**kw):
    kw.setdefault('initial_speed', 0.0)   # brakes only: a train at rest stays put
    return TrainSimulator(SimConfig.from_dict(kw))


def first_time_above(sim, threshold, t_end):
    """Time [s] at which each coach's cylinder first exceeds threshold [Pa]."""
    n = sim.n
    first = np.full(n, np.nan)
    while sim.t < t_end:
        sim.advance(1)
        newly = np.isnan(first) & (sim.cylinder_pressure > threshold)
        first[newly] = sim.t
    return first


def test_braking_force_eq13_and_adhesion_limit_eq12():
    m = np.array([45000.0, 45000.0, 80000.0, 45000.0])
    p = np.array([P_MAX, 0.5 * P_MAX, P_MAX, -1e4])
    Fb = brakes.braking_force(p, P_MAX, 0.1, m, 9.81, np.empty(4))
    np.testing.assert_allclose(Fb, [0.1 * 45000 * 9.81, 0.05 * 45000 * 9.81,
                                    0.1 * 80000 * 9.81, 0.0])
    # a cylinder over p_max cannot exceed the adhesion limit mu_a m g (eq. 12)
    over = brakes.braking_force(np.array([2 * P_MAX]), P_MAX, 0.1, m[:1], 9.81, np.empty(1))
    assert over[0] == pytest.approx(0.1 * 45000 * 9.81)


def test_brake_wave_reaches_coach_i_after_i_minus_1_times_0p1_s():
    sim = make(num_coaches=6, integration_step=1e-3)
    sim.advance_to(1.0)
    sim.set_head_pipe_pressure(0.0)
    first = first_time_above(sim, 1.0, 2.0)
    expected = 1.0 + np.arange(6) * 25.0 / 250.0
    np.testing.assert_allclose(first, expected + 1e-3, atol=1.5e-3)
    np.testing.assert_allclose(np.diff(first), 0.1, atol=1.5e-3)


def test_references_closed_form_braking_is_the_simulators():
    """
    The references' closed-form braking (HeadVentBraking) against the simulator.

    Paper defaults (25 m coaches, wave at 250 m/s: 0.1 s per coach): before the wave nothing,
    at the end of the filling table the adhesion limit mu_a m g, and in between the simulator's
    own braking forces to rounding (it applies the mean over its step h, (Fb(t-h) + Fb(t)) / 2).
    """
    cfg = SimConfig.from_dict({'num_coaches': 4})
    ref = HeadVentBraking(cfg, 1.0)
    np.testing.assert_allclose(ref.delays, [0.0, 0.1, 0.2, 0.3])
    full = cfg.adhesion_coefficient * np.array(cfg.mass_array) * cfg.gravity
    t_full = cfg.fill_table()[0][-1]
    np.testing.assert_array_equal(ref(1.0), 0.0)
    np.testing.assert_allclose(ref(1.0 + 0.3 + t_full), full)
    kinks = ref.kinks(3.0)
    assert kinks[0] == 1.0 and kinks[-1] < 3.0 and np.all(np.diff(kinks) > 0)
    sim = TrainSimulator(cfg)
    sim.schedule(1.0, lambda: sim.set_head_pipe_pressure(0.0))
    h = cfg.integration_step
    worst = 0.0
    for t in np.round(np.arange(1, 301) * 0.01, 10):
        sim.advance_to(t)
        worst = max(worst, np.abs(sim.brake_force - 0.5 * (ref(t - h) + ref(t))).max())
    assert worst < 1e-9 * full.max(), worst


def test_propagation_speed_sets_the_delay():
    sim = make(num_coaches=3, integration_step=1e-3, brake_propagation_speed=125.0,
               coach_length=20.0)
    sim.set_head_pipe_pressure(0.0)
    first = first_time_above(sim, 1.0, 1.0)
    np.testing.assert_allclose(np.diff(first), 20.0 / 125.0, atol=1.5e-3)


@pytest.mark.parametrize('pipe_bar, cyl_bar', [
    (4.85, 0.0),                       # 0.15 bar drop: inside the sensitivity, no braking
    (4.75, 0.0),                       # 0.25 bar: still ignored
    (4.6, 3.8 * 0.4 / 1.5),            # first stages: graduated, p_max * drop / 1.5 bar
    (4.25, 3.8 * 0.75 / 1.5),
    (4.0, 3.8 * 1.0 / 1.5),
    (3.5, 3.8),                        # full service
    (2.0, 3.8),                        # deeper drops cannot brake harder
    (0.0, 3.8),                        # emergency venting: full pressure
])
def test_distributor_graduated_application(pipe_bar, cyl_bar):
    sim = make(num_coaches=2, brake_input='pipe_per_coach')
    sim.set_pipe_pressure(pipe_bar * BAR)
    sim.advance_to(30.0)
    np.testing.assert_allclose(sim.cylinder_pressure, cyl_bar * BAR, rtol=1e-9, atol=1e-6)


def test_graduated_release_then_full_release():
    sim = make(num_coaches=2, brake_input='pipe_per_coach')
    sim.set_pipe_pressure(3.5 * BAR)                       # full service
    sim.advance_to(20.0)
    assert sim.cylinder_pressure == pytest.approx([P_MAX, P_MAX])
    sim.set_pipe_pressure(4.25 * BAR)                      # recharge halfway
    sim.advance_to(60.0)
    np.testing.assert_allclose(sim.cylinder_pressure, 1.9 * BAR, rtol=1e-9)   # not released
    sim.set_pipe_pressure(5.0 * BAR)                       # back to running pressure
    sim.advance_to(120.0)
    np.testing.assert_allclose(sim.cylinder_pressure, 0.0, atol=1e-9)


def test_per_coach_pipe_pressures_are_independent():
    sim = make(num_coaches=3, brake_input='pipe_per_coach')
    sim.set_pipe_pressure(5.0 * BAR)
    sim.set_pipe_pressure(3.5 * BAR, index=1)
    sim.advance_to(10.0)
    np.testing.assert_allclose(sim.cylinder_pressure, [0.0, P_MAX, 0.0], atol=1e-9)


def fill_and_release_times(regime):
    sim = make(num_coaches=2, brake_input='pipe_per_coach', brake_regime=regime,
               integration_step=1e-3)
    sim.set_pipe_pressure(0.0)
    t95 = first_time_above(sim, 0.95 * P_MAX - 1e-6, 60.0)[0]
    sim.advance_to(80.0)
    assert sim.cylinder_pressure[0] == pytest.approx(P_MAX)
    sim.set_pipe_pressure(5.0 * BAR)
    t_start = sim.t
    while sim.cylinder_pressure[0] > 0.4 * BAR:
        sim.advance(1)
    return t95, sim.t - t_start


def test_uic_passenger_brake_times():
    t_fill, t_release = fill_and_release_times('P')
    assert 3.0 <= t_fill <= 5.0           # UIC P: 3-5 s to 95 % of the maximum
    assert 15.0 <= t_release <= 20.0      # UIC P: 15-20 s release (to 0.4 bar)


def test_uic_goods_brake_times():
    t_fill, t_release = fill_and_release_times('G')
    assert 18.0 <= t_fill <= 30.0         # UIC G: 18-30 s
    assert 45.0 <= t_release <= 60.0      # UIC G: 45-60 s


def test_custom_filling_table_is_followed_exactly():
    table_t = [0.0, 1.0, 2.0]
    table_f = [0.0, 0.8, 1.0]
    sim = make(num_coaches=2, brake_input='pipe_per_coach', cylinder_fill_time=table_t,
               cylinder_fill_fraction=table_f, integration_step=1e-3)
    sim.set_pipe_pressure(0.0)
    sim.advance_to(0.5)
    # the first step applies the brake; the cylinder is 0.5 s along the table
    assert sim.cylinder_pressure[0] == pytest.approx(0.4 * P_MAX, rel=1e-9)
    sim.advance_to(1.5)
    assert sim.cylinder_pressure[0] == pytest.approx(0.9 * P_MAX, rel=1e-9)


def test_cylinder_per_coach_is_used_directly():
    sim = make(num_coaches=3, brake_input='cylinder_per_coach', initial_speed=20.0)
    sim.set_cylinder_pressure([0.0, 190000.0, 380000.0])
    sim.advance(10)
    np.testing.assert_allclose(sim.cylinder_pressure, [0.0, 190000.0, 380000.0])
    np.testing.assert_allclose(sim.brake_force, 0.1 * 45000 * 9.81 * np.array([0.0, 0.5, 1.0]),
                               rtol=1e-12)


def test_non_finite_input_is_refused():
    sim = make()
    for bad in (float('nan'), float('inf')):
        with pytest.raises(ValueError):
            sim.set_head_pipe_pressure(bad)
    with pytest.raises(ValueError):
        sim.set_cylinder_pressure([0.0, float('nan'), 0.0])
