"""UIC 540 by default: an emergency runs along the pneumatic brake pipe at >= 250 m/s."""
import os

import numpy as np
import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics import pneumatic as pn
from train_dynamics.physics.brake_valve import BrakeValveModel
from train_dynamics.physics.config import consist, SimConfig
from train_dynamics.physics.train import TrainSimulator

BAR = 1.0e5
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def drop_instants(cfg, seconds):
    """Instants [s] each vehicle's pipe is 1 bar below its start, emergency at t = 1 s."""
    sim = TrainSimulator(cfg)
    valve = BrakeValveModel(schedule=['0.0:release', '1.0:emergency'])
    every = 0.004
    t, pipe = [], []
    for k in range(int(round(seconds / every))):
        sim.set_head_pipe_pressure(valve.advance_to(k * every))
        sim.advance_to((k + 1) * every)
        t.append(sim.t)
        pipe.append(sim.pipe_pressure)
    t, pipe = np.array(t), np.array(pipe)
    down = pipe < pipe[0] - 1.0 * BAR
    assert down.any(axis=0).all(), 'a vehicle never dropped 1 bar'
    return t[np.argmax(down, axis=0)]


def test_default_uniform_train_carries_the_emergency_at_250_m_s():
    """
    40 coaches of 25 m, the defaults (brake_model pneumatic): accelerators on, >= 250 m/s.

    The speed of the 1 bar drop along the train (least squares of its instants against the
    distributors' positions, :func:`propagation_speed`); without accelerators (the former
    default) it crawled at 74 m/s.
    """
    cfg = SimConfig.from_dict({'num_coaches': 40, 'brake_model': 'pneumatic'})
    assert cfg.emergency_accelerator
    drop = drop_instants(cfg, 6.0)
    assert pn.propagation_speed(np.full(40, 25.0), drop) >= 250.0


def test_shipped_freight_carries_the_emergency_at_250_m_s():
    """
    config/freight_1500m.yaml (1491 m, 92 wagons between two Class 66): >= 250 m/s.

    The library's freight wagons have their distributors' accelerated emergency; the
    locomotives none (only the head's brake valve vents there). It was 59 m/s without.
    """
    cfg = load_param_file(os.path.join(ROOT, 'config', 'freight_1500m.yaml'))
    drop = drop_instants(cfg, 8.0)
    lengths = np.array(cfg.consist['length'])
    assert pn.propagation_speed(lengths, drop) >= 250.0
    assert pn.propagation_speed(lengths[1:-1], drop[1:-1]) >= 250.0


def test_library_types_with_and_without_an_accelerator():
    """Coaches and wagons carry one, locomotives say they have none (their comments)."""
    types = consist.library_types()
    defaults = consist.defaults_of({})
    fitted = {name: bool(fields.get('emergency_accelerator', defaults['emergency_accelerator']))
              for name, fields in types.items()}
    for name in ('passenger_coach', 'freight_wagon_loaded', 'freight_wagon_empty',
                 'freight_wagon_loaded_category_a', 'paper_coach'):
        assert fitted[name], name
    for name in ('electric_passenger_locomotive', 'heavy_freight_locomotive',
                 'electric_freight_locomotive'):
        assert not fitted[name], name


def test_a_vehicle_without_accelerator_keeps_the_slow_pipe():
    """emergency_accelerator false on the uniform train: the drop crawls, < 120 m/s."""
    cfg = SimConfig.from_dict({'num_coaches': 40, 'brake_model': 'pneumatic',
                               'emergency_accelerator': False})
    drop = drop_instants(cfg, 20.0)
    assert pn.propagation_speed(np.full(40, 25.0), drop) == pytest.approx(74.0, rel=0.1)
