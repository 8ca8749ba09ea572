"""``initial_state: equilibrium``: a train starts at the static coupler forces of its chain."""
import numpy as np
import pytest

from train_dynamics.physics import equilibrium
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel.traction import available_force
from train_dynamics.physics.train import TrainSimulator

G = 9.81


def freight(tmp_path, **params):
    path = tmp_path / 'train.yaml'
    path.write_text('vehicles:\n  - {type: electric_freight_locomotive}\n'
                    '  - {type: freight_wagon_loaded, count: 20}\n')
    base = {'consist_file': str(path), 'gravity': G, 'brake_input': 'pipe_head',
            'integration_step': 0.002}
    return SimConfig.from_dict({**base, **params})


def test_balanced_traction_on_a_constant_gradient_has_no_coupler_transient(tmp_path):
    v0 = 15.0
    cfg = freight(tmp_path, initial_speed=v0, track_gradient_positions=[-1.0e5],
                  track_gradients=[4.0])
    sim = TrainSimulator(cfg)
    c = cfg.consist
    m = c['mass']
    need = float(np.sum(c['davis_a'] + (c['davis_b'] + c['davis_c'] * v0) * v0)
                 + np.sum(m) * G * 4.0e-3)
    i = sim.locomotives[0]
    avail = available_force(v0, c['max_tractive_force'][i], c['max_power'][i],
                            c['traction_adhesion'][i], m[i] * G)
    sim.set_traction_command(need / avail, i)
    f0 = sim.coupler_force.copy()
    assert f0[0] > 1.0e5                        # the locomotive pulls the train up the hill
    forces = [f0]
    for _ in range(50):                         # 5 s in 0.1 s samples
        sim.advance(50)
        forces.append(sim.coupler_force.copy())
    rate = np.abs(np.diff(np.array(forces), axis=0)) / 0.1
    steady = np.abs(f0)
    # every coupler's max |dF/dt| below 1 % of its steady force per second
    assert np.all(rate.max(axis=0) < 0.01 * np.maximum(steady, 0.01 * steady.max()))
    # unstressed, the same run rings
    cfg_u = freight(tmp_path, initial_speed=v0, track_gradient_positions=[-1.0e5],
                    track_gradients=[4.0], initial_state='unstressed')
    sim_u = TrainSimulator(cfg_u)
    sim_u.set_traction_command(need / avail, i)
    sim_u.advance(50)
    assert np.max(np.abs(sim_u.coupler_force - f0)) > 0.05 * steady.max()


def test_a_train_straddling_a_gradient_change_starts_at_the_closed_form_forces(tmp_path):
    # the train's front on +10 per mille, its rear on level track; coasting at 20 m/s
    cfg = freight(tmp_path, initial_speed=20.0, initial_position=150.0,
                  track_gradient_positions=[150.0 - 170.0], track_gradients=[10.0])
    sim = TrainSimulator(cfg)
    c = cfg.consist
    lengths = c['length']
    fronts = 150.0 - np.concatenate(([0.0], np.cumsum(lengths[:-1])))
    start = 150.0 - 170.0
    on_hill = np.clip((fronts - start) / lengths, 0.0, 1.0)        # share of each vehicle
    v0 = 20.0
    f = (-c['mass'] * G * 10e-3 * on_hill
         - (c['davis_a'] + (c['davis_b'] + c['davis_c'] * v0) * v0))
    inertia = c['mass'] * (1.0 + c['rotating_mass_factor'])
    a = f.sum() / inertia.sum()
    closed = np.cumsum(f - inertia * a)[:-1]
    assert np.max(np.abs(closed)) > 3.0e4          # ~45 kN in compression
    assert sim.coupler_force == pytest.approx(closed, rel=0.01, abs=0.01 * np.max(np.abs(closed)))


def test_unstressed_and_level_starts_leave_the_couplers_at_zero(tmp_path):
    sim = TrainSimulator(freight(tmp_path, initial_speed=20.0, initial_state='unstressed'))
    assert np.all(sim.x == 0.0)
    sim = TrainSimulator(SimConfig.from_dict({}))          # the paper's train: nothing acts
    assert np.all(sim.x == 0.0)


def test_static_deflection_takes_the_free_play_first():
    y = equilibrium.static_deflection(np.array([1.0e5, -1.0e5, 0.0]), 2.0e6, 4.0e6, 0.01,
                                      0.02, 0.1, 0.1, 1e8)
    assert y == pytest.approx([0.01 + 0.025, -0.02 - 0.05, 0.0])
    assert list(equilibrium.positions([0.1, -0.2])) == pytest.approx([0.0, -0.1, 0.1])
