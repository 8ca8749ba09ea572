"""The coach chain: momentum (eq. 8), energy, stopping distance, brakes that hold."""
import numpy as np
from physics_helpers import paper_sim
import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel.layout import STATE
from train_dynamics.physics.train import TrainSimulator

G = 9.81
MU = 0.1


def test_momentum_balance_eq8_to_round_off():
    """Coupler forces are internal: d(sum m v)/dt = -sum Fb, step by step (eq. 8)."""
    sim = paper_sim(masses=[45000.0, 60000.0, 30000.0, 52000.0, 45000.0])
    impulse_scale = sim.h * MU * G * 60000.0
    worst = 0.0
    peak = 0.0
    while sim.t < 8.0:                          # the brake wave and the buffer shocks
        p0 = sim.momentum
        sim.advance(1)
        assert not sim.held.any()
        balance = (sim.momentum - p0) + sim.h * np.sum(sim.brake_force)
        worst = max(worst, abs(balance))
        peak = max(peak, np.max(np.abs(sim.coupler_force)))
    assert worst < 1e-9 * impulse_scale * 1e3   # round-off of ~1e6 kg m/s sums
    assert peak > 1000.0                        # the couplers were loaded meanwhile


def test_energy_balance_paper_scenario():
    """Kinetic energy lost = brake work + work on the couplers (stored + dissipated)."""
    sim = paper_sim()
    ke0 = sim.kinetic_energy
    sim.advance_to(70.0)
    assert sim.held.all() and np.all(sim.v == 0.0)
    lost = ke0 - sim.kinetic_energy
    assert lost == pytest.approx(sim.work_brake + sim.work_coupler, rel=5e-3)
    dissipated = sim.work_coupler - sim.elastic_energy
    assert dissipated > 0.0


def test_energy_balance_buffer_impact():
    """
    Two free coaches, the rear one 1 m/s faster: all energy goes into the couplers.

    Here the coupler work is everything, so the test checks the coupler bookkeeping itself.
    """
    sim = TrainSimulator(SimConfig.from_dict({'num_coaches': 2, 'initial_speed': 10.0,
                                              'integration_step': 5e-4}))
    sim.coach[STATE.V, 1] = 11.0
    ke0 = sim.kinetic_energy
    p0 = sim.momentum
    sim.advance_to(3.0)
    lost = ke0 - sim.kinetic_energy
    assert sim.work_brake == 0.0
    assert sim.momentum == pytest.approx(p0, rel=1e-13)
    assert lost == pytest.approx(sim.work_coupler, rel=5e-3)
    dissipated = sim.work_coupler - sim.elastic_energy
    # the buffer hysteresis absorbs a large share of the 11.25 kJ of relative motion energy
    assert 0.2 * lost < dissipated <= lost * 1.005


def test_stopping_distance_matches_v2_over_2a():
    """All cylinders at maximum from t = 0: a = mu_a g, distance v0^2 / (2 a)."""
    v0 = 44.444
    sim = TrainSimulator(SimConfig.from_dict({'brake_input': 'cylinder_per_coach',
                                              'num_coaches': 5}))
    sim.set_cylinder_pressure(380000.0)
    sim.advance_to(60.0)
    assert sim.held.all()
    expected = v0 ** 2 / (2 * MU * G)
    assert sim.x == pytest.approx(np.full(5, expected), rel=1e-2)
    # stopping time v0 / a too
    assert np.all(sim.v == 0.0)


def test_braked_train_at_rest_stays_at_rest():
    sim = paper_sim()
    sim.advance_to(60.0)
    assert sim.held.all()
    x_stop = sim.x
    trace = []
    for _ in range(50):
        sim.advance_to(sim.t + 0.2)
        trace.append(sim.v.copy())
    assert np.all(np.array(trace) == 0.0)
    np.testing.assert_array_equal(sim.x, x_stop)


def test_brake_never_pushes_backwards():
    """During the whole stop no coach ever moves backwards; a standing coach stays put."""
    sim = paper_sim(num_coaches=6)
    vmin = np.inf
    while sim.t < 60.0:
        sim.advance(25)
        vmin = min(vmin, sim.v.min())
    assert vmin >= 0.0
    standing = TrainSimulator(SimConfig.from_dict({'initial_speed': 0.0,
                                                   'brake_input': 'cylinder_per_coach'}))
    standing.set_cylinder_pressure(380000.0)
    standing.advance_to(5.0)
    assert np.all(standing.x == 0.0) and np.all(standing.v == 0.0)


def test_released_brakes_let_compressed_couplers_spring_back():
    """Holding is friction, not glue: with the brakes released the stored energy moves coaches."""
    sim = TrainSimulator(SimConfig.from_dict({'brake_input': 'cylinder_per_coach',
                                              'initial_speed': 20.0}))
    sim.set_cylinder_pressure([380000.0, 150000.0, 50000.0])   # the rear pushes on the front
    sim.advance_to(80.0)
    # coaches 1-2 are held; coach 3's spring force just exceeds its brake, and with tanh
    # friction vanishing at ydot = 0 it creeps back (nm/s) towards k_e |y| = Fb
    assert sim.held[:2].all() and np.max(np.abs(sim.v)) < 1e-6
    sim.set_cylinder_pressure(0.0)
    sim.advance_to(80.1)
    assert np.max(np.abs(sim.v)) > 1e-2


def test_fault_stops_integration_and_keeps_state():
    sim = TrainSimulator(SimConfig.from_dict({'max_coupler_displacement': 0.001,
                                              'brake_input': 'cylinder_per_coach'}))
    sim.set_cylinder_pressure([380000.0, 0.0, 0.0])
    sim.advance_to(10.0)
    assert sim.fault is not None and 'range' in sim.fault
    t_fault, x_fault = sim.t, sim.x
    assert sim.advance(100) == 0 and sim.t == t_fault
    np.testing.assert_array_equal(sim.x, x_fault)
    assert np.all(np.abs(sim.y) <= 0.001)
    sim.reset()
    assert sim.fault is None and sim.t == 0.0


def test_mixed_vehicles_per_coupler_constants():
    """A train can mix vehicles: each coupler uses its own constants (eqs. 2-3)."""
    ke = [2.8e6, 8.0e6, 2.8e6]
    sim = TrainSimulator(SimConfig.from_dict({'num_coaches': 4, 'initial_speed': 10.0}),
                         coupler_constants={'buffer_stiffness': ke})
    sim.coach[STATE.V, 3] = 10.5          # the last coach runs into the train
    sim.advance_to(0.3)
    y, yd = sim.y, sim.ydot
    s = np.tanh(1000.0 * yd)
    expected = np.where(y < 0, (np.array(ke) - 1.4e6 * s) * y, (5.46e6 + 2.43e6 * s) * y)
    np.testing.assert_allclose(sim.coupler_force, expected, rtol=1e-12)
    assert y[2] < 0.0                  # the impact compressed the last coupler
    with pytest.raises(ValueError):
        TrainSimulator(SimConfig.from_dict({'num_coaches': 4}),
                       coupler_constants={'buffer_friction': [3e6, 1e6, 1e6]})
