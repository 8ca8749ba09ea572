"""Shared scenario helpers for the physics tests (plain functions, no fixtures)."""
import numpy as np

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel.couplers import coupler_force, TANH
from train_dynamics.physics.reference import HeadVentBraking, reference_solution
from train_dynamics.physics.train import TrainSimulator

T_EMERGENCY = 1.0   # the brake valve vents the pipe at t = 1 s


def paper_sim(**overrides) -> TrainSimulator:
    """Return the paper's scenario (config defaults), pipe vented to 0 gauge at t = 1 s."""
    sim = TrainSimulator(SimConfig.from_dict(overrides))
    sim.advance_to(T_EMERGENCY)
    sim.set_head_pipe_pressure(0.0)
    return sim


def record(sim: TrainSimulator, t_end: float, dt: float = 0.01):
    """Advance to t_end; sample (t, y, ydot, F) every dt like the node's 100 Hz output."""
    ts, ys, yds, Fs = [], [], [], []
    k = int(np.floor(sim.t / dt + 0.5))
    while sim.t < t_end - 1e-9:
        k += 1
        sim.advance_to(k * dt)
        ts.append(sim.t)
        ys.append(sim.y)
        yds.append(sim.ydot)
        Fs.append(sim.coupler_force)
    return np.array(ts), np.array(ys), np.array(yds), np.array(Fs)


def paper_reference(t_eval, u=1000.0, **overrides):
    """
    Return the coupler forces at t_eval of a tight-tolerance solution of the paper scenario.

    Returns (F [N], shape (len(t_eval), N-1), brake(t) -> braking forces [N]).

    The brake system does not depend on the motion: after the emergency venting the cylinder
    of coach i follows the filling table from T_EMERGENCY + (i-1) L / c, so the braking force
    is known in closed form (eq. 13).
    """
    cfg = SimConfig.from_dict(overrides)
    n = cfg.n_coaches
    m = np.array(cfg.mass_array)
    brake = HeadVentBraking(cfg, T_EMERGENCY)
    sol = reference_solution(m, cfg.buffer_stiffness, cfg.buffer_friction,
                             cfg.draw_gear_stiffness, cfg.draw_gear_friction, u,
                             cfg.initial_speed, brake, float(t_eval[-1]), t_eval=t_eval)
    assert sol.status == 0, sol.message
    x, v = sol.y[:n], sol.y[n:]
    k = [np.full(n - 1, c) for c in (cfg.buffer_stiffness, cfg.buffer_friction,
                                     cfg.draw_gear_stiffness, cfg.draw_gear_friction)]
    F = np.array([coupler_force(x[:-1, i] - x[1:, i], v[:-1, i] - v[1:, i], *k, TANH, u)
                  for i in range(len(t_eval))])
    return F, brake
