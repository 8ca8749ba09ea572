"""
Force laws of the traction, collision and coupling device (paper eqs. 1-4, 14-16).

Sign conventions (product contract): y = x_i - x_{i+1} [m] is the coupler's relative
displacement, y < 0 compression (the buffers work, constants k_e, k_f), y > 0 extension (the
draw gear works, constants k_ec, k_fc). F > 0 is tension [N].

    F(y, ydot) = 1/2 (1 - sgn y) (k_e  - k_f  s(ydot)) y          buffers,   eq. (2) / (15)
               + 1/2 (1 + sgn y) (k_ec + k_fc s(ydot)) y          draw gear, eq. (3) / (16)

with s = sgn (paper eqs. 1-4, model ``sign``) or s(ydot) = tanh(u ydot) (eq. 14, model
``tanh``, scale factor u [s/m]). The friction term is k_f |y| s(ydot) in compression and
k_fc |y| s(ydot) in extension: it always opposes the relative velocity, so the loading branch
is (k + k_friction)|y| and the unloading branch (k - k_friction)|y| (the hysteresis loop of
the paper's Fig. 2).

The law is written once, per coupler (:func:`coupler_branch` for the branches,
:func:`coupler_force_scalar` for F and its derivatives), compiled with numba and called by
the integrator kernel; :func:`coupler_force` and :func:`coupler_force_jacobian` apply it to
arrays of couplers (per-coupler constants let a train mix vehicles). The couplers' resultant
on each coach (eqs. 5-7) is :func:`net_force` (per coach) and :func:`net_forces`. The
single-coupler law for plots, and the energy and deflection bounds with free play, are in
:mod:`train_dynamics.physics.couplers`.
"""
from __future__ import annotations

import math

import numpy as np

from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import COUPLER, TABLE_KNOTS


#: model codes used inside the compiled kernels
SIGN = 0


TANH = 1


MODEL_CODES = {'sign': SIGN, 'tanh': TANH}

#: rows of the coupling tables in ``cpl`` (numba freezes these globals as constants)
C_TAB = COUPLER.TAB
C_T_D1 = COUPLER.T_D1
C_T_IH = COUPLER.T_IH
C_C_D1 = COUPLER.C_D1
C_C_IH = COUPLER.C_IH
C_T_E0 = COUPLER.T_E0
C_T_R0 = COUPLER.T_R0
C_C_E0 = COUPLER.C_E0
C_C_R0 = COUPLER.C_R0


@jit
def fast_tanh(z: float) -> float:
    """
    Return tanh(z) to full double precision through expm1 (cheaper than libm's tanh here).

    tanh|z| = -expm1(-2|z|) / (2 + expm1(-2|z|)): no cancellation near 0, exactly 1 once
    expm1 rounds to -1; no branch (the kernels' loops run it for every coupler).
    """
    e = math.expm1(-2.0 * abs(z))
    return math.copysign(-e / (2.0 + e), z)


@jit
def coupler_branch(y: float, s: float, ke: float, kf: float, kec: float, kfc: float):
    """
    Return the branch of the law at y [m] for a friction sign s (sgn or tanh of ydot).

    Returns (F [N], dF/dy [N/m], k_fr), k_fr = -k_f (buffers) or +k_fc (draw gear), so that
    the friction part of F is k_fr s y.

    y < 0: F = (k_e - k_f s) y (eq. 2 / 15); y > 0: F = (k_ec + k_fc s) y (eq. 3 / 16);
    y = 0: F = 0 (sgn 0 = 0 in eq. 4), dF/dy the mean of both branches. Selects, not
    jumps: y changes sign often in a long train.
    """
    comp = y < 0.0
    k = ke if comp else kec
    kfr = -kf if comp else kfc
    stiff = k + kfr * s
    if y == 0.0:
        stiff = 0.5 * (ke - kf * s) + 0.5 * (kec + kfc * s)
    return stiff * y, stiff, kfr


@jit
def friction_sign(ydot: float, model: int, u: float):
    """
    Return (s, ds/dydot): s = sgn(ydot) (eq. 1) or tanh(u ydot) (eq. 14), ydot [m/s], u [s/m].

    The friction term's direction in every coupler law (eqs. 2-3, 15-16).
    """
    if model == TANH:
        s = fast_tanh(u * ydot)
        return s, u * (1.0 - s * s)
    return np.sign(ydot), 0.0


@jit
def coupler_force_scalar(y: float, ydot: float, ke: float, kf: float, kec: float, kfc: float,
                         model: int, u: float):
    """
    Return one coupler's (F [N], dF/dy [N/m], dF/dydot [N s/m]) at y [m], ydot [m/s].

    s = sgn(ydot) (eq. 1) or tanh(u ydot) (eq. 14) in the branch law of
    :func:`coupler_branch` (eqs. 2-4 / 15-16).
    """
    s, dsdv = friction_sign(ydot, model, u)
    f, stiff, kfr = coupler_branch(y, s, ke, kf, kec, kfc)
    return f, stiff, kfr * y * dsdv


@jit
def coupler_force(y: np.ndarray, ydot: np.ndarray, ke: np.ndarray, kf: np.ndarray,
                  kec: np.ndarray, kfc: np.ndarray, model: int, u: float) -> np.ndarray:
    """
    Return the force F(y, ydot) [N] of every coupler, eq. (4) = (2) + (3), or (15) + (16).

    y [m], ydot [m/s], stiffness/friction constants [N/m] per coupler, u [s/m].
    """
    out = np.empty(y.shape[0])
    for j in range(y.shape[0]):
        out[j] = coupler_force_scalar(y[j], ydot[j], ke[j], kf[j], kec[j], kfc[j], model, u)[0]
    return out


@jit
def coupler_force_jacobian(y: np.ndarray, ydot: np.ndarray, ke: np.ndarray, kf: np.ndarray,
                           kec: np.ndarray, kfc: np.ndarray, model: int, u: float):
    """
    Return the partial derivatives (dF/dy [N/m], dF/dydot [N s/m]) of every coupler's force.

    dF/dy is the branch stiffness k +- k_friction s(ydot). dF/dydot is the friction
    term's u k_friction |y| sech^2(u ydot) for ``tanh``: the stiff part of the system
    (about 1.4e6 * 0.02 * 1e4 = 3e8 N s/m at u = 1e4). For ``sign`` it is 0 (the
    derivative is a Dirac at ydot = 0): the sign model's friction is then treated
    explicitly, as a fixed-step code treats it, which is what makes it chatter.
    """
    dfdy = np.empty(y.shape[0])
    dfdv = np.empty(y.shape[0])
    for j in range(y.shape[0]):
        _, dfdy[j], dfdv[j] = coupler_force_scalar(y[j], ydot[j], ke[j], kf[j], kec[j], kfc[j],
                                                   model, u)
    return dfdy, dfdv


@jit
def net_force(F: np.ndarray, i: int, n_couplers: int) -> float:
    """
    Return the couplers' resultant on coach i, F_{i-1} - F_i [N] (eqs. 5-7).

    0-based: coupler j joins coaches j and j+1, so the front coach (i = 0) and the last
    (i = n_couplers) have one coupler each. Only F[:n_couplers] is read.
    """
    f = 0.0
    if i > 0:
        f += F[i - 1]
    if i < n_couplers:
        f -= F[i]
    return f


@jit
def net_forces(F: np.ndarray) -> np.ndarray:
    """Return the couplers' resultant on every coach [N] (N = len(F) + 1), eqs. (5)-(7)."""
    n = F.shape[0]
    out = np.empty(n + 1)
    for i in range(n + 1):
        out[i] = net_force(F, i, n)
    return out


@jit
def elastic_energy(y: np.ndarray, ke: np.ndarray, kec: np.ndarray) -> np.ndarray:
    """Energy stored in the springs of each coupler [J]: k_e y^2/2 (y<0), k_ec y^2/2 (y>0)."""
    return np.where(y < 0.0, 0.5 * ke * y * y, 0.5 * kec * y * y)


# ------------------------------------------------------------------ free play and blocking
@jit(inline=True)
def table_force(cpl, j: int, d: float, d1_row: int, ih_row: int, e_row: int, r_row: int):
    """
    Return (E [N], R [N], dE/dd [N/m], dR/dd [N/m]) of coupling j's table at deflection d >= 0.

    The table of a coupling with a preloaded or progressive end (rows of ``layout.COUPLER``,
    built by :func:`train_dynamics.physics.characteristics.coupling_table`): knot 0 at d = 0
    (E = R = 0), knot 1 at d_1 (the end of the preload ramp), knots 2 .. K-1 equally spaced up
    to the coupling's stroke; linear between knots, constant beyond the last (the blocked stiffness
    K_b takes over at the stroke). E is the elastic (mean) force, R the friction amplitude:
    the loading branch is E + R, the unloading branch E - R.
    """
    d1 = cpl[d1_row, j]
    if d <= d1 and d1 > 0.0:
        se = cpl[e_row + 1, j] / d1
        sr = cpl[r_row + 1, j] / d1
        return se * d, sr * d, se, sr
    t = (d - d1) * cpl[ih_row, j]
    last = TABLE_KNOTS - 2          # intervals after knot 1
    if t >= last:
        return cpl[e_row + TABLE_KNOTS - 1, j], cpl[r_row + TABLE_KNOTS - 1, j], 0.0, 0.0
    i = int(t)
    w = t - i
    e0 = cpl[e_row + 1 + i, j]
    e1 = cpl[e_row + 2 + i, j]
    r0 = cpl[r_row + 1 + i, j]
    r1 = cpl[r_row + 2 + i, j]
    ih = cpl[ih_row, j]
    return e0 + w * (e1 - e0), r0 + w * (r1 - r0), (e1 - e0) * ih, (r1 - r0) * ih


@jit
def coupler_branch_table(y: float, s: float, gt: float, gc: float, st: float, sc: float,
                         kb: float, cpl, j: int):
    """
    Return (F [N], dF/dy [N/m], friction amplitude [N]) of coupling j's tabled law at y [m].

    The law of :func:`coupler_branch_travel` with the tables of :func:`table_force` for the
    springs: y > g_t: d = y - g_t, F = E_t(d) + s R_t(d); y < -g_c: a = -(y + g_c),
    F = -(E_c(a) - s R_c(a)) (friction opposing the motion as in eqs. 2-3); blocking beyond
    the strokes adds K_b as there; 0 in free play (a tight coupling at y = 0: the mean slope
    of both sides).
    """
    if y > gt:
        d = y - gt
        e, r, de, dr = table_force(cpl, j, d, C_T_D1, C_T_IH, C_T_E0, C_T_R0)
        f = e + s * r
        stiff = de + s * dr
        if d > st:
            f += kb * (d - st)
            stiff += kb
        return f, stiff, r
    if y < -gc:
        d = y + gc
        e, r, de, dr = table_force(cpl, j, -d, C_C_D1, C_C_IH, C_C_E0, C_C_R0)
        f = s * r - e
        stiff = de - s * dr
        if d < -sc:
            f += kb * (d + sc)
            stiff += kb
        return f, stiff, r
    if gt == 0.0 and gc == 0.0:
        _, _, det, drt = table_force(cpl, j, 0.0, C_T_D1, C_T_IH, C_T_E0, C_T_R0)
        _, _, dec, drc = table_force(cpl, j, 0.0, C_C_D1, C_C_IH, C_C_E0, C_C_R0)
        return 0.0, 0.5 * (det + s * drt) + 0.5 * (dec - s * drc), 0.0
    return 0.0, 0.0, 0.0


@jit
def coupler_branch_travel(y: float, s: float, ke: float, kf: float, kec: float, kfc: float,
                          gt: float, gc: float, st: float, sc: float, kb: float):
    """
    Return the branch of the extended law at y [m]: (F [N], dF/dy [N/m], k_fr d [N/m * m]).

    Slack g_t (draw gear), g_c (buffers) [m], strokes S_t, S_c [m], blocked stiffness K_b
    [N/m]; the friction part of F is k_fr d s, so k_fr d is its amplitude:

    - y > g_t: d = y - g_t, F = (k_ec + k_fc s) d + K_b max(d - S_t, 0)
    - y < -g_c: d = y + g_c, F = (k_e - k_f s) d + K_b min(d + S_c, 0)
    - otherwise free play: F = 0, dF/dy = 0.

    With no slack at all it is :func:`coupler_branch` (eqs. 2-4 / 15-16) with the same
    arithmetic (bit for bit below the strokes), y = 0 included. Blocking adds K_b to the
    slope, so the integrator's stage matrix sees the stiff block. A coupling with a
    preloaded or progressive end (``cpl[COUPLER.TAB, j]`` set) has its tables instead of the
    linear springs: :func:`coupler_branch_table` (the callers choose: no array reaches this
    function, whose calls stay free of reference counting).
    """
    if y > gt:
        d = y - gt
        k = kec
        kfr = kfc
    elif y < -gc:
        d = y + gc
        k = ke
        kfr = -kf
    else:
        if gt == 0.0 and gc == 0.0:      # y == 0 of the tight coupling: the paper's law
            stiff = 0.5 * (ke - kf * s) + 0.5 * (kec + kfc * s)
            return stiff * y, stiff, 0.0
        return 0.0, 0.0, 0.0
    stiff = k + kfr * s
    f = stiff * d
    if d > st:
        f += kb * (d - st)
        stiff += kb
    elif d < -sc:
        f += kb * (d + sc)
        stiff += kb
    return f, stiff, kfr * d


@jit
def coupler_force_travel_scalar(y: float, ydot: float, ke: float, kf: float, kec: float,
                                kfc: float, gt: float, gc: float, st: float, sc: float,
                                kb: float, model: int, u: float):
    """
    Return (F [N], dF/dy [N/m], dF/dydot [N s/m]) of one coupler with free play and blocking.

    s = sgn(ydot) (eq. 1) or tanh(u ydot) (eq. 14) in :func:`coupler_branch_travel`.
    """
    s, dsdv = friction_sign(ydot, model, u)
    f, stiff, amp = coupler_branch_travel(y, s, ke, kf, kec, kfc, gt, gc, st, sc, kb)
    return f, stiff, amp * dsdv


@jit
def coupler_force_table_scalar(y: float, ydot: float, gt: float, gc: float, st: float,
                               sc: float, kb: float, model: int, u: float, cpl, j: int):
    """
    Return (F [N], dF/dy [N/m], dF/dydot [N s/m]) of tabled coupler j (``cpl`` its tables).

    s = sgn(ydot) (eq. 1) or tanh(u ydot) (eq. 14) in :func:`coupler_branch_table`.
    """
    s, dsdv = friction_sign(ydot, model, u)
    f, stiff, amp = coupler_branch_table(y, s, gt, gc, st, sc, kb, cpl, j)
    return f, stiff, amp * dsdv


@jit
def coupler_force_any(y: float, ydot: float, ke: float, kf: float, kec: float, kfc: float,
                      gt: float, gc: float, st: float, sc: float, kb: float, model: int,
                      u: float, cpl, j: int):
    """Return :func:`coupler_force_table_scalar` for a tabled coupler j, else the linear law's."""
    if cpl[C_TAB, j] != 0.0:
        return coupler_force_table_scalar(y, ydot, gt, gc, st, sc, kb, model, u, cpl, j)
    return coupler_force_travel_scalar(y, ydot, ke, kf, kec, kfc, gt, gc, st, sc, kb, model, u)


@jit
def coupler_force_travel(y: np.ndarray, ydot: np.ndarray, ke: np.ndarray, kf: np.ndarray,
                         kec: np.ndarray, kfc: np.ndarray, gt: np.ndarray, gc: np.ndarray,
                         st: np.ndarray, sc: np.ndarray, kb: np.ndarray, model: int,
                         u: float, cpl: np.ndarray) -> np.ndarray:
    """
    Return the force F [N] of every coupler with free play and blocking (arrays of N-1).

    ``cpl``: (len(COUPLER), N-1), whose table rows are read (TAB = 0: the linear law).
    """
    out = np.empty(y.shape[0])
    for j in range(y.shape[0]):
        out[j] = coupler_force_any(y[j], ydot[j], ke[j], kf[j], kec[j], kfc[j], gt[j], gc[j],
                                   st[j], sc[j], kb[j], model, u, cpl, j)[0]
    return out


@jit
def coupler_jacobian_travel(y: np.ndarray, ydot: np.ndarray, ke: np.ndarray, kf: np.ndarray,
                            kec: np.ndarray, kfc: np.ndarray, gt: np.ndarray, gc: np.ndarray,
                            st: np.ndarray, sc: np.ndarray, kb: np.ndarray, model: int,
                            u: float, cpl: np.ndarray):
    """Return (dF/dy [N/m], dF/dydot [N s/m]) of every coupler with free play and blocking."""
    dfdy = np.empty(y.shape[0])
    dfdv = np.empty(y.shape[0])
    for j in range(y.shape[0]):
        _, dfdy[j], dfdv[j] = coupler_force_any(y[j], ydot[j], ke[j], kf[j], kec[j], kfc[j],
                                                gt[j], gc[j], st[j], sc[j], kb[j], model, u,
                                                cpl, j)
    return dfdy, dfdv
