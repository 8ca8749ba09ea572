"""
The adhesion limit of a train without wheelsets: the brake passes at most mu(v) m g to the rail.

Hand-computed figures: the available adhesion mu(v) = mu_low f(v) / f(0), Curtius and
Kniffler's f(v) = 0.161 + 7.5 / (3.6 v + 44) (0.331 at rest on dry rail); a coach braked
harder than that is decelerated by mu(v) g and stops in int_0^v0 v dv / (mu(v) g)
(:func:`~train_dynamics.physics.wheelset.adhesion_limited_distance`); the demand beyond it is
booked as sliding (time and distance), as a wheelset's locked wheel is.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics.physics import wheelset as wsl
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.train import TrainSimulator

P_FULL = 3.8e5
MASS = 45_000.0
G = 9.81
#: the force chain of the hostile case: 64 cylinders of 1 m^2, rigging ratio 100 (composite
#: blocks): some 1.2e9 N of block force on a 45 t coach
ABSURD_CHAIN = {'friction_material': 'composite_k', 'brake_cylinder_area': 1.0,
                'brake_cylinders': 64.0, 'rigging_ratio': 100.0}


def _sim(**overrides) -> TrainSimulator:
    values = {'num_coaches': 2, 'coach_mass': MASS, 'initial_speed': 100 / 3.6,
              'brake_input': 'cylinder_per_coach'}
    values.update(overrides)
    return TrainSimulator(SimConfig.from_dict(values))


def _mu(v: float, mu_low: float = wsl.DRY_ADHESION) -> float:
    """Curtius-Kniffler by hand: mu_low f(v) / f(0), v [m/s]."""
    return mu_low * (0.161 + 7.5 / (3.6 * v + 44.0)) / (0.161 + 7.5 / 44.0)


def test_absurd_force_chain_brakes_at_the_adhesion_and_counts_the_sliding():
    """The 64 x 1 m^2 chain: the coach brakes with mu(v) m g, not ~1e9 N; its wheels slide."""
    sim = _sim(**ABSURD_CHAIN)
    sim.set_cylinder_pressure(P_FULL)
    sim.advance_to(0.5)
    v = sim.v
    # the force over the last step: the mean of the limits at the step's two ends
    assert sim.brake_force == pytest.approx(_mu(v[0]) * MASS * G * np.ones(2), rel=1e-3)
    assert np.all(sim.sliding_time == pytest.approx(0.5, abs=2 * sim.h))
    travelled = sim.x
    assert sim.sliding_distance == pytest.approx(travelled, rel=1e-3)
    # unlimited: the force as computed (~5e8 N) stops the train from 100 km/h within 0.1 s
    unlimited = _sim(adhesion_limit=False, **ABSURD_CHAIN)
    unlimited.set_cylinder_pressure(P_FULL)
    unlimited.advance_to(0.1)
    assert np.all(unlimited.v == 0.0)
    assert np.all(unlimited.sliding_time == 0.0)


def test_adhesion_limited_stop_takes_the_ideal_distance():
    """Braked beyond the adhesion from 100 km/h the train stops in int v dv / (mu(v) g)."""
    sim = _sim(**ABSURD_CHAIN)
    sim.set_cylinder_pressure(P_FULL)
    while np.any(sim.v > 0.0) and sim.t < 60.0:
        sim.advance(50)
    ideal = wsl.adhesion_limited_distance(100 / 3.6, wsl.DRY_ADHESION, g=G)
    assert sim.x[0] == pytest.approx(ideal, rel=0.005)
    assert np.all(sim.v == 0.0)


def test_limit_follows_the_track_adhesion_changed_live():
    """A train without wheelsets on a rail set to 0.05 live: Fb = 0.05 f(v) / f(0) m g."""
    sim = _sim(**ABSURD_CHAIN)
    assert not sim.wheelsets
    sim.set_track_adhesion([-1.0e6], [0.05])
    sim.set_cylinder_pressure(P_FULL)
    sim.advance_to(0.2)
    assert sim.brake_force == pytest.approx(_mu(sim.v[0], 0.05) * MASS * G * np.ones(2),
                                            rel=1e-3)
    wet = _sim(track_adhesion_positions=[-1.0e6], track_adhesion=[0.4], **ABSURD_CHAIN)
    assert not wet.wheelsets                              # above dry: no wheelsets implied
    wet.set_cylinder_pressure(P_FULL)
    wet.advance_to(0.2)
    assert wet.brake_force[0] == pytest.approx(_mu(wet.v[0], 0.4) * MASS * G, rel=1e-3)


@pytest.mark.parametrize('tolerance', [0.0, 1e-3])
def test_adhesion_limited_stop_balances_energy_and_momentum(tolerance):
    """Limited stop (fixed step, error control): energy within 0.5 %, momentum to round-off."""
    sim = _sim(num_coaches=4, integration_tolerance=tolerance, davis_a=500.0, **ABSURD_CHAIN)
    ke0, p0 = sim.kinetic_energy, sim.momentum
    sim.set_cylinder_pressure(P_FULL)
    sim.advance_to(30.0)
    assert np.all(sim.v == 0.0)
    assert np.all(sim.sliding_time > 5.0)
    lost = ke0 - sim.kinetic_energy
    dissipated = sim.work_brake + sim.work_resistance + (sim.work_coupler - sim.elastic_energy)
    assert abs(dissipated - lost) < 0.005 * lost
    assert sim.momentum - p0 == pytest.approx(sim.external_impulse, abs=1e-9 * abs(p0))


def test_paper_brake_below_the_adhesion_is_unchanged_bit_for_bit():
    """The paper's mu_a = 0.1 never reaches the dry rail's mu(v) (0.20 at 160 km/h)."""
    runs = []
    for limit in (True, False):
        sim = TrainSimulator(SimConfig.from_dict({'adhesion_limit': limit}))
        sim.advance_to(1.0)
        sim.set_head_pipe_pressure(0.0)
        sim.advance_to(20.0)
        runs.append((sim.x, sim.v, sim.coupler_force, sim.brake_force, sim.sliding_time))
    for a, b in zip(*runs):
        assert np.array_equal(a, b)
    assert np.all(runs[0][4] == 0.0)


def test_run_metrics_report_the_sliding_of_the_limit():
    """The summary and /diagnostics carry the limited vehicles' sliding time and distance."""
    from train_dynamics.physics.metrics import RunMetrics
    from train_dynamics.simulation.runner import Sample
    sim = _sim(**ABSURD_CHAIN)
    metrics = RunMetrics.for_run(sim.cfg, sim)
    sim.set_cylinder_pressure(P_FULL)
    metrics.sample(Sample(0, 0.0, sim, None))
    k = 0
    while np.any(sim.v > 0.0) and sim.t < 60.0:
        sim.advance(5)
        k += 5
        metrics.sample(Sample(k, sim.t, sim, None))
    flat = metrics.result()['train']
    assert flat['max_sliding_time'] == pytest.approx(float(np.max(sim.sliding_time)))
    assert flat['max_sliding_time'] > 0.9 * sim.t
    assert flat['max_sliding_distance'] == pytest.approx(flat['stopping_distance'], rel=0.01)
    values = dict(metrics.diagnostic()[2])
    assert float(values['max_sliding_time']) > 0.0
