"""
The shipped low-adhesion scenario, shortened: emergency onto a section of 0.05 adhesion.

``config/passenger_low_adhesion_12.yaml`` (wsp none) and ``..._wsp.yaml`` (wsp builtin),
differing in ``wsp`` alone, run here from 100 km/h onto 1 km of 0.05 adhesion from 150 m on
(the shipped run: 160 km/h, 2.5 km from 400 m; figures in docs/brakes.md). Unprotected, the
wheelsets lock on the section and slide over it; the reference slide protection keeps every
wheel turning (none at rest for more than 0.5 s while its vehicle moves), slides a small
fraction of that and stops shorter; both balance the energy of vehicles and wheelsets
(brake work at the wheels + creep work + coupler and resistance work = kinetic energy lost)
and the momentum against the external impulse.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.train import TrainSimulator

CONFIG = os.path.join(
    os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), 'config')
SECTION = (150.0, 1150.0)       # [m] the shortened low-adhesion section
SHORT = {'initial_speed': 100 / 3.6, 'track_adhesion_positions': list(SECTION),
         'track_adhesion': [0.05, 0.331]}


def _scenario(name):
    return load_param_file(os.path.join(CONFIG, name))


def _run(cfg, chunk=25):
    """Emergency at t = 1 s (the files' brake valve) until the train stops: its figures."""
    sim = TrainSimulator(cfg)
    e0 = sim.kinetic_energy + sim.wheel_kinetic_energy
    p0 = sim.momentum
    sim.set_head_pipe_pressure(5.0e5)
    sim.advance_to(1.0)
    sim.set_head_pipe_pressure(0.0)
    rest = np.zeros(sim.n)
    longest = np.zeros(sim.n)
    locked_on_section = np.zeros(sim.n)
    dt = chunk * sim.h
    while np.any(sim.v > 0.0) and sim.t < 200.0:
        sim.advance(chunk)
        at_rest = (sim.v > 0.0) & (sim.wheel_speed == 0.0)
        rest = np.where(at_rest, rest + dt, 0.0)
        longest = np.maximum(longest, rest)
        locked_on_section += dt * at_rest
    return {'sim': sim, 'distance': sim.x[0], 'longest_rest': longest,
            'locked': locked_on_section, 'energy_lost': e0 - sim.kinetic_energy
            - sim.wheel_kinetic_energy, 'initial_energy': e0,
            'work': sim.work_wheel_brake + sim.work_creep + sim.work_coupler
            + sim.work_resistance - sim.work_traction - sim.work_gravity,
            'momentum_change': sim.momentum - p0, 'impulse': sim.external_impulse,
            'momentum': p0}


def test_the_two_files_differ_in_wsp_alone():
    bare = _scenario('passenger_low_adhesion_12.yaml')
    wsp = _scenario('passenger_low_adhesion_12_wsp.yaml')
    assert (bare.wsp, wsp.wsp) == ('none', 'builtin')
    assert bare.replace(wsp='builtin') == wsp
    assert list(bare.track_adhesion) == [0.05, 0.331]


def test_low_adhesion_scenario_short():
    bare = _run(_scenario('passenger_low_adhesion_12.yaml').replace(**SHORT))
    prot = _run(_scenario('passenger_low_adhesion_12_wsp.yaml').replace(**SHORT))
    for r in (bare, prot):
        assert np.all(r['sim'].v == 0.0)
        assert abs(r['energy_lost'] - r['work']) <= 0.005 * r['initial_energy']
        assert r['momentum_change'] == pytest.approx(r['impulse'], abs=1e-9 * r['momentum'])
    # unprotected: every wheelset locks on the section and slides most of it
    s = bare['sim']
    assert np.all(bare['locked'] > 10.0)
    assert np.all(s.sliding_distance > 0.7 * (SECTION[1] - SECTION[0]))
    # protected: no wheel rests > 0.5 s while its vehicle moves, a tenth of the sliding,
    # a shorter stop
    p = prot['sim']
    assert np.all(prot['longest_rest'] <= 0.5)
    assert np.all(p.sliding_distance < 0.1 * s.sliding_distance)
    assert prot['distance'] < bare['distance']
