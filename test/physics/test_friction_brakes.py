"""Friction materials, EN 14531-1 force chain, braked mass, wheel slide, slide protection."""
import math

import numpy as np
import pytest

from train_dynamics.physics import friction as fr
from train_dynamics.physics import wheelset as ws

G = 9.81


def test_force_chain_worked_example():
    # Tread-braked wagon worked by hand with the EN 14531-1 formulae: a 10" cylinder
    # (d = 254 mm, A = 0.050671 m^2) at 3.8 bar, cylinder efficiency 0.95, return spring
    # 1500 N; rigging ratio 8.5, efficiency 0.83; 8 cast-iron blocks; at 60 km/h.
    area = math.pi * 0.254 ** 2 / 4.0
    piston = 3.8e5 * area * 0.95 - 1500.0                  # 18292.2 - 1500 = 16792.2 N
    assert piston == pytest.approx(16792.2, abs=0.5)
    normal = fr.chain_normal_force(3.8e5, area, 1500.0, 8.5, 0.83, cylinders=1,
                                   cylinder_efficiency=0.95)
    assert normal == pytest.approx(16792.2 * 8.5 * 0.83, rel=1e-5)      # 118 469 N
    block = normal / 8                                                   # 14 809 N = 1.5096 t
    k = block / (1000 * G)
    mu = 0.6 * (16 * k + 100) / (80 * k + 100) * (60 + 100) / (5 * 60 + 100)
    # 0.6 (16 * 1.5096 + 100) / (80 * 1.5096 + 100) = 0.33742; * (160 / 400) = 0.13497
    assert mu == pytest.approx(0.13497, abs=5e-5)
    force = fr.retarding_force(fr.CAST_IRON, 60 / 3.6, normal, 8)
    assert force == pytest.approx(mu * normal, rel=1e-12)
    assert force == pytest.approx(15_990.0, rel=1e-3)
    # below the spring's pressure the chain gives nothing
    assert fr.chain_normal_force(1500.0 / area / 2, area, 1500.0, 8.5, 0.83) == 0.0


def _deceleration(material, kmh, normal=120_000.0, blocks=8, mass=60_000.0):
    return fr.retarding_force(material, kmh / 3.6, normal, blocks) / mass


def test_cast_iron_falls_with_speed_disc_nearly_constant():
    ratio = _deceleration(fr.CAST_IRON, 10) / _deceleration(fr.CAST_IRON, 100)
    assert 1.8 <= ratio <= 2.6
    assert ratio == pytest.approx((110 / 150) / (200 / 600), rel=1e-12)
    disc = _deceleration(fr.DISC, 10) / _deceleration(fr.DISC, 100)
    assert abs(disc - 1.0) <= 0.15
    for material in (fr.COMPOSITE_K, fr.COMPOSITE_LL):
        assert abs(_deceleration(material, 10) / _deceleration(material, 100) - 1.0) <= 0.3


@pytest.mark.parametrize('material, braked_mass, blocks', [
    (fr.CAST_IRON, 50_000.0, 8), (fr.DISC, 75_000.0, 16), (fr.COMPOSITE_K, 60_000.0, 8)])
def test_braked_mass_reproduces_braked_weight_percentage(material, braked_mass, blocks):
    mass = 50_000.0
    tau = 1.5                          # first-order fill: equivalent response time tau
    test = ws.BrakeTest(mass=mass, v0=120 / 3.6, material=material, blocks=blocks,
                        fill_tau=tau, h=0.01)
    rotating = test.inertia / test.radius ** 2
    test.normal_full = fr.braked_mass_normal_force(braked_mass, mass, material, blocks, tau,
                                                   inertia=rotating)
    result = test.run()
    assert result['longest_locked'] == 0.0
    lam = fr.minden_percentage(120 / 3.6, result['distance'])
    assert lam == pytest.approx(100 * braked_mass / mass, rel=0.03)


def test_load_weighing():
    assert fr.load_weighed_force(30e3, 25e3, 90e3, 50e3, 150e3, changeover_mass=50e3) == 50e3
    assert fr.load_weighed_force(60e3, 25e3, 90e3, 50e3, 150e3, changeover_mass=50e3) == 150e3
    assert fr.load_weighed_force(57.5e3, 25e3, 90e3, 50e3, 150e3) == pytest.approx(100e3)
    assert fr.load_weighed_force(120e3, 25e3, 90e3, 50e3, 150e3) == 150e3


def test_creep_law_saturates_and_falls():
    mu = 0.05
    assert ws.creep_coefficient(0.0, 20.0, mu) == 0.0
    peak = max(ws.creep_coefficient(20.0 * k / 1000, 20.0, mu) for k in range(1, 50))
    assert 0.95 * mu < peak <= mu
    assert ws.creep_coefficient(20.0, 20.0, mu) == pytest.approx(
        mu * (0.6 * math.exp(-0.6 * 20.0) + 0.4), rel=1e-9)          # locked: sliding friction
    assert ws.available_adhesion(100 / 3.6, ws.DRY_ADHESION) == pytest.approx(
        0.161 + 7.5 / 144, rel=1e-12)


def _emergency(mu_low, wsp, v0=100 / 3.6):
    return ws.BrakeTest(mu_low=mu_low, wsp=wsp, v0=v0, h=0.005).run()


def test_dry_rail_no_slide_and_energy_momentum():
    r = _emergency(ws.DRY_ADHESION, 'none')
    assert r['sliding_time'] == 0.0 and r['longest_locked'] == 0.0
    assert r['v_end'] < 0.05
    balance = r['brake_work'] + r['creep_work'] - r['energy_drop']
    assert abs(balance) <= 0.005 * r['initial_energy']
    assert abs(balance) <= 1e-12 * r['initial_energy']       # exact by construction
    assert r['impulse'] == pytest.approx(r['momentum_drop'], rel=1e-12)


def test_low_adhesion_locks_without_wsp_not_with_builtin():
    mu = 0.05
    ideal = ws.adhesion_limited_distance(100 / 3.6, mu)
    bare = _emergency(mu, 'none')
    assert bare['longest_locked'] > 10.0                    # locked for most of the stop
    assert bare['creep_work'] > 0.5 * bare['initial_energy']     # the rail, not the brake
    protected = _emergency(mu, 'builtin')
    assert protected['longest_locked'] <= 0.5
    assert protected['distance'] <= 1.3 * ideal
    assert protected['distance'] < bare['distance']
    for r in (bare, protected):
        assert abs(r['brake_work'] + r['creep_work'] - r['energy_drop']) \
            <= 0.005 * r['initial_energy']
        assert r['impulse'] == pytest.approx(r['momentum_drop'], rel=1e-12)


# -- the train: friction materials in the kernel --------------------------------------------

def _train(speed_kmh, **overrides):
    from train_dynamics.physics.config import SimConfig
    from train_dynamics.physics.train import TrainSimulator
    values = {'num_coaches': 3, 'initial_speed': speed_kmh / 3.6,
              'brake_input': 'cylinder_per_coach', 'brake_model': 'empirical'}
    values.update(overrides)
    return TrainSimulator(SimConfig.from_dict(values))


def _train_deceleration(speed_kmh, **overrides):
    """Deceleration [m/s^2] of a train at full cylinder pressure, measured over 0.2 s."""
    sim = _train(speed_kmh, **overrides)
    sim.set_cylinder_pressure(3.8e5)
    sim.advance_to(0.05)
    v0, t0 = sim.v.mean(), sim.t
    sim.advance_to(0.25)
    return (v0 - sim.v.mean()) / (sim.t - t0)


def test_train_cast_iron_and_disc_against_speed():
    chain = {'brake_cylinder_area': 0.0507, 'rigging_ratio': 8.0, 'brake_blocks': 8.0}
    iron = _train_deceleration(10, friction_material='cast_iron', **chain) \
        / _train_deceleration(100, friction_material='cast_iron', **chain)
    assert 1.8 <= iron <= 2.6
    disc = {'friction_material': 'disc', 'braked_mass_p': 60_000.0, 'brake_radius_ratio': 0.55,
            'brake_blocks': 16.0}
    ratio = _train_deceleration(10, **disc) / _train_deceleration(100, **disc)
    assert abs(ratio - 1.0) <= 0.15
    # the chain by hand: 3.8 bar * 0.0507 m^2 * 0.95 * 8 * 0.83 = 121 543 N on 8 blocks
    sim = _train(100, friction_material='cast_iron', **chain)
    sim.set_cylinder_pressure(3.8e5)
    sim.advance_to(0.01)
    normal = 3.8e5 * 0.0507 * 0.95 * 8.0 * 0.83
    expected = fr.retarding_force(fr.CAST_IRON, sim.v[0], normal, 8)
    assert sim.brake_force[0] == pytest.approx(expected, rel=2e-3)


def test_train_friction_material_needs_a_force_level():
    from train_dynamics.physics.config import ConfigError
    with pytest.raises(ConfigError, match=r'vehicle 1 \(coach\).*brake_cylinder_area.*'
                                          r'rigging_ratio.*braked_mass_p'):
        _train(100, friction_material='composite_k')


def test_train_paper_default_unchanged():
    assert _train_deceleration(100) == pytest.approx(_train_deceleration(100, braked_mass_p=1.0))


@pytest.mark.parametrize('changeover, factor', [(0.0, 0.4 + 0.6 * 5 / 65), (50_000.0, 0.4),
                                                (28_000.0, 1.0)])
def test_train_load_weighing_scales_the_piston_pressure(changeover, factor):
    chain = {'brake_cylinder_area': 0.0507, 'rigging_ratio': 8.0, 'brake_spring_force': 1500.0,
             'friction_material': 'composite_k', 'coach_mass': 30_000.0,
             'load_empty_mass': 25_000.0, 'load_full_mass': 90_000.0, 'load_empty_ratio': 0.4,
             'load_changeover_mass': changeover}
    sim = _train(50, **chain)
    sim.set_cylinder_pressure(3.8e5)
    sim.advance_to(0.01)
    lever = 8.0 * 0.83
    normal = 3.8e5 * factor * 0.0507 * 0.95 * lever - 1500.0 * lever
    expected = fr.retarding_force(fr.COMPOSITE_K, sim.v[0], normal, 8)
    assert sim.brake_force[0] == pytest.approx(expected, rel=2e-3)


@pytest.mark.parametrize('tolerance', [0.0, 1e-3])
def test_train_cast_iron_stop_energy_and_momentum(tolerance):
    """A cast-iron train stops: energy within 0.5 %, momentum to round-off."""
    sim = _train(100, num_coaches=4, integration_tolerance=tolerance,
                 friction_material='cast_iron', brake_cylinder_area=0.0507, rigging_ratio=8.0,
                 brake_spring_force=1500.0, davis_a=500.0)     # resistance: impulses booked
    ke0, p0 = sim.kinetic_energy, sim.momentum
    sim.set_cylinder_pressure(3.8e5)
    sim.advance_to(150.0)
    assert np.all(sim.v == 0.0)                     # stopped, held by the brakes
    lost = ke0 - sim.kinetic_energy
    dissipated = sim.work_brake + sim.work_resistance + (sim.work_coupler - sim.elastic_energy)
    assert abs(dissipated - lost) < 0.005 * lost
    assert sim.momentum - p0 == pytest.approx(sim.external_impulse, abs=1e-9 * abs(p0))
