"""
The train's quasi-static equilibrium at t = 0: coupler forces and deflections of a chain.

A train that starts in equilibrium (parameter ``initial_state: equilibrium``) has every vehicle
at the one acceleration its external forces give the whole train, a = sum F_i / sum M_i (M the
inertia, m (1 + rotating-mass factor) [kg]; F_i the gradient force, traction and running and
curve resistance at t = 0 [N, forward > 0]). Newton on vehicles 1..j then gives the force of
coupler j (tension > 0, it pulls vehicle j back):

    T_j = sum_{i <= j} (F_i - M_i a)                                          [N]

and the law of the coupler at rest (ydot = 0: the friction term of eqs. 2-3 / 14-16 is 0,
s(0) = 0) gives its deflection, free play first: y = g_t + T / k_ec in tension (blocked
beyond the stroke S_t: y = g_t + S_t + (T - k_ec S_t) / (k_ec + K_b)), y = -g_c + T / k_e in
compression, y = 0 at T = 0. One static solve: the forces are those at the unstressed
positions (the deflections move the vehicles by millimetres).
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.couplers import table_knots, table_side


def chain_forces(external, inertia) -> np.ndarray:
    """Return the coupler forces T_j [N] (N-1, tension > 0) of vehicles with forces F_i [N]."""
    f = np.asarray(external, dtype=float)
    m = np.asarray(inertia, dtype=float)
    a = f.sum() / m.sum()
    return np.cumsum(f - m * a)[:-1]


def static_deflection(force, ke, kec, gt, gc, st, sc, kb, tables=None) -> np.ndarray:
    """
    Return each coupler's deflection y [m] at rest under ``force`` [N] (arrays of N-1).

    ``tables``: the couplers' table rows (``layout.TABLE_ROWS``); a tabled coupling (a
    preloaded or progressive end) carries its elastic force E(d) at rest (s = 0), inverted
    between its knots, then K_b beyond the stroke (E constant there).
    """
    t = np.asarray(force, dtype=float)
    tension = np.where(t / kec <= st, gt + t / kec, gt + st + (t - kec * st) / (kec + kb))
    comp = np.where(-t / ke <= sc, -gc + t / ke, -gc - sc + (t + ke * sc) / (ke + kb))
    y = np.where(t > 0.0, tension, np.where(t < 0.0, comp, 0.0))
    if tables is None:
        return y
    for j in np.flatnonzero(np.asarray(tables)[0] != 0.0):
        if t[j] == 0.0:
            continue
        side = 0 if t[j] > 0.0 else 1
        grid = table_knots(tables[:, j], side)
        e = table_side(tables[:, j], side)[0]
        slack, stroke = (gt[j], st[j]) if side == 0 else (gc[j], sc[j])
        a = abs(t[j])
        d = (np.interp(a, e, grid) if a <= e[-1] else stroke + (a - e[-1]) / kb[j])
        y[j] = slack + d if side == 0 else -(slack + d)
    return y


def positions(y) -> np.ndarray:
    """Return the vehicles' displacements x [m] (N) with x_1 = 0 and x_j - x_{j+1} = y_j."""
    return -np.concatenate(([0.0], np.cumsum(np.asarray(y, dtype=float))))
