"""
The shipped per-bogie scenario, config/emu_flirt_4_wsp.yaml, against its variants.

The FLIRT's full service from 160 km/h onto 0.06 adhesion (from 300 m on) with per-bogie
wheelsets and the builtin WSP on each bogie stops (docs/multiple_units.md: 1251 m from the
demand) farther than on dry rail (863 m), and nearer with the leading bogies conditioning
the rail (``rail_conditioning`` 0.2) than without (1481 m); every wheel protected (no car
slides 5 s), and the energy balance closes.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.train import TrainSimulator

ROOT = Path(__file__).resolve().parents[2]


def _stop(**overrides) -> dict:
    cfg = load_param_file(str(ROOT / 'config' / 'emu_flirt_4_wsp.yaml'))
    sim = TrainSimulator(cfg.replace(demand_schedule_times=[], demand_schedule_values=[],
                                     **overrides))
    e0 = sim.kinetic_energy + sim.wheel_kinetic_energy
    sim.advance_to(1.0)
    x0 = float(sim.x[0])
    sim.bcu.set_demand(1.0)
    while np.any(sim.v > 0.0) and sim.t < 150.0:
        sim.advance_to(sim.t + 0.5)
    e1 = sim.kinetic_energy + sim.wheel_kinetic_energy
    work = (sim.work_wheel_brake + sim.work_creep + sim.work_coupler + sim.work_resistance
            - sim.work_traction - sim.work_gravity)
    return {'distance': float(sim.x[0]) - x0, 'stopped': bool(np.all(sim.v == 0.0)),
            'sliding': float(np.max(sim.sliding_time)), 'residue': (e0 - e1 - work) / e0}


def test_the_per_bogie_scenario_stops_between_dry_rail_and_no_conditioning():
    shipped = _stop()
    plain = _stop(rail_conditioning=0.0)
    assert shipped['stopped'] and plain['stopped']
    assert 863.0 < shipped['distance'] < plain['distance']
    assert shipped['distance'] == pytest.approx(1251.0, rel=0.01)      # the docs' figure
    assert plain['distance'] == pytest.approx(1481.0, rel=0.01)
    assert shipped['sliding'] < 5.0
    assert abs(shipped['residue']) < 1e-6 and abs(plain['residue']) < 1e-6
