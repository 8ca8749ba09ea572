"""The pneumatic brake inside the simulator: brake_model pneumatic, bypasses, outputs."""
import numpy as np
import pytest

from train_dynamics.cli.offline import main
from train_dynamics.physics import pneumatic as pn
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.bags import bag_info
from train_dynamics.recording.history import load_history
from train_dynamics.recording.outputs import output_topics, OutputEncoder
from train_dynamics.recording.plots import plot_bag

P_MAX = 380000.0


def emergency(sim, t_end, t_brake=1.0):
    """Run to t_brake, vent the head (command 0), run to t_end."""
    sim.advance_to(t_brake)
    sim.set_head_pipe_pressure(0.0)
    sim.advance_to(t_end)
    return sim


def test_default_is_empirical_and_has_no_reservoirs():
    cfg = SimConfig.from_dict({})
    assert cfg.brake_model == 'empirical'
    sim = TrainSimulator(cfg)
    assert sim.pneu is None and sim.auxiliary_pressure is None
    assert output_topics(cfg)[:3] == ('couplers', 'coaches', 'brake_cylinders')
    assert 'brake_reservoirs' not in output_topics(cfg)


def test_pneumatic_train_hands_the_cylinders_to_the_chain():
    """The chain brakes with exactly the cylinder pressures of the standalone model."""
    cfg = SimConfig.from_dict({'brake_model': 'pneumatic', 'num_coaches': 5})
    sim = emergency(TrainSimulator(cfg), 6.0)
    alone = pn.from_config(cfg, sim.h)
    alone.advance(500)
    alone.set_command(0.0)
    alone.advance(2500)
    assert np.array_equal(sim.cylinder_pressure, alone.cylinder_pressure)
    assert np.array_equal(sim.pipe_pressure, alone.pipe_pressure)
    assert np.array_equal(sim.auxiliary_pressure, alone.auxiliary_pressure)
    # eq. 13 with these pressures (the coaches still move)
    fb = cfg.adhesion_coefficient * 45000.0 * cfg.gravity * np.minimum(
        sim.cylinder_pressure / P_MAX, 1.0)
    assert np.allclose(sim.brake_force, fb, rtol=0.02)
    assert np.all(sim.cylinder_pressure > 0.9 * P_MAX)


def test_pneumatic_train_stops_and_brakes_later_than_empirical():
    """The relay valve and chokes delay the brake: longer stopping distance than the table."""
    stops = {}
    for model in ('empirical', 'pneumatic'):
        sim = emergency(TrainSimulator(SimConfig.from_dict({'brake_model': model})), 70.0)
        assert np.all(sim.v == 0.0) and sim.fault is None
        stops[model] = sim.x[0]
    assert stops['empirical'] < stops['pneumatic'] < 1.1 * stops['empirical']


def test_cylinder_per_coach_bypasses_the_pneumatic_brake():
    """cylinder_per_coach: the same run, bit for bit, with either brake model."""
    runs = []
    for model in ('empirical', 'pneumatic'):
        sim = TrainSimulator(SimConfig.from_dict({'brake_model': model,
                                                  'brake_input': 'cylinder_per_coach'}))
        sim.set_cylinder_pressure([300000.0, 200000.0, 100000.0])
        sim.advance_to(5.0)
        runs.append(np.concatenate([sim.x, sim.v, sim.coupler_force]))
    assert np.array_equal(runs[0], runs[1])


def test_pipe_per_coach_drives_the_distributors():
    cfg = SimConfig.from_dict({'brake_model': 'pneumatic', 'brake_input': 'pipe_per_coach'})
    sim = TrainSimulator(cfg)
    sim.set_pipe_pressure([500000.0, 425000.0, 350000.0])
    sim.advance_to(15.0)
    p = sim.cylinder_pressure
    assert p[0] == 0.0
    assert p[1] == pytest.approx(0.5 * P_MAX, abs=5000.0)
    assert p[2] == pytest.approx(P_MAX, abs=5000.0)
    assert np.array_equal(sim.pipe_pressure, [500000.0, 425000.0, 350000.0])


def test_closed_angle_cock_parameter():
    cfg = SimConfig.from_dict({'brake_model': 'pneumatic', 'num_coaches': 6,
                               'angle_cock_closed': 2})
    sim = emergency(TrainSimulator(cfg), 8.0)
    assert np.all(sim.brake_force[:2] > 0.0)
    assert np.all(sim.brake_force[2:] == 0.0)
    with pytest.raises(ConfigError):
        SimConfig.from_dict({'num_coaches': 6, 'angle_cock_closed': 6})


def test_reservoir_topic_encoded_and_recorded(tmp_path):
    """brake_reservoirs: position = auxiliary, effort = control reservoir [Pa gauge]."""
    params = tmp_path / 'p.yaml'
    params.write_text('train_dynamics:\n  ros__parameters:\n    brake_model: pneumatic\n'
                      'brake_valve:\n  ros__parameters:\n    schedule: ["1.0:emergency"]\n')
    out = tmp_path / 'bag'
    assert main(['simulate', '--params', str(params), '--duration', '5', '--output',
                 str(out), '-q']) == 0
    assert 'brake_reservoirs' in bag_info(out).topics
    hist = load_history(out)
    rs = hist.reservoirs
    assert rs.names == ['coach_1', 'coach_2', 'coach_3']
    assert np.allclose(rs.effort[-1], 500000.0, atol=2000.0)       # CR keeps 5 bar
    assert np.all(rs.position[-1] < rs.position[0])                # AR fed the cylinders
    assert np.all(hist.cylinders.position[-1] > 0.5 * P_MAX)
    pneumatic = SimConfig.from_dict({'brake_model': 'pneumatic', 'num_coaches': 3})
    assert OutputEncoder(pneumatic).topics[3] == 'brake_reservoirs'
    names = [p.name for p in plot_bag(out, tmp_path / 'plots')]
    assert 'brake_pressures.png' in names
