"""Standstill: brakes holding the vehicles at rest, a complementarity problem."""
import itertools

import numpy as np
import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import standstill
from train_dynamics.physics.kernel.layout import WORK
from train_dynamics.physics.kernel.step import make_workspace
from train_dynamics.physics.train import TrainSimulator

G = 9.81
MU = 0.1
P_MAX = 380000.0


def braking_train(n, h, **params) -> TrainSimulator:
    """
    Return n paper coaches, head pipe vented at t = 0 (emergency), fixed step h [s].

    The paper's law without blocking (strokes out of reach, as the bench's reference): the
    couplers of a long train stay deflected when it stops, and the brakes must hold them.
    """
    sim = TrainSimulator(SimConfig.from_dict({'num_coaches': n, 'integration_step': h,
                                              'buffer_stroke': 10.0,
                                              'draw_gear_stroke': 10.0, **params}))
    sim.set_head_pipe_pressure(0.0)
    return sim


@pytest.mark.parametrize('n, h', [(100, 5e-3), (100, 2e-3), (30, 5e-3)])
def test_long_train_is_at_rest_and_held_within_2_s_and_stays_so(n, h):
    """
    Every vehicle at rest (v == 0) and held within 2 s of the last vehicle's first stop.

    Then 20 s at rest: no vehicle moves, no held flag flips, and no step needs more than
    one chain solve (the stopped train costs what a moving one does). Before the holding
    LCP, 100 coaches chattered for ever (period 2, 95-97 of 100 held; 30 coaches settled
    before too).
    """
    sim = braking_train(n, h)
    sim.advance_to(45.0)
    stopped = np.zeros(n, dtype=bool)
    while not stopped.all():
        assert sim.t < 70.0, 'the train does not stop'
        sim.advance(1)
        stopped |= sim.v == 0.0
    t_stop = sim.t
    while not (np.all(sim.held) and np.all(sim.v == 0.0)):
        assert sim.t < t_stop + 2.0, f'{np.sum(~sim.held)} vehicles not held 2 s after the stop'
        sim.advance(1)
    x_rest = sim.x
    solves = sim.integration_stats['hold_solves']
    t_end = sim.t + 20.0
    while sim.t < t_end:
        sim.advance(1)
        assert np.all(sim.held) and np.all(sim.v == 0.0), f'moved again at t = {sim.t}'
    np.testing.assert_array_equal(sim.x, x_rest)
    assert sim.integration_stats['hold_solves'] == solves
    assert sim.integration_stats['hold_capped'] == 0


def test_error_controlled_stepping_brings_the_train_to_rest_too():
    sim = braking_train(100, 2e-3, integration_tolerance=1e-3)
    sim.advance_to(54.0)
    assert np.all(sim.held) and np.all(sim.v == 0.0)
    x_rest = sim.x
    sim.advance_to(64.0)
    np.testing.assert_array_equal(sim.x, x_rest)


def gradient_sim(gradient, pressure, **params) -> TrainSimulator:
    """Return 3 coaches at rest on a constant gradient [per mille], cylinders at ``pressure``."""
    sim = TrainSimulator(SimConfig.from_dict({
        'num_coaches': 3, 'initial_speed': 0.0, 'brake_input': 'cylinder_per_coach',
        'track_gradient_positions': [-1.0e6], 'track_gradients': [gradient], **params}))
    sim.set_cylinder_pressure(np.full(3, pressure))
    return sim


@pytest.mark.parametrize('gradient', [-8.0, 8.0])
def test_brake_holds_on_a_gradient_with_the_downhill_force(gradient):
    """Held, the brake's force is the downhill force m g G (not its limit mu m g)."""
    sim = gradient_sim(gradient, P_MAX)
    sim.advance_to(20.0)
    assert np.all(sim.x == 0.0) and np.all(sim.v == 0.0) and np.all(sim.held)
    np.testing.assert_allclose(sim.brake_force, 45000.0 * G * abs(gradient) * 1e-3,
                               rtol=1e-9)


@pytest.mark.parametrize('gradient', [-40.0, 40.0])
@pytest.mark.parametrize('davis_a', [0.0, 3000.0])
def test_released_vehicle_slides_downhill_at_the_closed_form_acceleration(gradient, davis_a):
    """
    Downhill force above brake + static resistance: it slides downhill, never uphill.

    a = (m g |G| - Fb - A) / (m (1 + rmf)), Fb = mu m g p / p_max (eq. 13); the braking
    force acts from the instant its cylinder input is set (zero-order hold).
    """
    rmf = 0.05
    ratio = 0.2       # Fb = 0.02 m g < m g 0.04
    sim = gradient_sim(gradient, ratio * P_MAX, davis_a=davis_a, rotating_mass_factor=rmf)
    m = 45000.0
    fb = MU * m * G * ratio
    a = (m * G * abs(gradient) * 1e-3 - fb - davis_a) / (m * (1.0 + rmf))
    downhill = -np.sign(gradient)
    sim.advance_to(5.0)
    assert not sim.held.any()
    expected = downhill * a * 5.0
    np.testing.assert_allclose(sim.v, expected, rtol=1e-9)


@pytest.mark.parametrize('h', [5e-3, 2e-3])
def test_momentum_and_energy_balance_through_the_standstill(h):
    """
    The holding forces are external: momentum change = external impulse, energy balanced.

    100 coaches with static resistance (Davis A, held like the brake) brake to rest and
    are held 20 s; the stop needed the LCP's extra solves.
    """
    sim = braking_train(100, h, davis_a=500.0)
    p0, ke0 = sim.momentum, sim.kinetic_energy
    sim.advance_to(75.0)
    assert np.all(sim.held) and np.all(sim.v == 0.0)
    assert sim.integration_stats['hold_solves'] > 0
    assert sim.momentum - p0 == pytest.approx(sim.external_impulse, abs=1e-6 * abs(p0))
    lost = ke0 - sim.kinetic_energy
    dissipated = (sim.work_brake + sim.work_resistance
                  + (sim.work_coupler - sim.elastic_energy))
    assert abs(dissipated - lost) < 0.005 * lost


def test_energy_balance_through_the_standstill_paper_law():
    """Kinetic energy lost = brake work + coupler work, the holding included (no resistance)."""
    sim = braking_train(100, 5e-3)
    ke0 = sim.kinetic_energy
    sim.advance_to(75.0)
    assert np.all(sim.held)
    lost = ke0 - sim.kinetic_energy
    assert lost == pytest.approx(sim.work_brake + sim.work_coupler, rel=5e-3)


def test_iteration_cap_is_counted_and_the_step_finishes():
    """
    300 coaches stop in waves: some steps reach the cap of chain solves; counted, finite.

    (A block of this train keeps creeping backwards at mm/s: its couplers' springs push
    harder than the brakes hold, and tanh friction vanishes at rest.)
    """
    sim = braking_train(300, 5e-3)
    sim.advance_to(70.0)
    assert sim.fault is None
    assert sim.integration_stats['hold_capped'] > 0
    assert np.all(np.isfinite(sim.x)) and np.all(np.isfinite(sim.v))
    assert np.max(np.abs(sim.v)) < 0.05


def _consistent(held, d, a, r, fb):
    """Return whether the set (held, slide direction d) solves the friction LCP exactly."""
    n = len(r)
    f = np.where(held, 0.0, d * fb)
    free = ~held
    z = np.zeros(n)
    if free.any():
        z[free] = np.linalg.solve(a[np.ix_(free, free)], (r - f)[free])
    hold = r - a @ z
    ok_held = np.abs(hold[held]) <= fb[held] * (1.0 + 1e-9)
    ok_free = d[free] * z[free] > 0.0
    return ok_held.all() and ok_free.all(), z


@pytest.mark.parametrize('seed', range(8))
def test_holding_lcp_matches_the_brute_force_solution(seed):
    """
    Block principal pivoting finds the one consistent set of held and sliding vehicles.

    Six vehicles at rest on a tridiagonal stage matrix A (masses + coupler weights kk),
    holding limits Fb, right-hand side r: the pivoting's set is the one of the 3^6 sets
    where every held vehicle needs |A z - r| <= Fb and every sliding one moves its way.
    """
    rng = np.random.default_rng(seed)
    n = 6
    masses = rng.uniform(2e4, 6e4, n)
    kk = rng.uniform(1e3, 2e5, n - 1)
    a = np.diag(masses)
    for j in range(n - 1):
        a[j, j] += kk[j]
        a[j + 1, j + 1] += kk[j]
        a[j, j + 1] = a[j + 1, j] = -kk[j]
    fb = rng.uniform(2e4, 5e4, n)
    r = rng.uniform(-1.0, 1.0, n) * fb * rng.uniform(0.5, 2.5, n)
    ws = make_workspace(n)
    ws[WORK.DIAG] = np.diag(a)
    ws[WORK.KK, :n - 1] = kk
    ws[WORK.LR] = r
    ws[WORK.FB] = fb
    ws[WORK.LS] = 2.0
    held = np.ones(n, dtype=bool)
    assert standstill.pivot(1.0, held, ws, 50) > 0
    d = ws[WORK.RELDIR].copy()
    ok, z = _consistent(held, d, a, r, fb)
    assert ok
    solutions = []
    for states in itertools.product((0, 1, -1), repeat=n):
        s = np.array(states, dtype=float)
        if _consistent(s == 0, s, a, r, fb)[0]:
            solutions.append(s)
    assert len(solutions) == 1
    np.testing.assert_array_equal(np.where(held, 0.0, d), solutions[0])
