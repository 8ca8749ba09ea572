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
from train_dynamics.physics.kernel.layout import COUPLER, TABLE_KNOTS


def force_law(y, ydot, *, ke=2.8e6, kf=1.4e6, kec=5.46e6, kfc=2.43e6, model='tanh', u=1000.0):
    """Return F [N] for scalars or arrays of y [m], ydot [m/s]; paper constants by default."""
    y = np.atleast_1d(np.asarray(y, dtype=float))
    ydot = np.broadcast_to(np.asarray(ydot, dtype=float), y.shape).copy()
    full = [np.broadcast_to(np.asarray(k, dtype=float), y.shape).copy()
            for k in (ke, kf, kec, kfc)]
    return coupler_force(y, ydot, *full, MODEL_CODES[model], float(u))


def no_tables(n: int = 1) -> np.ndarray:
    """Return the ``cpl`` argument of the kernel's law for n couplers without tables (TAB 0)."""
    return np.zeros((len(COUPLER), n))


def elastic_energy_travel(y, ke, kec, gt, gc, st, sc, kb, tables=None) -> np.ndarray:
    """
    Return the energy stored in each coupler [J] with free play and blocking.

    k d^2 / 2 on the spring's deflection d beyond the slack, plus K_b (|d| - S)^2 / 2 beyond
    the stroke; 0 in free play (arrays of N-1, or scalars). ``tables``: the couplers' table
    rows; a tabled coupling stores the integral of its elastic force E (:func:`table_side`)
    over d instead of k d^2 / 2.
    """
    y = np.asarray(y, dtype=float)
    dt = np.maximum(y - gt, 0.0)
    dc = np.maximum(-y - gc, 0.0)
    out = (0.5 * kec * dt * dt + 0.5 * kb * np.maximum(dt - st, 0.0) ** 2
           + 0.5 * ke * dc * dc + 0.5 * kb * np.maximum(dc - sc, 0.0) ** 2)
    if tables is None:
        return out
    for j in np.flatnonzero(np.asarray(tables)[0] != 0.0):
        stored = 0.5 * kb[j] * (max(dt[j] - st[j], 0.0) ** 2 + max(dc[j] - sc[j], 0.0) ** 2)
        for side, d in ((0, dt[j]), (1, dc[j])):
            grid = table_knots(tables[:, j], side)
            e = table_side(tables[:, j], side)[0]
            upto = np.minimum(grid, d)
            e_at = np.interp(upto, grid, e)
            stored += float(np.sum(0.5 * (e_at[1:] + e_at[:-1]) * np.diff(upto)))
            stored += max(d - grid[-1], 0.0) * e[-1]
        out[j] = stored
    return out


def law_breakpoints(gt, gc, st, sc, tables=None) -> np.ndarray:
    """
    Return the displacements y [m] where the coupler law changes branch: (B, N-1) or (B,).

    The ends of the free play -g_c and g_t (the kink at y = 0 of a tight coupling) and the
    strokes' ends, where blocking starts, -(g_c + S_c) and g_t + S_t (the law of
    :func:`train_dynamics.physics.kernel.couplers.coupler_branch_travel`). Across each the
    slope of F(y) jumps: an integrator of order > 1 must not step over one. ``tables``: the
    couplers' table rows (``layout.TABLE_ROWS``, (len, N-1)): a tabled coupling's knots
    (:func:`table_knots`, beyond the free play on either side) are breakpoints too (B = 4 +
    2 (K - 1); an untabled coupler repeats g_t there).
    """
    gt, gc, st, sc = (np.asarray(a, dtype=float) for a in (gt, gc, st, sc))
    base = np.array(np.broadcast_arrays(-(gc + sc), -gc, gt, gt + st))
    if tables is None:
        return base
    tables = np.asarray(tables, dtype=float)
    extra = np.broadcast_to(gt, (2 * (TABLE_KNOTS - 1),) + gt.shape).copy()
    for j in np.flatnonzero(tables[0] != 0.0):
        extra[:TABLE_KNOTS - 1, j] = gt[j] + table_knots(tables[:, j], 0)[1:]
        extra[TABLE_KNOTS - 1:, j] = -(gc[j] + table_knots(tables[:, j], 1)[1:])
    return np.concatenate((base, extra))


def table_knots(rows: np.ndarray, side: int) -> np.ndarray:
    """
    Return the knots d_k [m] of one side of a coupling table (side 0 draw gear, 1 buffers).

    d_0 = 0, d_1 (end of the preload ramp), then equal spacing 1 / ``ih`` (rows of
    ``layout.COUPLER``, TAB onwards: TAB, T_D1, T_IH, C_D1, C_IH, ...).
    """
    d1, ih = rows[1 + 2 * side], rows[2 + 2 * side]
    return np.concatenate(([0.0], d1 + np.arange(TABLE_KNOTS - 1) / ih))


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


# ------------------------------------------------------------------------ coupling tables
def table_side(rows: np.ndarray, side: int):
    """Return (E, R) [N] at the knots of one side of a coupling table (0 draw gear, 1 buffers)."""
    k = TABLE_KNOTS
    return (rows[5 + 2 * side * k:5 + (2 * side + 1) * k],
            rows[5 + (2 * side + 1) * k:5 + (2 * side + 2) * k])


def table_energy(rows: np.ndarray, device: str) -> float:
    """Return the energy [J] a tabled coupling's loading branch absorbs to its stroke."""
    side = 0 if device == 'draw_gear' else 1
    e, r = table_side(rows, side)
    load = e + r
    return float(np.sum(0.5 * (load[1:] + load[:-1]) * np.diff(table_knots(rows, side))))
