"""
Coupler force laws on the Python side: one coupler's law, energies, deflection bounds.

The law of a single coupler for plots and tests, the energy stored with free play and
blocking, the deflection a force allows, and one vehicle end's quasi-static deflection and
absorbed energy (a coupling is two ends in series, :mod:`~train_dynamics.physics.config.consist`).

The law itself (paper eqs. 1-4, 14-16, sign conventions and the free play and blocking of a
real coupler) is compiled: :mod:`train_dynamics.physics.kernel.couplers`.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.couplers import coupler_force, MODEL_CODES


def force_law(y, ydot, *, ke=2.8e6, kf=1.4e6, kec=5.46e6, kfc=2.43e6, model='tanh', u=1000.0):
    """Return F [N] for scalars or arrays of y [m], ydot [m/s]; paper constants by default."""
    y = np.atleast_1d(np.asarray(y, dtype=float))
    ydot = np.broadcast_to(np.asarray(ydot, dtype=float), y.shape).copy()
    full = [np.broadcast_to(np.asarray(k, dtype=float), y.shape).copy()
            for k in (ke, kf, kec, kfc)]
    return coupler_force(y, ydot, *full, MODEL_CODES[model], float(u))


def elastic_energy_travel(y, ke, kec, gt, gc, st, sc, kb) -> np.ndarray:
    """
    Return the energy stored in each coupler [J] with free play and blocking.

    k d^2 / 2 on the spring's deflection d beyond the slack, plus K_b (|d| - S)^2 / 2 beyond
    the stroke; 0 in free play (arrays of N-1, or scalars).
    """
    y = np.asarray(y, dtype=float)
    dt = np.maximum(y - gt, 0.0)
    dc = np.maximum(-y - gc, 0.0)
    return (0.5 * kec * dt * dt + 0.5 * kb * np.maximum(dt - st, 0.0) ** 2
            + 0.5 * ke * dc * dc + 0.5 * kb * np.maximum(dc - sc, 0.0) ** 2)


def law_breakpoints(gt, gc, st, sc) -> np.ndarray:
    """
    Return the displacements y [m] where the coupler law changes branch: (4, N-1) or (4,).

    The ends of the free play -g_c and g_t (the kink at y = 0 of a tight coupling) and the
    strokes' ends, where blocking starts, -(g_c + S_c) and g_t + S_t (the law of
    :func:`train_dynamics.physics.kernel.couplers.coupler_branch_travel`). Across each the
    slope of F(y) jumps: an integrator of order > 1 must not step over one.
    """
    gt, gc, st, sc = (np.asarray(a, dtype=float) for a in (gt, gc, st, sc))
    return np.array(np.broadcast_arrays(-(gc + sc), -gc, gt, gt + st))


def deflection_bounds(force, gt, gc, st, sc, kb):
    """
    Return (lowest, highest) y [m] a coupler carrying ``force`` [N] can have.

    -(g_c + S_c + |F| / K_b) <= y <= g_t + S_t + |F| / K_b: beyond slack and stroke only
    the blocked stiffness gives (the springs' own force has the sign of F).
    """
    extra = np.abs(np.asarray(force, dtype=float)) / kb
    return -(gc + sc + extra), gt + st + extra


def end_deflection(force, k, k_friction, slack, stroke, kb):
    """
    Return one vehicle end's deflection [m] (> 0) under a quasi-static load ``force`` [N] (> 0).

    On the loading branch of the paper's law (eqs. 2-3, friction opposing the motion): the free
    play g, then F / (k + k_friction) up to the stroke S, then the blocked stiffness K_b:
    g + min(F / (k + k_fr), S) + max(F - (k + k_fr) S, 0) / K_b. The ends of a coupling carry
    the same force, so its deflection is the sum of its ends' (``config.consist``'s series rule).
    """
    force = np.asarray(force, dtype=float)
    k_load = k + k_friction
    return (slack + np.minimum(force / k_load, stroke)
            + np.maximum(force - k_load * stroke, 0.0) / kb)


def end_energy_to_blocking(k, k_friction, stroke):
    """Return the energy [J] one end absorbs loaded to blocking: (k + k_fr) S^2 / 2."""
    return 0.5 * (k + k_friction) * stroke * stroke
