"""Real trains in the model: gradients, resistance, traction, free play, blocking."""
import numpy as np
import pytest

from train_dynamics.physics import couplers
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel.layout import COUPLER
from train_dynamics.physics.resistance import coast_down_speed
from train_dynamics.physics.train import TrainSimulator

G = 9.81


def sim_of(**params) -> TrainSimulator:
    """Return a simulator of ``params`` (brakes released: the head pipe stays at 5 bar)."""
    return TrainSimulator(SimConfig.from_dict(params))


def write_consist(tmp_path, text):
    path = tmp_path / 'train.yaml'
    path.write_text(text)
    return str(path)


@pytest.mark.parametrize('rmf', [0.0, 0.1])
def test_free_rolling_train_on_a_gradient_accelerates_at_g_G_over_1_plus_rmf(rmf):
    sim = sim_of(num_coaches=5, initial_speed=20.0, rotating_mass_factor=rmf,
                 track_gradient_positions=[-1.0e6], track_gradients=[10.0])
    sim.advance_to(10.0)
    expected = -G * 10.0 / 1000.0 / (1.0 + rmf)
    np.testing.assert_allclose((sim.v - 20.0) / 10.0, expected, rtol=1e-9)
    assert np.max(np.abs(sim.coupler_force)) < 1e-3        # no in-train force from gravity
    assert sim.gradient_force == pytest.approx(np.full(5, -45000.0 * G * 0.01))


def test_davis_coast_down_matches_the_closed_form():
    a, b, c, rmf = 1000.0, 40.0, 5.0, 0.06
    sim = sim_of(num_coaches=3, initial_speed=30.0, davis_a=a, davis_b=b, davis_c=c,
                 rotating_mass_factor=rmf)
    m_eq = 45000.0 * (1.0 + rmf)
    for t in (50.0, 200.0, 400.0, 700.0):
        sim.advance_to(t)
        expected = coast_down_speed(t, 30.0, m_eq, a, b, c)
        np.testing.assert_allclose(sim.v, expected, rtol=1e-6, atol=1e-6)
    assert np.all(sim.v == 0.0) and np.all(sim.held)       # stopped, held by A
    x_stop = sim.x.copy()
    sim.advance_to(720.0)
    np.testing.assert_array_equal(sim.x, x_stop)           # the resistance never pushes


def test_vehicle_at_rest_on_a_gradient_is_held_by_its_brake():
    common = {'num_coaches': 3, 'initial_speed': 0.0, 'brake_input': 'cylinder_per_coach',
              'track_gradient_positions': [-1.0e6], 'track_gradients': [-8.0]}
    sim = sim_of(**common)
    sim.set_cylinder_pressure(np.full(3, 380000.0))
    sim.advance_to(20.0)
    assert np.all(sim.x == 0.0) and np.all(sim.held)
    # released, it rolls downhill (forward on a falling gradient)
    sim = sim_of(**common)
    sim.advance_to(5.0)
    assert np.all(sim.v > 0.0) and sim.v[0] == pytest.approx(G * 8e-3 * 5.0, rel=1e-6)
    # the static resistance alone holds it when it exceeds the downhill force m g G
    sim = sim_of(davis_a=45000.0 * G * 8e-3 * 1.01, **common)
    sim.advance_to(5.0)
    assert np.all(sim.x == 0.0)


MIXED = """
vehicles:
  - {type: heavy_freight_locomotive, traction_build_up_time: 1.0}
  - {type: freight_wagon_loaded, count: 3}
  - {type: freight_wagon_empty, count: 2, draw_gear_slack: 0.01, buffer_slack: 0.01}
  - {type: freight_wagon_loaded, count: 2}
"""


def mixed_sim(tmp_path, **params) -> TrainSimulator:
    """Return a locomotive and 7 wagons on a line with a hump, a sag and a curve."""
    base = {'consist_file': write_consist(tmp_path, MIXED), 'initial_speed': 15.0,
            'brake_regime': 'G', 'initial_position': 0.0,
            'track_gradient_positions': [100.0, 300.0, 500.0],
            'track_gradients': [6.0, -10.0, 2.0], 'track_curve_starts': [150.0],
            'track_curve_ends': [400.0], 'track_curve_radii': [280.0]}
    base.update(params)
    return sim_of(**base)


def drive(sim, phases):
    """Run ``phases`` of (t_end, traction command, head-pipe gauge pressure [Pa])."""
    for t_end, command, head in phases:
        for i in sim.locomotives:
            sim.set_traction_command(command, i)
        sim.set_head_pipe_pressure(head)
        sim.advance_to(t_end)


PHASES = [(15.0, 0.8, 500000.0), (30.0, -1.0, 500000.0), (80.0, 0.0, 0.0)]


def test_momentum_balance_with_all_external_forces(tmp_path):
    sim = mixed_sim(tmp_path)
    p0 = sim.momentum
    drive(sim, PHASES)
    assert np.all(sim.v == 0.0)                             # stopped and held
    assert sim.momentum - p0 == pytest.approx(sim.external_impulse, abs=1e-6 * abs(p0))


def test_energy_balance_with_all_external_forces(tmp_path):
    sim = mixed_sim(tmp_path)
    ke0, pe0 = sim.kinetic_energy, sim.potential_energy
    drive(sim, PHASES)
    assert sim.work_traction != 0.0 and sim.work_resistance > 0.0
    lost = (ke0 - sim.kinetic_energy) + (pe0 - sim.potential_energy)
    dissipated = (sim.work_brake + sim.work_resistance
                  + (sim.work_coupler - sim.elastic_energy) - sim.work_traction)
    assert abs(dissipated - lost) < 0.005 * abs(lost)
    # the kernel's gravity work is the potential energy lost
    assert sim.work_gravity == pytest.approx(pe0 - sim.potential_energy, rel=1e-3)


def test_gradient_changes_alone_give_in_train_forces(tmp_path):
    sim = mixed_sim(tmp_path, initial_position=320.0)       # the train across the hump
    sim.advance_to(5.0)
    grade = sim.gradient_force
    assert grade.min() < 0.0 < grade.max()
    assert np.max(np.abs(sim.coupler_force)) > 1000.0


def test_traction_force_follows_the_curves_and_the_build_up(tmp_path):
    sim = mixed_sim(tmp_path, initial_speed=0.0, track_gradient_positions=[],
                    track_gradients=[], track_curve_starts=[], track_curve_ends=[],
                    track_curve_radii=[])
    sim.set_traction_command(1.0, 0)
    sim.advance_to(0.5)
    f_half = sim.traction_force[0]
    sim.advance_to(3.0)
    f_full = sim.traction_force[0]
    weight = 126900.0 * G
    assert f_half == pytest.approx(0.5 * 409000.0, rel=0.01)        # 1 s build-up
    v = sim.v[0]
    mu = 0.33 * (0.161 + 7.5 / (3.6 * v + 44.0)) / (0.161 + 7.5 / 44.0)   # Curtius-Kniffler
    assert f_full == pytest.approx(min(409000.0, 1.85e6 / v, mu * weight), rel=0.01)
    assert np.all(sim.traction_force[1:] == 0.0)
    with pytest.raises(ValueError, match='not a locomotive'):
        sim.set_traction_command(0.5, 1)
    with pytest.raises(ValueError, match=r'\[-1, 1\]'):
        sim.set_traction_command(1.5, 0)


RUNIN = """
vehicles:
  - {{type: heavy_freight_locomotive, traction_build_up_time: 0.5, buffer_stroke: {s},
     draw_gear_stroke: {s}, max_dynamic_brake_force: 400000.0, max_dynamic_brake_power: 4.0e6}}
  - {{type: freight_wagon_loaded, count: 8, buffer_stroke: {s}, draw_gear_stroke: {s}}}
"""


def runin_sim(tmp_path, h=2e-3, stroke=0.01):
    """Return a run-in with slack 20 mm and buffers that block after ``stroke`` [m]."""
    return sim_of(consist_file=write_consist(tmp_path, RUNIN.format(s=stroke)),
                  initial_speed=8.0, brake_regime='G', integration_step=h, buffer_slack=0.02,
                  draw_gear_slack=0.02)


def run_runin(sim, t_end=14.0, dt=0.005):
    """Pull for 6 s, then full dynamic brake: the slack runs in; sample every ``dt`` [s]."""
    ys, fs = [], []
    per = int(round(dt / sim.h))
    sim.set_traction_command(1.0, 0)
    for k in range(1, int(round(t_end / dt)) + 1):
        if k == int(round(6.0 / dt)) + 1:
            sim.set_traction_command(-1.0, 0)
        sim.advance(per)
        ys.append(sim.y)
        fs.append(sim.coupler_force)
    return np.array(ys), np.array(fs)


def test_no_deflection_beyond_slack_stroke_and_blocked_spring(tmp_path):
    sim = runin_sim(tmp_path)
    y, f = run_runin(sim)
    assert sim.fault is None
    c = sim.cpl
    lo, hi = couplers.deflection_bounds(f, c[COUPLER.GT], c[COUPLER.GC], c[COUPLER.ST],
                                        c[COUPLER.SC], c[COUPLER.KB])
    assert np.all(y >= lo - 1e-12) and np.all(y <= hi + 1e-12)
    blocked = (y < -(c[COUPLER.GC] + c[COUPLER.SC])) | (y > c[COUPLER.GT] + c[COUPLER.ST])
    assert blocked.any()                                     # the test reaches the blocks


def test_blocking_impact_is_stable_and_accurate_at_the_default_step(tmp_path):
    _, f = run_runin(runin_sim(tmp_path))
    _, f_ref = run_runin(runin_sim(tmp_path, h=2.5e-4))
    peak, peak_ref = f.min(), f_ref.min()
    assert peak_ref < -1.0e6                                  # a hard, blocked impact
    assert peak == pytest.approx(peak_ref, rel=0.03)          # measured: 1.7 %
    assert f.max() == pytest.approx(f_ref.max(), rel=0.06)    # the snatch: 4.4 %
    # each coupler's peak (the impacts' timing shifts by a few ms: not sample by sample)
    np.testing.assert_allclose(f.min(axis=0), f_ref.min(axis=0), rtol=0.12)
    assert np.all(np.isfinite(f)) and np.max(np.abs(f)) < 1.1 * np.max(np.abs(f_ref))


def test_per_vehicle_adhesion_and_cylinder_pressure(tmp_path):
    path = write_consist(tmp_path, """
vehicles:
  - {type: paper_coach}
  - {type: paper_coach, adhesion_coefficient: 0.2, max_cylinder_pressure: 190000.0}
""")
    sim = sim_of(consist_file=path, brake_input='cylinder_per_coach', initial_speed=0.0)
    sim.set_cylinder_pressure([380000.0, 190000.0])
    sim.advance(1)
    np.testing.assert_allclose(sim.cylinder_pressure, [380000.0, 190000.0])
    sim2 = sim_of(consist_file=path, brake_input='cylinder_per_coach', initial_speed=10.0)
    sim2.set_cylinder_pressure([380000.0, 190000.0])
    sim2.advance(2)
    np.testing.assert_allclose(sim2.brake_force, [0.1 * 45000 * G, 0.2 * 45000 * G],
                               rtol=1e-9)
