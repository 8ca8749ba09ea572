"""
The couplers' rows of the workspace: force, slopes and stage weights at the chain's state.

Each coupler's law (:mod:`.couplers`, with free play and blocking) is evaluated at its
(y, ydot) into the WORK rows F, DFDY and KK (the stage-matrix weights g h dF/dydot +
(g h)^2 dF/dy) that :func:`~.rosenbrock2.ros2_step` solves with. Cache (bit for bit): the rows
carry the (y, ydot) and g h they were made for (WORK.YKEY, VKEY), so a coupler whose
state did not change keeps them (:func:`invalidate_caches` forgets them all).
:func:`eval_couplers_work` also books the couplers' work over the step and widens the
in-train force envelope (WORK.FHI, FLO).
"""
from __future__ import annotations

import math

import numpy as np

from train_dynamics.physics.kernel import couplers
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import COUPLER, STATE, WORK
from train_dynamics.physics.kernel.rosenbrock2 import GAMMA

#: [-] a coupler whose step reaches its blocked branch has the blocked slope k + K_b in the
#: stage matrix when the slope it lacks would weigh more than this fraction of its reduced
#: mass there, (g h)^2 (k + K_b - dF/dy) > BLOCK_WEIGHT mu: (g h)^2 K / mu = g^2 (h w)^2, so
#: 0.25 lets at most h w = 0.29 of a block be explicit (ROS2 without its matrix is explicit
#: and unstable on an undamped spring; at h w = 6, K_b = 1e12 N/m at 2 ms, a chain of
#: blocking impacts gained energy without bound). The shipped trains (K_b = 1e8 N/m per
#: coupling, 2 ms, >= 22 t reduced mass) stay below 0.06: their steps are never redone.
BLOCK_WEIGHT = 0.25


@jit(inline=True)
def invalidate_caches(ws):
    """
    Forget the static resistance cached per vehicle (WORK.XKEY, see :func:`static_resistance`).

    Call it when a vehicle's resistance constants or the track change without a new
    simulator (nothing does today: they are fixed per simulator, reset() rewrites the same
    values). The couplers' cache (WORK.YKEY, VKEY) is renewed by every :func:`eval_couplers`.
    """
    xkey = ws[WORK.XKEY]
    for i in range(xkey.shape[0]):
        xkey[i] = np.nan


@jit
def _coupler_w(y, ydot, ke, kf, kec, kfc, gt, gc, st, sc, kb, model, u, h):
    """
    Return one coupler's F [N], dF/dy [N/m] and the dF/dydot [N s/m] of the stage matrix.

    The stage matrix takes, for the tanh model (eq. 14), the secant slope of the friction
    force through ydot = 0, k_fr |y| tanh(u ydot) / ydot, not the tangent
    u k_fr |y| sech^2(u ydot): a step that carries ydot across the 1/u-wide tanh band then
    still sees the friction's damping (the tangent is ~0 outside the band, which made the
    friction explicit exactly there and overshot the peak force of long trains by 10 % at
    5 ms). ROS2 is a W-method: order 2 holds for any matrix. Both slopes agree as
    ydot -> 0. The sign model keeps 0. The law has free play (slack g_t, g_c [m]) and blocks
    at the strokes S_t, S_c [m] with stiffness K_b [N/m], which dF/dy then includes
    (:func:`couplers.coupler_branch_travel`; with no slack and below the strokes it is the
    paper's law bit for bit).
    """
    if model == couplers.TANH:
        z = u * ydot
        a = abs(z)
        t = couplers.fast_tanh(a)               # tanh|z|
        s = math.copysign(t, z)
        ratio = t / a if a > 1e-3 else 1.0     # tanh(z) / z, within 4e-7 of 1 below 1e-3
    else:
        s = np.sign(ydot)
        ratio = 0.0
    f, stiff, amp = couplers.coupler_branch_travel(y, s, ke, kf, kec, kfc, gt, gc, st, sc, kb)
    return f, _travel_slope(y, ydot, h, stiff, ke, kec, gt, gc, st, sc, kb), amp * u * ratio


@jit(inline=True)
def _sign_ratio(ydot, model, u):
    """
    Return (s, tanh(u ydot) / (u ydot)) of the tanh model (eq. 14), (sgn ydot, 0) of sign.

    As :func:`_coupler_w` computes them (written there too: the linear law's hot path).
    """
    if model == couplers.TANH:
        z = u * ydot
        a = abs(z)
        t = couplers.fast_tanh(a)               # tanh|z|
        s = math.copysign(t, z)
        ratio = t / a if a > 1e-3 else 1.0     # tanh(z) / z, within 4e-7 of 1 below 1e-3
    else:
        s = np.sign(ydot)
        ratio = 0.0
    return s, ratio


@jit
def _coupler_w_table(y, ydot, gt, gc, st, sc, kb, model, u, h, cpl, j):
    """
    Return :func:`_coupler_w` of tabled coupler j (preloaded or progressive ends, ``cpl``).

    The law is :func:`couplers.coupler_branch_table`; the stage matrix takes the secant of
    its elastic force when the step crosses the end of the free play, of a stroke or of the
    preload ramp (:func:`_travel_slope`'s rule), else the tangent.
    """
    s, ratio = _sign_ratio(ydot, model, u)
    f, stiff, amp = couplers.coupler_branch_table(y, s, gt, gc, st, sc, kb, cpl, j)
    yp = y + h * ydot
    lo = min(y, yp)
    hi = max(y, yp)
    cross = ((lo < gt + st < hi) or (lo < -(gc + sc) < hi) or (lo < gt < hi)
             or (lo < -gc < hi) or (lo < gt + cpl[COUPLER.T_D1, j] < hi)
             or (lo < -(gc + cpl[COUPLER.C_D1, j]) < hi))
    if cross:
        stiff = (couplers.coupler_branch_table(yp, 0.0, gt, gc, st, sc, kb, cpl, j)[0]
                 - couplers.coupler_branch_table(y, 0.0, gt, gc, st, sc, kb, cpl, j)[0]) / (
                     yp - y)
    return f, stiff, amp * u * ratio


@jit
def _elastic_travel(y, ke, kec, gt, gc, st, sc, kb):
    """Return the elastic (friction-free) force [N] of the law with free play and blocking."""
    if y > gt:
        d = y - gt
        return kec * d + kb * max(d - st, 0.0)
    if y < -gc:
        d = y + gc
        return ke * d + kb * min(d + sc, 0.0)
    return 0.0


@jit(inline=True)
def _travel_slope(y, ydot, h, stiff, ke, kec, gt, gc, st, sc, kb):
    """
    Return the dF/dy [N/m] of the stage matrix: the secant over the step's predicted move.

    When y + h ydot crosses the end of the free play (g_t or g_c > 0) or a stroke, the
    tangent at y (0 in free play, k before blocking) would leave the stiff contact
    explicit for the whole step: the secant of the elastic force between y and y + h ydot
    puts it in the matrix (K_b when the step blocks). ROS2 is a W-method, so any slope keeps
    order two. Without a crossing: the tangent ``stiff``.
    """
    yp = y + h * ydot
    lo = min(y, yp)
    hi = max(y, yp)
    cross = (lo < gt + st < hi) or (lo < -(gc + sc) < hi)
    if gt > 0.0:
        cross = cross or (lo < gt < hi)
    if gc > 0.0:
        cross = cross or (lo < -gc < hi)
    if not cross:
        return stiff
    return (_elastic_travel(yp, ke, kec, gt, gc, st, sc, kb)
            - _elastic_travel(y, ke, kec, gt, gc, st, sc, kb)) / (yp - y)


@jit
def _store_coupler_table(j, y, ydot, cpl, model, u, gh, ws):
    """Do :func:`_store_coupler` for tabled coupler j (:func:`_coupler_w_table`)."""
    f, dy, dv = _coupler_w_table(y, ydot, cpl[COUPLER.GT, j], cpl[COUPLER.GC, j],
                                 cpl[COUPLER.ST, j], cpl[COUPLER.SC, j], cpl[COUPLER.KB, j],
                                 model, u, gh / GAMMA, cpl, j)
    ws[WORK.F, j] = f
    ws[WORK.DFDY, j] = dy
    ws[WORK.KK, j] = gh * dv + gh * gh * dy
    ws[WORK.YKEY, j] = y
    ws[WORK.VKEY, j] = ydot


@jit(inline=True)
def _store_coupler(j, y, ydot, cpl, model, u, gh, ws):
    """
    Write coupler j's F [N], dF/dy [N/m] and stage-matrix weight [kg] at (y, ydot) to ws.

    Force law eqs. (2)-(4) / (14)-(16) with the constants of ``cpl`` [N/m]; the weight is
    g h dF/dydot + (g h)^2 dF/dy (rows WORK.F, DFDY, KK). (y, ydot) go to WORK.YKEY, VKEY:
    the key of :func:`eval_couplers_work`'s cache.
    """
    if cpl[COUPLER.TAB, j] != 0.0:       # preloaded or progressive ends: the tables
        _store_coupler_table(j, y, ydot, cpl, model, u, gh, ws)
        return
    f, dy, dv = _coupler_w(y, ydot, cpl[COUPLER.KE, j], cpl[COUPLER.KF, j],
                           cpl[COUPLER.KEC, j], cpl[COUPLER.KFC, j], cpl[COUPLER.GT, j],
                           cpl[COUPLER.GC, j], cpl[COUPLER.ST, j], cpl[COUPLER.SC, j],
                           cpl[COUPLER.KB, j], model, u, gh / GAMMA)
    ws[WORK.F, j] = f
    ws[WORK.DFDY, j] = dy
    ws[WORK.KK, j] = gh * dv + gh * gh * dy
    ws[WORK.YKEY, j] = y
    ws[WORK.VKEY, j] = ydot


@jit(inline=True)
def eval_couplers(x, v, cpl, model, u, gh, ws):
    """
    Write every coupler's law at (x, v) to ws (:func:`_store_coupler`; y from eq. 9).

    g h [s] goes to column N-1 of WORK.VKEY: with the couplers' (y, ydot), the key of
    :func:`eval_couplers_work`'s cache.
    """
    n = x.shape[0]
    for j in range(n - 1):
        _store_coupler(j, x[j] - x[j + 1], v[j] - v[j + 1], cpl, model, u, gh, ws)
    ws[WORK.VKEY, n - 1] = gh


@jit
def eval_couplers_work(coach, cpl, model, u, gh, ws):
    """
    Do :func:`eval_couplers` at the new state (STATE.X, V); return the couplers' work [J].

    The work over the step from the positions WORK.XOLD [m] is trapezoidal in the force:
    sum_j (F_j(old) + F_j(new)) / 2 (y_j(new) - y_j(old)). A coupler whose (y, ydot) and
    g h are those its rows were evaluated at (WORK.YKEY, VKEY: e.g. between two vehicles
    held at rest) keeps them: the law is a function of these alone (and of the model and
    the constants, which change only with CACHE.WS_VALID = 0, then :func:`eval_couplers`).
    Every accepted step's forces also widen the in-train force envelope WORK.FHI, FLO (the
    largest tension and compression of each coupler [N], at the integrator's resolution:
    an impact's peak between two outputs included).
    """
    x = coach[STATE.X]
    v = coach[STATE.V]
    x_old = ws[WORK.XOLD]
    F0 = ws[WORK.F]
    ykey = ws[WORK.YKEY]
    vkey = ws[WORK.VKEY]
    f_hi = ws[WORK.FHI]
    f_lo = ws[WORK.FLO]
    wc = 0.0
    n = x.shape[0]
    same_gh = vkey[n - 1] == gh
    for j in range(n - 1):
        y = x[j] - x[j + 1]
        ydot = v[j] - v[j + 1]
        f_old = F0[j]
        if not (same_gh and y == ykey[j] and ydot == vkey[j]):
            _store_coupler(j, y, ydot, cpl, model, u, gh, ws)
        f = F0[j]
        wc += 0.5 * (f_old + f) * (y - (x_old[j] - x_old[j + 1]))
        if f > f_hi[j]:
            f_hi[j] = f
        elif f < f_lo[j]:
            f_lo[j] = f
    vkey[n - 1] = gh
    return wc


@jit(inline=True)
def raise_blocked_slopes(h, x, v, masses, cpl, ws):
    """
    Put the blocked slope in the stage matrix of the couplers the step just solved blocks.

    The slope of the stage matrix is chosen at the step's start (:func:`_travel_slope`:
    the tangent, or the secant over the move y + h ydot predicted from the coupler's own
    speed). In a chain of impacts a coupler is driven into its block within the step by its
    neighbours' motion: the blocked stiffness K_b [N/m] then acts only through the stage-2
    force, explicitly. A coupler whose step (y at the start, at the stage-2 point
    y + h a1 and at the end, from WORK.B1, XNEW; x, v [m, m/s] the start, h [s]) reaches a
    blocked branch takes that branch's slope k + K_b into WORK.DFDY and KK when the slope
    it lacks weighs more than BLOCK_WEIGHT of its reduced mass ``masses`` [kg]
    (:data:`BLOCK_WEIGHT`); its rows are no longer those of its state (WORK.YKEY = NaN).
    ROS2 is a W-method: any matrix keeps its order, and a stiffer one damps the stiff mode
    (L-stable). Return how many couplers took it: the caller solves the step again.
    """
    gh = GAMMA * h
    b1 = ws[WORK.B1]
    x_new = ws[WORK.XNEW]
    dfdy = ws[WORK.DFDY]
    kk = ws[WORK.KK]
    ykey = ws[WORK.YKEY]
    raised = 0
    for j in range(x.shape[0] - 1):
        y = x[j] - x[j + 1]
        y2 = y + h * (v[j] - v[j + 1] + gh * (b1[j] - b1[j + 1]))
        ye = x_new[j] - x_new[j + 1]
        hi = max(y, max(y2, ye))
        lo = min(y, min(y2, ye))
        k = 0.0
        if hi > cpl[COUPLER.GT, j] + cpl[COUPLER.ST, j]:
            k = cpl[COUPLER.KEC, j] + cpl[COUPLER.KB, j]
        if lo < -(cpl[COUPLER.GC, j] + cpl[COUPLER.SC, j]):
            k = max(k, cpl[COUPLER.KE, j] + cpl[COUPLER.KB, j])
        lack = gh * gh * (k - dfdy[j])
        if lack > BLOCK_WEIGHT * masses[j] * masses[j + 1] / (masses[j] + masses[j + 1]):
            kk[j] += lack
            dfdy[j] = k
            ykey[j] = np.nan
            raised += 1
    return raised
