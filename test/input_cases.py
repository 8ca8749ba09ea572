"""
Input cases shared by the tests of inputs at their own instants and of the multirate step.

``khz_case``: four unequal coaches with cylinders replayed at 1 kHz and the chain reference;
``replay``: the same inputs through the simulator; ``mixed_consist``: a locomotive and five
wagons with free play and blocking. Forces in N, pressures in Pa, times in s.
"""
import numpy as np

from train_dynamics.physics.chain_reference import ChainLaw, solve_chain
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel.layout import COUPLER
from train_dynamics.physics.train import TrainSimulator

MASSES = [45000.0, 30000.0, 60000.0, 25000.0]


def khz_case(t_end=1.5, seed=1):
    """Four unequal coaches, tanh u = 700, cylinders replayed at 1 kHz; the reference."""
    cfg = SimConfig.from_dict({'masses': MASSES, 'brake_input': 'cylinder_per_coach',
                               'scale_factor': 700.0})
    sim = TrainSimulator(cfg)
    pmax = cfg.max_cylinder_pressure
    rng = np.random.default_rng(seed)
    times = np.arange(int(t_end * 1000)) * 1e-3
    levels = np.empty((times.size, 4))
    cur = np.zeros(4)
    for k in range(times.size):
        if rng.random() < 0.03:
            cur = rng.choice([0.0, 0.3, 0.6, 1.0], size=4) * pmax
        levels[k] = cur
    keep = np.r_[True, np.any(np.diff(levels, axis=0) != 0.0, axis=1)]
    times, levels = times[keep], levels[keep]
    full = cfg.adhesion_coefficient * np.array(MASSES) * cfg.gravity
    t_eval = np.round(np.arange(1, int(round(t_end / 0.01)) + 1) * 0.01, 10)
    ref = solve_chain(sim.inertia, ChainLaw.of_simulator(sim), cfg.initial_speed,
                      (times, levels / pmax * full), t_eval)
    return times, levels, t_eval, ref


def replay(times, levels, t_eval, **overrides):
    cfg = SimConfig.from_dict({'masses': MASSES, 'brake_input': 'cylinder_per_coach',
                               'scale_factor': 700.0, **overrides})
    sim = TrainSimulator(cfg)
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
