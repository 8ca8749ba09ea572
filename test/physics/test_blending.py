"""
Brake blending of a multiple unit (``blending: builtin``, physics/blending.py).

A four-car unit, motor - trailer - trailer - motor, on level track without resistance: the
train's deceleration is then the sum of the ED and friction forces over the sum of the
inertial masses, and every check below is a balance of those forces.
"""
import math

import numpy as np
import pytest

from train_dynamics.physics.blending import allocate_ed, ed_available, friction_make_up
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.kernel.layout import VEHICLE
from train_dynamics.physics.kernel.traction import adhesion
from train_dynamics.physics.train import TrainSimulator

UNIT = """
vehicle_types:
  mc:
    mass: 50000.0
    length: 25.0
    rotating_mass_factor: 0.08
    adhesion_coefficient: 0.15
    max_dynamic_brake_force: 60000.0
    max_dynamic_brake_power: 1200000.0
    traction_build_up_time: 1.0
    traction_adhesion: 0.3
    dynamic_brake_fade_speed: 2.0
  tc:
    mass: 40000.0
    length: 25.0
    rotating_mass_factor: 0.04
    adhesion_coefficient: 0.15
vehicles:
  - {type: mc}
  - {type: tc, count: 2}
  - {type: mc}
"""
#: inertial masses m (1 + rotating_mass_factor) [kg]: motor 54 t, trailer 41.6 t
M_MOTOR, M_TRAILER = 54000.0, 41600.0
M_TOTAL = 2 * M_MOTOR + 2 * M_TRAILER


@pytest.fixture
def unit(tmp_path):
    """Return a function making the unit's simulator with blending builtin (overrides)."""
    path = tmp_path / 'unit.yaml'
    path.write_text(UNIT)

    def make(**kw):
        params = {'consist_file': str(path), 'brake_input': 'cylinder_per_coach',
                  'blending': 'builtin', 'initial_speed': 20.0}
        params.update(kw)
        cfg = SimConfig(**params)
        cfg.check()
        return TrainSimulator(cfg)
    return make


def _deceleration(sim):
    """Return the train's deceleration from its brake forces [m/s^2] (no resistance)."""
    return (sim.bcu.ed_force().sum() + sim.brake_force.sum()) / sim.inertia.sum()


def test_allocation_by_hand():
    """ED first up to its limit, friction makes up the rest in proportion to the masses."""
    # at 25 m/s a motor car's ED is power-limited: 1.2 MW / 25 m/s = 48 kN (< 60 kN, and
    # the adhesion limit 0.3 * 0.196 / 0.331 * 490.5 kN = 87 kN)
    mass = np.array([M_MOTOR, M_TRAILER, M_TRAILER, M_MOTOR])
    avail = np.array([48000.0, 48000.0])
    a = 0.8                                    # 0.8 of full service, 1 m/s^2
    ed = allocate_ed(a, mass[[0, 3]], M_TOTAL, avail, per_car=False)
    assert ed == pytest.approx([48000.0, 48000.0])          # 152.96 kN demanded > 96 kN
    fric = friction_make_up(a, mass, ed, per_car=False)
    rest = 0.8 * M_TOTAL - 96000.0                           # 56 960 N
    assert fric == pytest.approx(rest * mass / M_TOTAL)
    assert fric[0] == pytest.approx(16087.03, abs=0.01)      # 56 960 x 54 / 191.2
    assert fric[1] == pytest.approx(12392.97, abs=0.01)
    # per car: a motor car brakes its own 43.2 kN with ED alone, a trailer 33.28 kN friction
    ed_car = allocate_ed(a, mass[[0, 3]], M_TOTAL, avail, per_car=True)
    assert ed_car == pytest.approx([43200.0, 43200.0])
    assert friction_make_up(a, mass, np.array([43200.0, 0, 0, 43200.0]), True) == \
        pytest.approx([0.0, 33280.0, 33280.0, 0.0])
    # a light demand: ED alone, shared by the motor cars as their availability
    ed = allocate_ed(0.3, mass[[0, 3]], M_TOTAL, np.array([60000.0, 30000.0]), per_car=False)
    assert ed == pytest.approx([0.3 * M_TOTAL * 2 / 3, 0.3 * M_TOTAL / 3])
    assert friction_make_up(0.3, mass, np.array([ed[0], 0, 0, ed[1]]), False) == \
        pytest.approx(np.zeros(4), abs=1e-9)


def test_ed_availability_follows_the_locomotive_law(unit):
    """ED limit at a speed: force, power and adhesion limits, linear fade-out."""
    sim = unit()
    c = sim.coach
    speeds = np.array([25.0, 10.0])
    assert ed_available(c, [0, 3], speeds) == pytest.approx([48000.0, 60000.0])
    mu = adhesion(25.0, 0.3)
    assert mu * 50000.0 * 9.81 > 48000.0
    # fade: at 1 m/s, half of min(60 kN, 1.2 MW / 1 m/s, adhesion)
    assert ed_available(c, [0, 3], np.array([1.0, 0.5])) == pytest.approx([30000.0, 15000.0])
    assert ed_available(c, [0, 3], np.array([0.0, 0.0])) == pytest.approx([0.0, 0.0])


def test_blended_brake_gives_the_demanded_deceleration_ed_first(unit):
    """At steady demand: ED at its limit at the present speed, friction the rest by mass."""
    sim = unit(initial_speed=25.0)
    sim.bcu.set_demand(0.8)
    sim.advance(1500)                       # 3 s: ramp (0.8 s at 1 m/s^3) and build-up done
    v = sim.v
    avail = ed_available(sim.coach, [0, 3])
    assert avail == pytest.approx(1.2e6 / v[[0, 3]], rel=1e-9)   # power-limited above 20 m/s
    ed = sim.bcu.ed_force()
    assert ed[[0, 3]] == pytest.approx(avail, rel=2e-3)
    assert ed[[1, 2]] == pytest.approx([0.0, 0.0])
    fb = sim.brake_force
    rest = 0.8 * M_TOTAL - ed.sum()
    mass = np.array([M_MOTOR, M_TRAILER, M_TRAILER, M_MOTOR])
    assert fb == pytest.approx(rest * mass / M_TOTAL, rel=0.02)
    assert _deceleration(sim) == pytest.approx(0.8, abs=0.01)


def test_handover_as_the_ed_fades_keeps_deceleration_and_jerk(unit):
    """ED fade-out below 2 m/s: deceleration error and jerk within the configured limits."""
    jerk_limit = 1.0
    sim = unit(initial_speed=6.0, blending_jerk_limit=jerk_limit)
    sim.bcu.set_demand(1.0)
    rows = []
    while sim.t < 20.0 and sim.v.max() > 0.0:
        sim.advance(5)
        rows.append((sim.v.mean(), sim.bcu.demanded_deceleration, _deceleration(sim),
                     sim.bcu.ed_force().sum()))
    r = np.array(rows)
    fade = (r[:, 0] < 2.0) & (r[:, 0] > 0.05)
    assert fade.sum() > 100                       # about 2 s of handover at 10 ms
    assert r[fade, 3].max() > 100000.0 and r[fade, 3].min() < 5000.0    # ED handed over
    assert np.abs(r[fade, 2] - r[fade, 1]).max() < 0.02      # 2 % of the demand
    jerk = np.abs(np.diff(r[:, 2])) / 0.01
    assert jerk[fade[1:] & fade[:-1]].max() <= jerk_limit


def test_ed_trip_friction_takes_over_within_the_response_time(unit):
    """ED lost at 3 s: the friction brake restores 95 % of the demand within 3 tau."""
    tau = 0.3
    sim = unit(friction_response_time=tau)
    sim.bcu.set_demand(1.0)
    sim.advance(1500)
    assert sim.bcu.ed_force().sum() == pytest.approx(120000.0, rel=1e-3)
    sim.bcu.set_ed_trip(True)
    t0 = sim.t
    sim.advance(1)
    assert sim.bcu.ed_force().sum() == 0.0
    taken_over = None
    while sim.t < t0 + 2.0:
        sim.advance(5)
        if sim.brake_force.sum() >= 0.95 * M_TOTAL and taken_over is None:
            taken_over = sim.t - t0
    assert taken_over is not None and taken_over <= 3 * tau + sim.bcu.period
    assert _deceleration(sim) == pytest.approx(1.0, abs=0.01)


def test_energy_balance_books_the_regenerated_energy(unit):
    """Kinetic energy lost = friction + regenerated (ED power integrated) within 0.5 %."""
    sim = unit(initial_speed=25.0)
    sim.bcu.set_demand(0.9)
    ke0 = sim.kinetic_energy
    regen = 0.0
    p_prev = 0.0
    while sim.t < 60.0 and sim.v.max() > 0.0:
        sim.advance(5)
        p = float(np.sum(sim.bcu.ed_force() * sim.v))
        regen += 0.5 * (p + p_prev) * 0.01
        p_prev = p
    lost = ke0 - sim.kinetic_energy
    assert sim.v.max() == 0.0
    assert -sim.work_traction == pytest.approx(regen, rel=5e-3)
    booked = sim.work_brake + (sim.work_coupler - sim.elastic_energy) - sim.work_traction
    assert booked == pytest.approx(lost, rel=5e-3)
    assert 0.3 < regen / lost < 0.9        # both brakes did a real share


def test_emergency_bypasses_the_blending(unit):
    """Emergency: every cylinder to p_max, ED off, whatever the demand; no jerk ramp."""
    sim = unit()
    sim.bcu.set_demand(0.2)
    sim.advance(1000)
    sim.bcu.set_emergency(True)
    sim.advance(1500)
    assert sim.cylinder_pressure == pytest.approx(np.full(4, 380000.0), rel=1e-3)
    assert sim.bcu.ed_force() == pytest.approx(np.zeros(4))
    # eq. (13): mu_a m g at p_max
    assert sim.brake_force == pytest.approx(0.15 * 9.81 * np.array([5e4, 4e4, 4e4, 5e4]),
                                            rel=1e-3)


def test_release_gives_the_traction_commands_back(unit):
    """Demand back to 0: ED and friction released, the unit stops writing commands."""
    sim = unit()
    sim.bcu.set_demand(0.5)
    sim.advance(1000)
    sim.bcu.set_demand(0.0)
    sim.advance(2000)
    assert sim.brake_force.sum() < 1.0 and sim.bcu.ed_force().sum() == 0.0
    sim.advance(10)
    assert not sim.bcu._braking


def test_blending_configuration_errors(tmp_path):
    """Blending builtin needs the cylinders; schedules need builtin; a fraction is <= 1."""
    with pytest.raises(ConfigError, match='cylinder_per_coach'):
        SimConfig(blending='builtin').check()
    with pytest.raises(ConfigError, match='need blending builtin'):
        SimConfig(demand_schedule_times=[1.0], demand_schedule_values=[0.5]).check()
    with pytest.raises(ConfigError, match='at most 1'):
        SimConfig(blending='builtin', brake_input='cylinder_per_coach',
                  demand_schedule_times=[1.0], demand_schedule_values=[1.5]).check()
    assert SimConfig().blending == 'none' and math.isfinite(SimConfig().blending_period)


def test_track_brake_shortens_the_stop_by_its_impulse(unit, tmp_path):
    """
    Emergency with constant track brake forces: closed-form stopping distance and momentum.

    Friction at once (tau 1 ms) and constant, a_f = mu_a g m / M per car; the track brakes
    (F_T per motor car, constant: v_h huge) from the delay d on: a = a_f + 2 F_T / M. Then
    s = v0 d - a_f d^2 / 2 + v(d)^2 / (2 a), v(d) = v0 - a_f d; without them v0^2 / (2 a_f).
    """
    v0, delay, f_t = 20.0, 0.5, 30000.0
    text = UNIT.replace('rotating_mass_factor: 0.08', 'rotating_mass_factor: 0.0').replace(
        'rotating_mass_factor: 0.04', 'rotating_mass_factor: 0.0').replace(
        'dynamic_brake_fade_speed: 2.0', 'dynamic_brake_fade_speed: 2.0\n'
        f'    track_brake_force: {f_t}\n    track_brake_half_speed: 1.0e9')
    (tmp_path / 'tb.yaml').write_text(text)
    mass = np.array([5e4, 4e4, 4e4, 5e4])
    a_f = 0.15 * 9.81                      # every car: mu_a m g over m
    a = a_f + 2 * f_t / mass.sum()
    stops = {}
    for on in (False, True):
        sim = unit(consist_file=str(tmp_path / 'tb.yaml'), initial_speed=v0,
                   friction_response_time=1e-3, track_brake_delay=delay)
        if not on:
            sim.bcu.track.cars = np.array([], dtype=int)
        sim.bcu.set_emergency(True)
        p0 = sim.momentum
        while sim.v.max() > 0.0 and sim.t < 30.0:
            sim.advance(1)
        stops[on] = (sim.x.mean(), sim.t)
        if on:
            # momentum: friction impulse sum(mu_a m g) t_stop + the track brakes' own
            friction_impulse = 0.15 * 9.81 * mass.sum() * sim.t
            assert sim.bcu.track.impulse == pytest.approx(2 * f_t * (sim.t - delay), rel=2e-3)
            assert p0 - sim.momentum == pytest.approx(
                friction_impulse + sim.bcu.track.impulse, rel=2e-3)
            assert -sim.external_impulse == pytest.approx(p0, rel=1e-6)
            assert sim.bcu.track.work == pytest.approx(sim.work_resistance, rel=2e-3)
    assert stops[False][0] == pytest.approx(v0 ** 2 / (2 * a_f), rel=2e-3)
    vd = v0 - a_f * delay
    closed = v0 * delay - a_f * delay ** 2 / 2 + vd ** 2 / (2 * a)
    assert stops[True][0] == pytest.approx(closed, rel=2e-3)
    assert stops[True][0] < 0.9 * stops[False][0]


def test_eddy_current_brake_follows_its_curve_and_books_its_work(unit, tmp_path):
    """Eddy-current brakes in an emergency: F(v, g) of each car, energy balance with them."""
    f_e, v_c, gap = 20000.0, 15.0, 0.01
    text = UNIT.replace('dynamic_brake_fade_speed: 2.0', 'dynamic_brake_fade_speed: 2.0\n'
                        f'    eddy_brake_force: {f_e}\n    eddy_brake_critical_speed: {v_c}\n'
                        f'    eddy_brake_air_gap: {gap}')
    (tmp_path / 'eddy.yaml').write_text(text)
    sim = unit(consist_file=str(tmp_path / 'eddy.yaml'), initial_speed=30.0,
               track_brake_delay=0.2)
    ke0 = sim.kinetic_energy
    sim.bcu.set_emergency(True)
    sim.advance(95)                            # 0.19 s: not yet
    assert sim.bcu.track.force.sum() == 0.0
    sim.advance(1005)
    v = sim.v[0]
    r = v / v_c
    # by hand: (7 / 10)^2 of the force at v_c, times 2 r / (1 + r^2) at the motor car's speed
    expected = f_e * 0.49 * 2 * r / (1 + r * r)
    assert sim.bcu.track.force[0] == pytest.approx(expected, rel=1e-2)
    assert sim.bcu.track.force[1] == 0.0                       # trailers carry none
    while sim.v.max() > 0.0 and sim.t < 40.0:
        sim.advance(50)
    assert sim.bcu.track.force.sum() == 0.0                    # 0 at rest
    booked = sim.work_brake + sim.work_resistance + sim.work_coupler - sim.elastic_energy \
        - sim.work_traction
    assert booked == pytest.approx(ke0, rel=5e-3)
    assert sim.bcu.track.work == pytest.approx(sim.work_resistance, rel=1e-2)
    assert sim.bcu.track.work > 0.02 * ke0


def test_reset_releases_the_track_brakes_and_restarts_the_unit(unit, tmp_path):
    """A reset mid-emergency: Davis A back to the car's own, the unit released at t = 0."""
    text = UNIT.replace('dynamic_brake_fade_speed: 2.0', 'dynamic_brake_fade_speed: 2.0\n'
                        '    track_brake_force: 30000.0\n    davis_a: 500.0')
    (tmp_path / 'tb.yaml').write_text(text)
    sim = unit(consist_file=str(tmp_path / 'tb.yaml'))
    v0 = sim.v.copy()
    sim.bcu.set_emergency(True)
    sim.advance(1000)
    assert sim.bcu.track.force[0] > 0.0
    sim.reset()
    assert sim.t == 0.0 and np.all(sim.v == v0)
    assert sim.coach[VEHICLE.DAVIS_A, 0] == 500.0
    assert not sim.bcu.emergency and sim.bcu.track.force.sum() == 0.0
    sim.advance(500)
    assert sim.brake_force.sum() == 0.0 and sim.bcu.ed_force().sum() == 0.0


def test_track_brake_command_applies_the_track_brakes_without_the_emergency(unit, tmp_path):
    """
    ``track_brake/command`` (a row of the input table): the track brakes alone, then released.

    Applied at t = 1 s, acting from 1 s + ``track_brake_delay`` d with F_T per motor car
    (constant: v_h huge), released at 3 s, the force booked until the brake control unit's
    next cycle (its cycle at 3 s ran before the command): their impulse is
    2 F_T (3 + ``blending_period`` - 1 - d); no demand, no emergency, no friction brake.
    """
    from train_dynamics.simulation.runner import CommandEvent, InputSchedule, run_simulation
    f_t, delay = 30000.0, 0.5
    (tmp_path / 'tb.yaml').write_text(UNIT.replace(
        'dynamic_brake_fade_speed: 2.0', 'dynamic_brake_fade_speed: 2.0\n'
        f'    track_brake_force: {f_t}\n    track_brake_half_speed: 1.0e9'))
    cfg = unit(consist_file=str(tmp_path / 'tb.yaml'), track_brake_delay=delay).cfg
    h = cfg.integration_step
    events = [CommandEvent.at('track_brake', None, 1.0, 1_000_000_000, h),
              CommandEvent.at('track_brake', None, 0.0, 3_000_000_000, h)]
    sim = run_simulation(cfg, 4.0, InputSchedule(cfg.brake_input, commands=events),
                         on_sample=lambda s: None)
    assert sim.fault is None and not sim.bcu.emergency
    held = 3.0 + cfg.blending_period - 1.0 - delay
    assert sim.bcu.track.impulse == pytest.approx(2 * f_t * held, rel=1e-6)
    assert np.all(sim.bcu.track.force == 0.0) and np.all(sim.brake_force == 0.0)
