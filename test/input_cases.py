"""
Input cases shared by the tests of inputs at their own instants and of the multirate step.

``khz_case``: four unequal coaches with cylinders replayed at 1 kHz
(``train_dynamics/physics/replay_cases.py``, the case ``bench/accuracy.py`` runs too) and the
chain reference;
``replay``: the same inputs through the simulator; ``mixed_consist``: a locomotive and five
wagons with free play and blocking. Forces in N, pressures in Pa, times in s.
"""
import numpy as np

from train_dynamics.physics.chain_reference import ChainLaw, solve_chain
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel.layout import COUPLER
from train_dynamics.physics.replay_cases import (khz_braking_forces, khz_config, KHZ_MASSES,
                                                 khz_pressures)
from train_dynamics.physics.train import TrainSimulator

MASSES = list(KHZ_MASSES)


def khz_case(t_end=1.5, seed=1):
    """Return the kHz replay case (``physics/replay_cases.py``) over ``t_end``; the reference."""
    cfg = khz_config()
    sim = TrainSimulator(cfg)
    times, levels = khz_pressures(cfg, t_end, seed, 0.03)
    t_eval = np.round(np.arange(1, int(round(t_end / 0.01)) + 1) * 0.01, 10)
    ref = solve_chain(sim.inertia, ChainLaw.of_simulator(sim), cfg.initial_speed,
                      (times, khz_braking_forces(cfg, levels)), t_eval)
    return times, levels, t_eval, ref


def replay(times, levels, t_eval, **overrides):
    sim = TrainSimulator(khz_config(**overrides))
    for t, p in zip(times, levels):
        sim.schedule(t, lambda p=p: sim.set_cylinder_pressure(p))
    F = []
    for t in t_eval:
        sim.advance_to(t)
        F.append(sim.coupler_force)
    return np.array(F), sim


def mixed_consist(**overrides):
    """Return a 90 t locomotive and 5 wagons (4-12 mm free play, 20-30 mm strokes); inputs."""
    masses = [90000.0, 80000.0, 22000.0, 80000.0, 22000.0, 22000.0]
    sim = TrainSimulator(SimConfig.from_dict({'masses': masses, 'brake_input':
                                              'cylinder_per_coach', 'initial_speed': 20.0,
                                              **overrides}))
    sim.cpl[COUPLER.GT] = sim.cpl[COUPLER.GC] = [0.004, 0.012, 0.008, 0.01, 0.006]
    sim.cpl[COUPLER.ST] = sim.cpl[COUPLER.SC] = [0.02, 0.03, 0.025, 0.02, 0.03]
    sim.cpl[COUPLER.KB] = [5e7, 8e7, 6e7, 7e7, 5e7]
    on = np.array([[1, 1, 0, 0, 0, 0], [1, 1, 1, 1, 1, 1]], float)
    times = np.array([0.2, 0.7])
    for t, p in zip(times, on * sim.cfg.max_cylinder_pressure):
        sim.schedule(t, lambda p=p: sim.set_cylinder_pressure(p))
    full = sim.cfg.adhesion_coefficient * np.array(masses) * sim.cfg.gravity
    return sim, (times, on * full)
