"""
Per-bogie wheelsets (``bogie_wheelsets``): two lumped wheelsets per vehicle, one per bogie.

What is checked, by hand or against the one-wheelset model:

- two equal bogies are the vehicle's lumped wheelset halved: the same run, bit for bit;
- a slide on one bogie only (the trailing bogie on a rail the leading one has cleaned,
  ``rail_conditioning`` 1): the leading bogie locks and slides with Polach's sliding friction,
  the trailing one rolls and passes its brake's force, 0.1 m g / 2 (paper brake, mu_a 0.1);
- energy (kinetic energy of vehicles and of all wheelsets lost = brake work at the wheels +
  creep work + coupler and resistance work) and momentum (its change = the external impulse)
  with two wheelsets per car and the builtin WSP on each bogie;
- each bogie's valves act on its own cylinder whatever drives the vehicle's brake (every
  ``brake_input``, the pneumatic and EP brakes, the builtin brake control unit): vented, its
  pressure falls as exp(-t / VENT_TAU), held it stays, released it refills toward the
  source with REFILL_TAU, while the other bogie follows the source.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from train_dynamics.physics import wheelset as wsl
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.kernel.creep import creep_coefficient, REFILL_TAU
from train_dynamics.physics.train import TrainSimulator

P_FULL = 3.8e5
V0 = 60 / 3.6
G = 9.81
M = 45000.0


def _sim(**overrides) -> TrainSimulator:
    values = {'num_coaches': 3, 'initial_speed': V0, 'davis_a': 300.0,
              'brake_input': 'cylinder_per_coach',
              'track_adhesion_positions': [-1.0e6], 'track_adhesion': [0.05]}
    values.update(overrides)
    return TrainSimulator(SimConfig.from_dict(values))


def _pairs(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split a per-wheelset array (bogie 1, bogie 2 of each vehicle in turn) by bogie."""
    return a[0::2], a[1::2]


@pytest.mark.parametrize('wsp', ['none', 'builtin'])
def test_two_equal_bogies_run_as_the_vehicles_lumped_wheelset_bit_for_bit(wsp):
    """Every mass and force halved (exact in binary): the same wheel speeds, the same train."""
    one = _sim(wsp=wsp)
    two = _sim(wsp=wsp, bogie_wheelsets=True)
    assert two.wheelsets and two.bogies and not one.bogies
    for sim in (one, two):
        sim.set_cylinder_pressure(P_FULL)
    # the builtin WSP: compared while moving (at rest a vented cylinder holds the vehicle
    # through the bogies' own pressures, the lumped one through its trapezoid)
    v_end = 0.0 if wsp == 'none' else 1.0
    while one.v.min() > v_end and one.t < 200.0:
        one.advance(10)
        two.advance(10)
        np.testing.assert_array_equal(one.x, two.x)
        np.testing.assert_array_equal(one.v, two.v)
        b1, b2 = _pairs(two.wheelset_speeds)
        np.testing.assert_array_equal(b1, one.wheel_speed)
        np.testing.assert_array_equal(b2, one.wheel_speed)
        c1, c2 = _pairs(two.wheelset_creep_forces)
        np.testing.assert_array_equal(c1 + c2, one.creep_force)
    assert one.t > 20.0
    np.testing.assert_array_equal(two.sliding_time, one.sliding_time)
    assert two.work_creep == one.work_creep
    assert two.wheel_kinetic_energy == pytest.approx(one.wheel_kinetic_energy, rel=1e-15)


def test_a_slide_on_the_leading_bogie_only():
    """
    0.05 adhesion, the trailing bogie on a cleaned rail: bogie 1 locks, bogie 2 rolls.

    Paper brake mu_a = 0.1: bogie 1's brake (0.05 m g) is above what its rail carries
    (mu(v) m g / 2 <= 0.025 m g), so it locks and its creep force is Polach's at a slip of
    the whole speed, N/2 f(v, v); bogie 2 on dry rail (mu(16.7 m/s) = 0.23) rolls, its creep
    force its brake's 0.05 m g less what turns its wheels down, J/(2 r^2) a (2.6 %).
    """
    sim = _sim(bogie_wheelsets=True, rail_conditioning=1.0, initial_speed=V0)
    sim.set_cylinder_pressure(P_FULL)
    sim.advance(2500)                   # 5 s
    v = sim.v
    u1, u2 = _pairs(sim.wheelset_speeds)
    f1, f2 = _pairs(sim.wheelset_creep_forces)
    assert np.all(v > 10.0)
    np.testing.assert_array_equal(u1, 0.0)                    # bogie 1 locked
    np.testing.assert_allclose(u2, v, rtol=2e-3)               # bogie 2 rolls
    for i in range(sim.n):
        mu = wsl.available_adhesion(v[i], 0.05)
        # at the step's start speed, v + h a: 4e-5 relative above the end's
        np.testing.assert_allclose(f1[i], 0.5 * M * G * creep_coefficient(v[i], v[i], mu),
                                   rtol=1e-4)
    # bogie 2 rolls with its vehicle: F_c = F_b - J/(2 r^2) a, a = (f1 + f2 + davis_a) / m
    # (equal vehicles: no coupler force), so f2 (1 + jr / m) = F_b - jr (f1 + davis_a) / m
    jr = 0.5 * 440.0 / 0.46 ** 2
    want = (0.5 * 0.1 * M * G - jr * (f1 + 300.0) / M) / (1.0 + jr / M)
    np.testing.assert_allclose(f2, want, rtol=1e-3)
    a1, a2 = _pairs(sim.wheelset_adhesion_available)     # at the last step's start speed
    np.testing.assert_allclose(a2, [wsl.available_adhesion(s, wsl.DRY_ADHESION) for s in v],
                               rtol=1e-4)
    np.testing.assert_allclose(a1, [wsl.available_adhesion(s, 0.05) for s in v], rtol=1e-4)
    assert np.all(sim.sliding_time > 4.5)             # the vehicle slides on bogie 1
    # without the conditioning both bogies slide: the stop is longer
    plain = _sim(bogie_wheelsets=True, initial_speed=V0)
    plain.set_cylinder_pressure(P_FULL)
    plain.advance(2500)
    assert np.all(_pairs(plain.wheelset_speeds)[1] == 0.0)
    assert plain.x[0] > sim.x[0] + 1.0


def _stop(sim: TrainSimulator) -> dict:
    sim.set_cylinder_pressure(P_FULL)
    e0 = sim.kinetic_energy + sim.wheel_kinetic_energy
    p0 = sim.momentum
    resting = np.zeros(2 * sim.n)
    longest = np.zeros(2 * sim.n)
    while np.any(sim.v > 0.0) and sim.t < 200.0:
        sim.advance(10)
        moving = np.repeat(sim.v > 0.0, 2)
        resting = np.where(moving & (sim.wheelset_speeds == 0.0), resting + 10 * sim.h, 0.0)
        longest = np.maximum(longest, resting)
    e1 = sim.kinetic_energy + sim.wheel_kinetic_energy
    work = (sim.work_wheel_brake + sim.work_creep + sim.work_coupler + sim.work_resistance
            - sim.work_traction - sim.work_gravity)
    return {'e0': e0, 'lost': e0 - e1, 'work': work, 'p0': p0,
            'dp': sim.momentum - p0, 'impulse': sim.external_impulse, 'longest': longest}


def test_energy_and_momentum_balance_with_two_wheelsets_per_car():
    """Builtin WSP per bogie, half-conditioned rail: the balances close to round-off."""
    sim = _sim(bogie_wheelsets=True, wsp='builtin', rail_conditioning=0.5)
    r = _stop(sim)
    assert np.all(sim.v == 0.0)
    assert r['work'] == pytest.approx(r['lost'], abs=1e-6 * r['e0'])
    assert r['dp'] == pytest.approx(r['impulse'], abs=1e-9 * r['p0'])
    assert sim.work_creep > 0.0 and sim.work_wheel_brake > 0.0
    assert np.all(r['longest'] <= 0.5), r['longest']       # no bogie rests while moving


def test_builtin_wsp_acts_on_the_slipping_bogie_only():
    """A clean rail for the trailing bogie: its valves stay normal, the leading one's cycle."""
    sim = _sim(bogie_wheelsets=True, wsp='builtin', rail_conditioning=1.0)
    sim.set_cylinder_pressure(P_FULL)
    seen1, seen2 = set(), set()
    low1 = np.inf
    for _ in range(400):                    # 8 s
        sim.advance(10)
        k1, k2 = _pairs(sim.wheelset_valves)
        seen1.update(k1.tolist())
        seen2.update(k2.tolist())
        p1, _ = _pairs(sim.bogie_cylinder_pressures)
        low1 = min(low1, p1.min())
    assert seen2 == {wsl.NORMAL}
    assert wsl.VENT in seen1
    assert low1 < 0.6 * P_FULL
    _, p2 = _pairs(sim.bogie_cylinder_pressures)
    np.testing.assert_array_equal(p2, sim.cylinder_pressure)     # the source's pressure


#: brake_input (and brake model, blending) -> (overrides, the full-brake command)
MODES = {
    'cylinder_per_coach': ({'brake_input': 'cylinder_per_coach'},
                           lambda sim: sim.set_cylinder_pressure(P_FULL)),
    'pipe_per_coach': ({'brake_input': 'pipe_per_coach'},
                       lambda sim: sim.set_pipe_pressure(np.zeros(sim.n))),
    'pipe_head': ({'brake_input': 'pipe_head'}, lambda sim: sim.set_head_pipe_pressure(0.0)),
    'pneumatic_pipe_head': ({'brake_input': 'pipe_head', 'brake_model': 'pneumatic'},
                            lambda sim: sim.set_head_pipe_pressure(0.0)),
    'ep': ({'brake_input': 'pipe_head', 'brake_model': 'pneumatic', 'brake_system': 'ep'},
           lambda sim: sim.set_ep_command(1.0)),
    'blending_builtin': ({'brake_input': 'cylinder_per_coach', 'blending': 'builtin'},
                         lambda sim: sim.bcu.set_demand(1.0)),
}


@pytest.mark.parametrize('mode', sorted(MODES))
def test_external_wsp_vents_holds_and_refills_one_bogie_whatever_drives_the_brake(mode):
    """
    Vehicle 2, bogie 2 vented 0.3 s, held 0.2 s, released: its cylinder only.

    Dry rail, no slide. Vent: p exp(-0.3 / VENT_TAU) (= 0.135 p); hold: unchanged; released:
    toward the source (steady by then) as 1 - exp(-t / REFILL_TAU). Bogie 1 of vehicle 2
    and both bogies of the others are the source's pressure throughout.
    """
    overrides, command = MODES[mode]
    values = {'num_coaches': 3, 'initial_speed': 30.0, 'wsp': 'external',
              'bogie_wheelsets': True, **overrides}
    sim = TrainSimulator(SimConfig.from_dict(values))
    command(sim)
    sim.advance(5000)                       # 10 s: every brake applied and steady
    source = sim.cylinder_pressure
    assert source[1] > 0.5 * sim.cfg.max_cylinder_pressure
    p0 = sim.bogie_cylinder_pressures[3]
    assert p0 == source[1]
    sim.set_wsp_valve(wsl.VENT, 1, 2)
    sim.advance(150)                        # 0.3 s
    p = sim.bogie_cylinder_pressures
    assert p[3] == pytest.approx(p0 * math.exp(-0.3 / wsl.VENT_TAU), rel=1e-9)
    others = np.delete(p, 3)
    np.testing.assert_array_equal(others, np.repeat(sim.cylinder_pressure, 2)[[0, 1, 2, 4, 5]])
    assert sim.wheelset_valves.tolist() == [0, 0, 0, wsl.VENT, 0, 0]
    f1, f2 = _pairs(sim.wheelset_creep_forces)
    assert f2[1] < 0.25 * f1[1]             # its brake is off, the other bogie's on
    held = p[3]
    sim.set_wsp_valve(wsl.HOLD, 1, 2)
    sim.advance(100)
    assert sim.bogie_cylinder_pressures[3] == held
    sim.set_wsp_valve(wsl.NORMAL, 1, 2)
    sim.advance(250)                        # 0.5 s
    src = sim.cylinder_pressure[1]
    want = src - (src - held) * math.exp(-0.5 / REFILL_TAU)
    assert sim.bogie_cylinder_pressures[3] == pytest.approx(want, rel=2e-3)


def test_a_vehicle_valve_command_sets_both_bogies_and_bad_bogies_are_refused():
    sim = _sim(wsp='external', bogie_wheelsets=True)
    sim.set_wsp_valve(wsl.VENT, 0)
    sim.advance(1)
    assert sim.wheelset_valves.tolist()[:2] == [wsl.VENT, wsl.VENT]
    with pytest.raises(ValueError, match='bogie'):
        sim.set_wsp_valve(wsl.VENT, 0, 3)
    with pytest.raises(ValueError, match='bogie'):
        _sim(wsp='external').set_wsp_valve(wsl.VENT, 0, 1)
    with pytest.raises(ConfigError, match='fixed step'):
        SimConfig.from_dict({'bogie_wheelsets': True, 'integration_tolerance': 1e-3})
