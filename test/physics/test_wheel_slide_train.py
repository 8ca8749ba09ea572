"""
Wheel slide in the train: track adhesion, rotating wheelsets, slide protection (physics).

The closed forms: the speed-dependent adhesion-limited stopping distance
int_0^v0 v dv / (mu(v) g) (:func:`~train_dynamics.physics.wheelset.adhesion_limited_distance`,
with Curtius-Kniffler's fall of the adhesion with speed; the constant-adhesion
v0^2 / (2 mu g) cannot be reached on a rail whose adhesion falls with speed, so it is not the
ideal here), the energy balance of vehicles and wheelsets (brake work at the wheel + creep
work + coupler and resistance work = kinetic energy lost) and the vehicles' momentum
against the external impulse.
"""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics.physics import wheelset as wsl
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.train import TrainSimulator

P_FULL = 3.8e5


def _sim(**overrides):
    values = {'num_coaches': 3, 'initial_speed': 100 / 3.6,
              'brake_input': 'cylinder_per_coach', 'davis_a': 300.0}
    values.update(overrides)
    return TrainSimulator(SimConfig.from_dict(values))


def _stop(sim, chunk=10, t_end=200.0):
    """Brake at full pressure from t = 0 until the train stops; return the run's figures."""
    sim.set_cylinder_pressure(P_FULL)
    e0 = sim.kinetic_energy + sim.wheel_kinetic_energy
    p0 = sim.momentum
    zero_run = np.zeros(sim.n)
    longest = np.zeros(sim.n)
    x0 = sim.x[0]
    dt = chunk * sim.h
    while np.any(sim.v > 0.0) and sim.t < t_end:
        sim.advance(chunk)
        moving = sim.v > 0.0
        locked = moving & (sim.wheel_speed == 0.0)
        zero_run = np.where(locked, zero_run + dt, 0.0)
        longest = np.maximum(longest, zero_run)
    e1 = sim.kinetic_energy + sim.wheel_kinetic_energy
    return {'distance': sim.x[0] - x0, 'time': sim.t, 'longest_locked': longest,
            'energy_lost': e0 - e1, 'initial_energy': e0,
            'work': sim.work_wheel_brake + sim.work_creep + sim.work_coupler
            + sim.work_resistance - sim.work_traction - sim.work_gravity,
            'momentum_change': sim.momentum - p0, 'impulse': sim.external_impulse,
            'momentum': p0, 'sliding_time': sim.sliding_time,
            'sliding_distance': sim.sliding_distance}


def _low(mu=0.05, **overrides):
    return _sim(track_adhesion_positions=[-1.0e6], track_adhesion=[mu], **overrides)


def test_track_adhesion_mean_over_the_vehicle():
    """A vehicle half on a 0.05 section and half on dry rail sees the mean: (0.05 + 0.331)/2."""
    sim = _sim(track_adhesion_positions=[-37.5], track_adhesion=[0.05], initial_speed=0.0)
    low = sim.track_adhesion_low()      # vehicles on [-25, 0], [-50, -25], [-75, -50] m
    assert low[0] == pytest.approx(0.05, rel=1e-12)
    assert low[1] == pytest.approx(0.5 * (0.05 + wsl.DRY_ADHESION), rel=1e-12)
    assert low[2] == pytest.approx(wsl.DRY_ADHESION, rel=1e-12)
    assert sim.adhesion_available[0] == pytest.approx(0.05, rel=1e-12)   # at rest
    sim.set_track_adhesion([], [])          # live: dry everywhere again
    assert sim.track_adhesion_low() == pytest.approx(wsl.DRY_ADHESION)
    with pytest.raises(ValueError, match='track_adhesion'):
        sim.set_track_adhesion([0.0], [1.5])


def test_wheelsets_implied_and_refused_with_error_control():
    assert _low().wheelsets and _sim(wsp='builtin').wheelsets
    assert not _sim().wheelsets
    assert not _sim(track_adhesion_positions=[0.0], track_adhesion=[0.4]).wheelsets
    with pytest.raises(ConfigError, match='fixed step'):
        SimConfig.from_dict({'wsp': 'builtin', 'integration_tolerance': 1e-3})


def test_traction_limited_by_track_adhesion():
    """A locomotive's starting force on 0.05 rail: traction_adhesion x 0.05 / 0.331 x m g."""
    values = {'num_coaches': 2, 'initial_speed': 0.0, 'brake_input': 'cylinder_per_coach',
              'max_tractive_force': 1e6, 'max_power': 1e7, 'traction_build_up_time': 0.0}
    for mu, share in ((None, 0.33), (0.05, 0.33 * 0.05 / wsl.DRY_ADHESION)):
        extra = {} if mu is None else {'track_adhesion_positions': [-1e6],
                                       'track_adhesion': [mu]}
        sim = TrainSimulator(SimConfig.from_dict({**values, **extra}))
        sim.set_traction_command(1.0, 0)
        sim.advance(2)          # the first step takes the mean of 0 and the command
        assert sim.traction_force[0] == pytest.approx(share * 45000.0 * 9.81, rel=1e-3)


def test_dry_rail_emergency_no_slide_energy_momentum():
    """A correctly braked train (disc, 150 % braked mass) on dry rail: no wheel slides."""
    r = _stop(_sim(wheelsets=True, friction_material='disc', braked_mass_p=67500.0,
                   brake_radius_ratio=0.55, initial_speed=160 / 3.6))
    assert np.all(r['sliding_time'] == 0.0) and np.all(r['longest_locked'] == 0.0)
    assert abs(r['energy_lost'] - r['work']) <= 0.005 * r['initial_energy']
    assert r['momentum_change'] == pytest.approx(r['impulse'], abs=1e-9 * r['momentum'])


def test_low_adhesion_locks_without_wsp():
    r = _stop(_low())
    assert np.all(r['longest_locked'] > 10.0)               # locked for most of the stop
    assert np.all(r['sliding_time'] > 0.9 * r['time'])
    assert np.all(r['sliding_distance'] > 0.9 * r['distance'])
    assert abs(r['energy_lost'] - r['work']) <= 0.005 * r['initial_energy']
    assert r['momentum_change'] == pytest.approx(r['impulse'], abs=1e-9 * r['momentum'])


def test_low_adhesion_builtin_wsp_keeps_wheels_turning():
    """With wsp builtin no wheel at rest > 0.5 s while moving; stop within 1.3 x the ideal."""
    bare = _stop(_low())
    r = _stop(_low(wsp='builtin'))
    ideal = wsl.adhesion_limited_distance(100 / 3.6, 0.05)
    assert np.all(r['longest_locked'] <= 0.5)
    assert r['distance'] <= 1.3 * ideal
    assert r['distance'] < bare['distance']
    assert np.all(r['sliding_time'] < 0.2 * bare['sliding_time'])
    assert abs(r['energy_lost'] - r['work']) <= 0.005 * r['initial_energy']
    assert r['momentum_change'] == pytest.approx(r['impulse'], abs=1e-9 * r['momentum'])


def test_external_valves_vent_and_hold():
    """With wsp external vent empties the cylinder (dump valve's time constant), hold keeps it."""
    sim = _sim(wsp='external')
    sim.set_cylinder_pressure(P_FULL)
    sim.advance(5)
    sim.set_wsp_valve(2, 0)
    sim.set_wsp_valve(1, 1)
    sim.advance(50)                         # 0.1 s
    p = sim.cylinder_pressure
    assert p[0] == pytest.approx(P_FULL * np.exp(-0.1 / wsl.VENT_TAU), rel=1e-9)
    assert p[1] == P_FULL and p[2] == P_FULL
    with pytest.raises(ValueError, match='0 .normal., 1 .hold. or 2'):
        sim.set_wsp_valve(3, 0)
    with pytest.raises(ValueError, match='wsp external'):
        _sim(wsp='builtin').set_wsp_valve(1, 0)


def test_sliding_metrics_and_stopping_distance():
    """The run metrics take the sliding time and distance of every step and the stop."""
    from train_dynamics.physics.metrics import RunMetrics
    from train_dynamics.simulation.runner import Sample
    sim = _low()
    metrics = RunMetrics.for_run(sim.cfg, sim)
    sim.set_cylinder_pressure(P_FULL)
    metrics.sample(Sample(0, 0.0, sim, None))
    k = 0
    while np.any(sim.v > 0.0) and sim.t < 200.0:
        sim.advance(5)
        k += 5
        metrics.sample(Sample(k, sim.t, sim, None))
    flat = metrics.result()['train']
    assert flat['max_sliding_time'] == pytest.approx(float(np.max(sim.sliding_time)))
    assert flat['max_sliding_distance'] == pytest.approx(float(np.max(sim.sliding_distance)))
    assert flat['max_sliding_time'] > 0.9 * sim.t                 # locked nearly throughout
    # every vehicle slid all the way: the sliding distance is the stopping distance (within
    # the last output period and the run-out below the sliding threshold)
    assert flat['max_sliding_distance'] == pytest.approx(flat['stopping_distance'], rel=0.01)
    rows = metrics.result()['vehicles']
    assert rows[0]['sliding_time'] == pytest.approx(sim.sliding_time[0])


def test_multirate_with_wheelsets_balances():
    """
    Wheelsets with ``multirate_tolerance``: the creep force is a constant force over sub-steps.

    Low adhesion, builtin WSP, coaches of 45 and 90 t alternating (the valves cycle, the
    couplers' forces jump; equal coaches would brake alike and load no coupler): the refined
    groups (counted) keep the momentum balance to round-off and the energy balance of
    vehicles and wheelsets; the stop differs from the fixed step's by less than 1 %.
    """
    masses = [45000.0, 90000.0] * 3
    fixed = _stop(_low(wsp='builtin', masses=masses))
    sim = _low(wsp='builtin', masses=masses, multirate_tolerance=1e-4)
    r = _stop(sim)
    assert sim.integration_stats['mr_groups'] > 0
    assert abs(r['energy_lost'] - r['work']) <= 0.005 * r['initial_energy']
    assert r['momentum_change'] == pytest.approx(r['impulse'], abs=1e-9 * r['momentum'])
    assert r['distance'] == pytest.approx(fixed['distance'], rel=0.01)


@pytest.mark.parametrize('material', ['paper', 'disc'])
def test_wheelset_solve_against_bisection(material):
    """
    The kernel's Newton sub-step against the reference's 60 bisections of the same equation.

    Rolling, sliding and locking wheels (brake from 0 to 3 times the adhesion), from a
    good, a poor and a far first guess: the wheel speed within the solver's tolerance
    U_TOL (1 + v) of the root, the creep force within its residual of the creep law at that
    speed, and the backward-Euler balance J / r^2 (u1 - u0) = h (F_c - F_b) within d U_TOL
    (d its slope).
    """
    from train_dynamics.physics import friction
    from train_dynamics.physics.kernel import wheelset as kw
    code = friction.MATERIAL_CODES[material]
    law = friction.law_of(material).vector
    h, jr, load, g, blocks, rho = 0.002, 2079.0, 441450.0, 9.81, 8.0, 0.55
    for v in (0.3, 5.0, 44.4):
        mu = wsl.available_adhesion(v, 0.05 if v < 10.0 else wsl.DRY_ADHESION)
        for share in (0.0, 0.3, 0.9, 1.1, 3.0):     # brake / (mu N) at the wheel
            fb_paper = share * mu * load
            normal = fb_paper / (friction.material_friction(code, v, 1.0, g) * rho) \
                if code != friction.PAPER else 0.0

            def brake(u, fb_paper=fb_paper, normal=normal):
                return kw.wheel_brake(u, fb_paper, law, normal, blocks, rho, g)

            for u0 in (v, 0.999 * v, 0.5 * v, 0.0):
                ref = wsl.wheelset_step(u0, v, h, jr, load, mu, brake)
                for guess in (ref[0], u0, v + 1.0):
                    u1, fc, fb = kw.wheelset_solve(u0, v, h, jr, load, mu, fb_paper, law,
                                                   normal, blocks, rho, g, guess)
                    tol = kw.U_TOL * (1.0 + v)
                    f, slope = kw.creep_and_slope(v - u1, v, mu)
                    d = jr + h * load * slope
                    assert abs(u1 - ref[0]) <= 2.0 * tol, (v, share, u0, guess)
                    if u1 > 0.0:
                        assert abs(jr * (u1 - u0) - h * (fc - fb)) <= 1.01 * d * tol
                        assert abs(fc - load * f) * h <= 1.01 * d * tol
                        assert fb == pytest.approx(brake(u1), rel=1e-6)
