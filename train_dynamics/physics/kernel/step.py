"""
The step of the coach chain, in named pieces shared by both drivers.

Fixed step: **ROS2**, the two-stage, second-order, L-stable Rosenbrock method of Verwer,
Spee, Blom and Hundsdorfer (SIAM J. Sci. Comput. 20, 1999), gamma = 1 + 1/sqrt(2).

Why this method: the tanh friction term makes the chain stiff. Its derivative with respect
to the coupler velocity is u k_f |y| sech^2(u ydot), about 1.4e6 * 0.02 * 1e3 = 3e7 N s/m at
u = 1e3 and ten times that at u = 1e4; on a 22.5 t reduced mass that is a decay rate of
1e3 - 1e4 1/s, so an explicit method would need steps of ~1e-5 s. A Rosenbrock method solves
one linear system per stage with the exact Jacobian instead of iterating Newton to
convergence: deterministic cost per step, no convergence failure. L-stability damps the
stiff friction modes in one step instead of letting them ring (the trapezoidal rule would
ring, and ringing around ydot = 0 is exactly the chattering the paper warns of). ROS2 keeps
order two for any Jacobian approximation (it is a W-method), so the sign model, whose
friction has no usable derivative, still integrates consistently: its friction is then
explicit and chatters around ydot = 0 as the paper reports, bounded by k_f |y|.

The Jacobian of the chain is block structured: d(x')/dv = I and
M d(v')/d(x, v) = -(D^T K D, D^T C D) with K = diag(dF/dy), C = diag(dF/dydot), so the stage
equations reduce to one tridiagonal system in the velocity stage,
(M + g h C_c + g^2 h^2 K_c) b = rhs, solved in O(N) by the Thomas algorithm (the matrix is
diagonally dominant: masses on the diagonal, k > k_friction in every branch).

Braking is friction: a coach at rest stays at rest while the braking force can hold it
(|net coupler force| <= Fb), and the brake never pushes a coach backwards. The step treats
resting coaches as held (their rows fixed at zero velocity) and finds the set of held
coaches by a short, capped active-set iteration: a moving coach whose velocity would change
sign is stopped; then the coaches at rest whose required holding force exceeds the
available braking force make the holding a box-constrained LCP on the stage matrix
(:mod:`.standstill`), whose set the step is solved with once more; a
coach released from rest that ends the step moving against its brake sticks. Momentum
bookkeeping is exact: the held coaches' brake force is the one that the stage equations
require.

One step, in named parts (the drivers: :mod:`.fixed_step` and :mod:`.adaptive`):

1. :func:`brake_system_step`: brake pipe, distributors and cylinders to t + h (they do not
   depend on the motion);
2. :func:`braking_force_trapezoid`: the braking force over the step, eq. (13);
3. :func:`active_set_step`: :func:`ros2_step` with the active set of held coaches
   (:func:`_signed_brake`, :func:`_hold_stopping`, :func:`_settle`); the fixed-step driver
   skips it at a standstill whose inputs did not change (it would repeat the last step
   exactly);
4. :func:`fault_check`, then :func:`accept_step` and the couplers at the new state
   (:func:`eval_couplers_work`, which keeps a coupler's law where its (y, ydot) did not
   change).

Caches (results bit for bit): the couplers' rows carry their (y, ydot) (WORK.YKEY, VKEY),
the static resistance and gradient force their position (WORK.XKEY,
:func:`static_resistance`); the fixed-step driver's standstill cache is described in
:mod:`.fixed_step`.

The packed arrays the kernel works on are laid out in :mod:`.layout`.
Speed: the steps take the packed arrays and are inlined into the drivers by numba
(``@jit(inline=True)``, as are the brake-system functions they call). A compiled function
that takes arrays, or makes row views, pays their reference counting at every call, and
a call left inside an inlined step stops LLVM from removing that counting: split into
ordinary calls, a 3-coach step ran 1.5-2 times slower.
"""
from __future__ import annotations

import math

import numpy as np

from train_dynamics.physics.kernel import brakes, couplers, standstill, traction
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import (CLOCK, COUNT, COUPLER, INPUT, OPTION, OUTPUT,
                                                  PARAM, SCALAR_INPUT, STATE, TOTAL, VEHICLE, WORK)
from train_dynamics.physics.kernel.track import profile_mean

GAMMA = 1.0 + 1.0 / np.sqrt(2.0)

#: chain solves per step at most: the first, then after stops or a new holding set
HOLD_SOLVES = 6
#: tridiagonal solves of one holding LCP at most (standstill.pivot)
HOLD_PIVOTS = 12

#: [m/s] a braked coach slower than this is at rest (standstill.V_REST)
V_REST = standstill.V_REST

OK = 0
NON_FINITE = 1
OUT_OF_RANGE = 2
STATUS_TEXT = {
    NON_FINITE: 'state became non-finite at t = {t:.4f} s; integration stopped',
    OUT_OF_RANGE: 'a coupler displacement left the physically possible range at '
                  't = {t:.4f} s; integration stopped',
}


def make_workspace(n: int) -> np.ndarray:
    """Return the kernel's scratch memory for n coaches: len(WORK) rows of n."""
    ws = np.zeros((len(WORK), n))
    invalidate_caches(ws)
    return ws


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


# ----------------------------------------------------------------------------- couplers
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


@jit(inline=True)
def _store_coupler(j, y, ydot, cpl, model, u, gh, ws):
    """
    Write coupler j's F [N], dF/dy [N/m] and stage-matrix weight [kg] at (y, ydot) to ws.

    Force law eqs. (2)-(4) / (14)-(16) with the constants of ``cpl`` [N/m]; the weight is
    g h dF/dydot + (g h)^2 dF/dy (rows WORK.F, DFDY, KK). (y, ydot) go to WORK.YKEY, VKEY:
    the key of :func:`eval_couplers_work`'s cache.
    """
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


# ----------------------------------------------------------------------------- external
@jit(inline=True)
def _stage_external(coach, x, v, h, ws, gx, gv, gc, track, row_gr, row_rd, row_tr, row_e):
    """
    Write the external forces of every vehicle at a stage's point to four WORK rows.

    The point is (x + h (v + g h b1), v + h b1) with b1 = WORK.B1: stage 1 for h = 0,
    stage 2 for the step h [s]. Forces [N]:
    the gradient -m g (mean gradient over the vehicle) / 1000 (``track``; at stage 1 the
    WORK.GR1 that :func:`external_step` left, the same position), the speed-dependent
    resistance d (B |v| + C v^2) against the friction's direction d (Davis; A is with the
    brake), traction (``traction.traction_force``), and E = gradient + traction -
    resistance. At stage 2 a vehicle that has not moved (a held one) keeps stage 1's gradient
    force. (Written out here, not in a called function: a per-vehicle call cost the step
    more than the forces themselves.)
    """
    gh = GAMMA * h
    grades = track and gx.shape[0] > 0
    b1 = ws[WORK.B1]
    v_start = ws[WORK.VSTART]
    rel_dir = ws[WORK.RELDIR]
    t_eff = ws[WORK.TEFF]
    davis_b = coach[VEHICLE.DAVIS_B]
    davis_c = coach[VEHICLE.DAVIS_C]
    gr1 = ws[WORK.GR1]
    out_gr = ws[row_gr]
    out_rd = ws[row_rd]
    out_tr = ws[row_tr]
    out_e = ws[row_e]
    for i in range(x.shape[0]):
        xi = x[i]
        vi = v[i]
        if h != 0.0:
            b = b1[i]
            xi += h * (vi + gh * b)
            vi += h * b
        vs = v_start[i]      # the friction acts against this (the brake's direction)
        d = 1.0 if vs > 0.0 else (-1.0 if vs < 0.0 else rel_dir[i])
        sv = abs(vi)
        rd = d * (davis_b[i] + davis_c[i] * sv) * sv
        gr = out_gr[i] if h == 0.0 else 0.0     # stage 1: from external_step
        if grades and h != 0.0:
            if xi == x[i]:      # not moved: the same point as stage 1
                gr = gr1[i]
            else:
                hi = coach[VEHICLE.FRONT0, i] + xi
                gr = -coach[VEHICLE.WEIGHT, i] * 1e-3 * profile_mean(
                    hi - coach[VEHICLE.LENGTH, i], hi, gx, gv, gc)
        tr = 0.0
        teff = t_eff[i]
        if teff != 0.0:
            tr = traction.traction_force(
                teff, vi, coach[VEHICLE.T_FORCE, i], coach[VEHICLE.T_POWER, i],
                coach[VEHICLE.DB_FORCE, i], coach[VEHICLE.DB_POWER, i], coach[VEHICLE.DB_FADE, i],
                coach[VEHICLE.T_ADH, i], coach[VEHICLE.WEIGHT, i])
        out_gr[i] = gr
        out_rd[i] = rd
        out_tr[i] = tr
        out_e[i] = gr + tr - rd


# ----------------------------------------------------------------------------- ROS2
@jit(inline=True)
def ros2_step(h, coach, cpl, model, u, held, ws, ext, track, gprof):
    """
    Do one ROS2 step of eqs. (5)-(7) from (x, v) with the coaches in ``held`` at rest.

    x = STATE.X [m], v = WORK.VSTART [m/s]; brake = WORK.SIGNED [N], the signed braking
    force on the moving coaches (positive retarding). The couplers' forces and Jacobian at
    (x, v) must be in ws (:func:`eval_couplers`).
    Leaves the new state in WORK.XNEW, VNEW and in WORK.HOLD the holding force [N] the
    stage equations require of each held coach (signed, positive retarding; 0 on moving
    coaches). Stage equations, with A = M + g h C_c + (g h)^2 K_c [kg] (tridiagonal):

      A b1 = g(x, v) - g h K_c v - Fb,                        a1 = v + g h b1
      A b2 = g(x + h a1, v + h b1) - 2 M b1 - g h K_c r - Fb,  r = v + h b1 - 2 a1,
                                                               a2 = r + g h b2
      x' = x + h (3/2 a1 + 1/2 a2),  v' = v + h (3/2 b1 + 1/2 b2),

    g the net coupler force of eqs. (5)-(7) (:func:`couplers.net_force`, summed here in the
    same branches as the stage matrix: a call per coach cost ~5 % at 1000 coaches), plus
    (``ext``) the external forces E: gradient, traction and the speed-dependent resistance
    at each stage's point (the brake and the static resistance A + curve are in Fb). A held
    coach's row becomes b_i = 0; its holding force is the mean over both stages of the
    residual its free row would leave. Written as fused loops (one pass: assembly, LU
    factorisation and forward substitution) in the caller's scratch rows: no allocation.
    """
    x = coach[STATE.X]
    v = ws[WORK.VSTART]
    masses = coach[VEHICLE.MASS]
    brake = ws[WORK.SIGNED]
    ke = cpl[COUPLER.KE]
    kf = cpl[COUPLER.KF]
    kec = cpl[COUPLER.KEC]
    kfc = cpl[COUPLER.KFC]
    gt = cpl[COUPLER.GT]
    gc = cpl[COUPLER.GC]
    st = cpl[COUPLER.ST]
    scs = cpl[COUPLER.SC]
    kb = cpl[COUPLER.KB]
    gx = gprof[0]
    gv = gprof[1]
    gpc = gprof[2]
    n = x.shape[0]
    m = n - 1
    gh = GAMMA * h
    hr = h - 2.0 * gh            # r = v + h b1 - 2 a1 = (h - 2 g h) b1 - v
    F0 = ws[WORK.F]
    dfdy = ws[WORK.DFDY]
    kk = ws[WORK.KK]
    diag = ws[WORK.DIAG]       # diagonal of the free rows (for the holding forces)
    lower = ws[WORK.LOWER]     # A[i+1, i] of the effective matrix
    rhs1 = ws[WORK.RHS1]       # right-hand sides of the free rows, brake apart
    rhs2 = ws[WORK.RHS2]
    b1 = ws[WORK.B1]
    b2 = ws[WORK.B2]
    c = ws[WORK.C]
    winv = ws[WORK.WINV]
    F2 = ws[WORK.F2]
    x_new = ws[WORK.XNEW]
    v_new = ws[WORK.VNEW]
    hold = ws[WORK.HOLD]
    e1 = ws[WORK.E1]
    e2 = ws[WORK.E2]
    if ext:       # the external forces at stage 1, (x, v)
        _stage_external(coach, x, v, 0.0, ws, gx, gv, gpc, track, WORK.GR1, WORK.RD1,
                        WORK.TR1, WORK.E1)
    # stage 1: assemble, factor and forward-substitute in one sweep
    for i in range(n):
        d = masses[i]
        g = 0.0
        kv = 0.0
        if i > 0:
            d += kk[i - 1]
            g += F0[i - 1]
            kv += dfdy[i - 1] * (v[i] - v[i - 1])
        if i < m:
            d += kk[i]
            g -= F0[i]
            kv += dfdy[i] * (v[i] - v[i + 1])
        diag[i] = d
        rhs1[i] = g - gh * kv
        if ext:
            rhs1[i] += e1[i]
        if held[i]:
            d = 1.0
            r1 = 0.0
        else:
            r1 = rhs1[i] - brake[i]
        if i == 0:
            winv[0] = 1.0 / d
            b1[0] = r1 * winv[0]
        else:
            up = 0.0 if held[i - 1] else -kk[i - 1]     # A[i-1, i]
            lo = 0.0 if held[i] else -kk[i - 1]         # A[i, i-1]
            lower[i - 1] = lo
            c[i - 1] = up * winv[i - 1]
            winv[i] = 1.0 / (d - lo * c[i - 1])
            b1[i] = (r1 - lo * b1[i - 1]) * winv[i]
    for i in range(n - 2, -1, -1):
        b1[i] -= c[i] * b1[i + 1]
    # stage 2 at (x + h a1, v + h b1), a1 = v + g h b1
    for j in range(m):
        dv = v[j] - v[j + 1]
        db = b1[j] - b1[j + 1]
        f, _, _ = couplers.coupler_force_travel_scalar(
            x[j] - x[j + 1] + h * (dv + gh * db), dv + h * db, ke[j], kf[j], kec[j], kfc[j],
            gt[j], gc[j], st[j], scs[j], kb[j], model, u)
        F2[j] = f
    if ext:       # the external forces at stage 2, (x + h a1, v + h b1)
        _stage_external(coach, x, v, h, ws, gx, gv, gpc, track, WORK.GR2, WORK.RD2,
                        WORK.TR2, WORK.E2)
    for i in range(n):
        g = 0.0
        kr = 0.0
        ri = hr * b1[i] - v[i]
        if i > 0:
            g += F2[i - 1]
            kr += dfdy[i - 1] * (ri - (hr * b1[i - 1] - v[i - 1]))
        if i < m:
            g -= F2[i]
            kr += dfdy[i] * (ri - (hr * b1[i + 1] - v[i + 1]))
        rhs2[i] = g - 2.0 * masses[i] * b1[i] - gh * kr
        if ext:
            rhs2[i] += e2[i]
        r2 = 0.0 if held[i] else rhs2[i] - brake[i]
        if i == 0:
            b2[0] = r2 * winv[0]
        else:
            b2[i] = (r2 - lower[i - 1] * b2[i - 1]) * winv[i]
    for i in range(n - 2, -1, -1):
        b2[i] -= c[i] * b2[i + 1]
    # the new state, and the holding forces the held rows of the stage equations require
    for i in range(n):
        a1 = v[i] + gh * b1[i]
        a2 = hr * b1[i] - v[i] + gh * b2[i]
        x_new[i] = x[i] + h * (1.5 * a1 + 0.5 * a2)
        v_new[i] = v[i] + h * (1.5 * b1[i] + 0.5 * b2[i])
        if not held[i]:
            hold[i] = 0.0
            continue
        ab1 = diag[i] * b1[i]
        ab2 = diag[i] * b2[i]
        if i > 0:
            ab1 -= kk[i - 1] * b1[i - 1]
            ab2 -= kk[i - 1] * b2[i - 1]
        if i < m:
            ab1 -= kk[i] * b1[i + 1]
            ab2 -= kk[i] * b2[i + 1]
        hold[i] = 0.5 * ((rhs1[i] - ab1) + (rhs2[i] - ab2))


# ----------------------------------------------------------------------------- active set
@jit
def _stops(v0, v1, fb):
    """
    Tell whether a moving coach stops within the step.

    Its velocity v0 -> v1 [m/s] changes sign, or a braked coach (fb [N] > 0) ends the step
    slower than V_REST.
    """
    if v0 == 0.0:
        return False
    if v0 * v1 <= 0.0:
        return True
    return fb > 0.0 and abs(v1) < V_REST


@jit(inline=True)
def _signed_brake(ws):
    """
    Sign the braking force over the step against each coach's motion [N] (WORK.SIGNED).

    From WORK.FB, positive retarding; a coach released from rest at this step
    (WORK.VSTART = 0) is braked against the direction WORK.RELDIR it slides in.
    """
    v_start = ws[WORK.VSTART]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    signed = ws[WORK.SIGNED]
    for i in range(v_start.shape[0]):
        if v_start[i] > 0.0:
            signed[i] = fb[i]
        elif v_start[i] < 0.0:
            signed[i] = -fb[i]
        else:
            signed[i] = rel_dir[i] * fb[i]


@jit(inline=True)
def _hold_stopping(held, masses, ws, extra_work, sc):
    """
    Hold the moving coaches that stop within the step from the step's start.

    Their kinetic energy m v^2 / 2 [J] goes to the brakes' work: return (whether any
    stopped, ``extra_work`` plus that energy); their momentum m v [N s] is taken off the
    external impulse (TOTAL.PEXT, ``sc``).
    """
    v_start = ws[WORK.VSTART]
    v_new = ws[WORK.VNEW]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    changed = False
    for i in range(held.shape[0]):
        if (not held[i]) and rel_dir[i] == 0.0 and _stops(v_start[i], v_new[i], fb[i]):
            held[i] = True
            extra_work += 0.5 * masses[i] * v_start[i] * v_start[i]
            sc[TOTAL.PEXT] -= masses[i] * v_start[i]
            v_start[i] = 0.0
            changed = True
    return changed, extra_work


@jit(inline=True)
def _stopping(held, ws):
    """Return how many moving coaches stop within the step (:func:`_hold_stopping` would)."""
    v_start = ws[WORK.VSTART]
    v_new = ws[WORK.VNEW]
    fb = ws[WORK.FB]
    rel_dir = ws[WORK.RELDIR]
    count = 0
    for i in range(held.shape[0]):
        if (not held[i]) and rel_dir[i] == 0.0 and _stops(v_start[i], v_new[i], fb[i]):
            count += 1
    return count


@jit(inline=True)
def _settle(h, held, ws):
    """
    Make the set of the coaches at rest consistent with the step just solved; return changed.

    Nothing to do when every held coach is within its brake
    (:func:`standstill.inconsistent`). Else the holding LCP
    on the step (:func:`standstill.effective_rhs`, :func:`standstill.pivot`, at most
    HOLD_PIVOTS tridiagonal solves) gives the next set. Should it end where it began, the
    coaches over their brake's limit would creep slower than V_REST: at rest (no change),
    or, when the pivoting hit its cap, they are released.
    """
    if standstill.inconsistent(held, ws, False) == 0:
        return False
    rel_dir = ws[WORK.RELDIR]
    before = ws[WORK.LS]
    for i in range(held.shape[0]):
        before[i] = 2.0 if held[i] else rel_dir[i]
    standstill.effective_rhs(h, held, ws)
    solved = standstill.pivot(h, held, ws, HOLD_PIVOTS) > 0
    for i in range(held.shape[0]):
        if (before[i] >= 2.0) != held[i] or (before[i] < 2.0 and before[i] != rel_dir[i]):
            return True
    if solved:      # the held coaches over their limit would creep slower than V_REST
        return False
    standstill.inconsistent(held, ws, True)
    return True


@jit(inline=True)
def active_set_step(h, coach, cpl, sc, iv, held, ws, gprof):
    """
    Do one ROS2 step of the chain with the active set of held coaches; return work [J].

    Starts from the coaches held at the end of the last step (STATE.HELD) and solves the
    step (at most HOLD_SOLVES times): first the moving coaches whose velocity would change
    sign stop at the step's start (:func:`_hold_stopping`, the couplers then re-evaluated),
    else the coaches at rest take the holding LCP's set (:func:`_settle`). A step that ends
    at the cap with coaches still to stop or over their brake's limit is counted
    (COUNT.HOLD_CAPPED), the extra solves in COUNT.HOLD_SOLVES. Coaches released from
    rest that end the step moving against their friction stick (:func:`standstill.stick`).
    WORK.FB is the braking force over the step [N]. The returned work is the kinetic energy
    of the coaches stopped at the step's start or stuck at its end. The new state and the
    holding forces are left in WORK.XNEW, VNEW, HOLD.
    """
    n = held.shape[0]
    u = sc[PARAM.U]
    model = iv[OPTION.MODEL]
    x = coach[STATE.X]
    v = coach[STATE.V]
    was_held = coach[STATE.HELD]
    v_start = ws[WORK.VSTART]
    rel_dir = ws[WORK.RELDIR]
    for i in range(n):
        held[i] = was_held[i] > 0.5
        rel_dir[i] = 0.0
        v_start[i] = v[i]
    extra_work = 0.0
    stale = False
    for it in range(HOLD_SOLVES):
        if stale:   # stopped coaches changed some starting velocities
            eval_couplers(x, v_start, cpl, model, u, GAMMA * h, ws)
            stale = False
        _signed_brake(ws)
        ros2_step(h, coach, cpl, model, u, held, ws, iv[OPTION.EXT], iv[OPTION.TRACK], gprof)
        if it == HOLD_SOLVES - 1:
            if _stopping(held, ws) + standstill.inconsistent(held, ws, False) > 0:
                iv[COUNT.HOLD_CAPPED] += 1
            break
        stale, extra_work = _hold_stopping(held, coach[VEHICLE.MASS], ws, extra_work, sc)
        if not (stale or _settle(h, held, ws)):
            break
        iv[COUNT.HOLD_SOLVES] += 1
    return extra_work + standstill.stick(held, coach[VEHICLE.MASS], ws, sc)


# ----------------------------------------------------------------------------- one step
@jit(inline=True)
def brake_system_step(coach, sc, iv, ring, tables, ws):
    """
    Move the brake system to the end of the step (it does not depend on the motion).

    ``pipe_head``: the head pressure [Pa] enters the delay line and each coach reads its
    delayed pipe pressure (WORK.K0 + FRAC steps ago); ``pipe_per_coach``: the pipe
    pressures are the inputs INPUT.PIPE. Then the distributors' targets and the
    cylinders along their filling/release tables [Pa]; or, ``cylinder_per_coach``, the
    cylinder pressures are the inputs INPUT.CYL (see ``brakes``).
    """
    mode = iv[OPTION.MODE]
    p_pipe = coach[STATE.PPIPE]
    p_cyl = coach[STATE.PCYL]
    target = ws[WORK.TARGET]
    p_max = sc[PARAM.PMAX]
    if mode == brakes.PIPE_HEAD:
        iv[CLOCK.RING_POS] = brakes.delay_line_push(ring, iv[CLOCK.RING_POS],
                                                    sc[SCALAR_INPUT.HEAD])
        brakes.delay_line_read(ring, iv[CLOCK.RING_POS], ws[WORK.K0], ws[WORK.FRAC], p_pipe)
    elif mode == brakes.PIPE_PER_COACH:
        p_pipe[:] = coach[INPUT.PIPE]
    if mode == brakes.CYLINDER_PER_COACH:
        p_cyl[:] = coach[INPUT.CYL]
    else:
        brakes.distributor_target(p_pipe, coach[STATE.APPLIED], sc[PARAM.PNOM],
                                  sc[PARAM.PFS], sc[PARAM.SENS], p_max, target)
        brakes.cylinder_advance(p_cyl, target, sc[PARAM.H], p_max, tables)


@jit(inline=True)
def braking_force_trapezoid(coach, sc, ws):
    """
    Write the braking force over the step [N] to WORK.FB: the trapezoid of eq. (13).

    The mean of the available force (eq. 13, limited by eq. 12) at both ends of the step,
    second order; STATE.FB_AVAIL moves on to the step's end (WORK.FBNEXT).
    """
    fb = ws[WORK.FB]
    fb_next = ws[WORK.FBNEXT]
    fb_avail = coach[STATE.FB_AVAIL]
    brakes.braking_force(coach[STATE.PCYL], sc[PARAM.PMAX], sc[PARAM.MU],
                         coach[VEHICLE.BMASS], sc[PARAM.G], fb_next)
    for i in range(fb.shape[0]):
        fb[i] = 0.5 * (fb_avail[i] + fb_next[i])
        fb_avail[i] = fb_next[i]


@jit(inline=True)
def external_step(coach, sc, iv, gprof, cprof, ws):
    """
    Add the static resistance to the friction of the step; ramp the traction command.

    :func:`static_resistance` (Davis A + curves, held like the brake; WORK.GR1, stage 1's
    gradient force). STATE.T_EFF moves toward the command INPUT.T_CMD (build-up rate
    limit); WORK.TEFF is the mean over the step.
    """
    static_resistance(coach, iv, gprof, cprof, ws)
    h = sc[PARAM.H]
    cmd = coach[INPUT.T_CMD]
    eff = coach[STATE.T_EFF]
    t_eff = ws[WORK.TEFF]
    for i in range(t_eff.shape[0]):
        old = eff[i]
        new = old
        if cmd[i] != old:
            new = traction.ramp(old, cmd[i], h, coach[VEHICLE.T_BUILD, i])
            eff[i] = new
        t_eff[i] = 0.5 * (old + new)


@jit(inline=True)
def fault_check(ws, y_limit):
    """
    Return the status of the new state WORK.XNEW, VNEW: OK, NON_FINITE or OUT_OF_RANGE.

    OUT_OF_RANGE: a coupler's |y| = |x_i - x_{i+1}| exceeds y_limit [m] (the displacement
    the vehicles physically allow); NON_FINITE wins.
    """
    x_new = ws[WORK.XNEW]
    v_new = ws[WORK.VNEW]
    n = x_new.shape[0]
    bad = OK
    for i in range(n):
        if not (np.isfinite(x_new[i]) and np.isfinite(v_new[i])):
            bad = NON_FINITE
            break
        if i < n - 1 and abs(x_new[i] - x_new[i + 1]) > y_limit:
            bad = OUT_OF_RANGE
    return bad


@jit(inline=True)
def accept_step(coach, held, extra_work, ws, ext):
    """
    Move the coaches to the new state; return the brakes' work over the step [J].

    The work is sum_i Fb_i (x_i' - x_i) with the holding force WORK.HOLD on held coaches
    and WORK.SIGNED on the others, plus ``extra_work``; OUTPUT.FB_APPLIED gets |Fb_i| [N],
    STATE.HELD the active set (1.0 = held), WORK.XOLD the positions at the step's start.
    """
    x = coach[STATE.X]
    v = coach[STATE.V]
    fb_applied = coach[OUTPUT.FB_APPLIED]
    is_held = coach[STATE.HELD]
    hold = ws[WORK.HOLD]
    signed = ws[WORK.SIGNED]
    x_new = ws[WORK.XNEW]
    v_new = ws[WORK.VNEW]
    x_old = ws[WORK.XOLD]
    wb = extra_work
    for i in range(x.shape[0]):
        if not ext:       # else booked by accept_external
            b = hold[i] if held[i] else signed[i]
            wb += b * (x_new[i] - x[i])
            fb_applied[i] = abs(b)
        x_old[i] = x[i]
        x[i] = x_new[i]
        v[i] = v_new[i]
        is_held[i] = 1.0 if held[i] else 0.0
    return wb


@jit(inline=True)
def accept_external(h, coach, sc, held, ws):
    """
    Book the external forces of the accepted step; return the brakes' work [J].

    Splits the friction applied (WORK.HOLD on held vehicles, WORK.SIGNED on the others) into
    brake and static resistance, books the work of brake, resistance, traction and gravity
    (TOTAL.WR, WT, WG: the stage mean of each force times the displacement, as the ROS2
    update weights them) and the impulse of all external forces (TOTAL.PEXT), and leaves
    the forces at the step's end in OUTPUT.F_TRAC, F_RES, F_GRADE [N, forward > 0]; h [s].
    """
    wb = 0.0
    wr = 0.0
    wt = 0.0
    wg = 0.0
    pext = 0.0
    x = coach[STATE.X]
    x_new = ws[WORK.XNEW]
    rstat = ws[WORK.RSTAT]
    hold = ws[WORK.HOLD]
    signed = ws[WORK.SIGNED]
    v_start = ws[WORK.VSTART]
    rel_dir = ws[WORK.RELDIR]
    rd1, rd2 = ws[WORK.RD1], ws[WORK.RD2]
    tr1, tr2 = ws[WORK.TR1], ws[WORK.TR2]
    gr1, gr2 = ws[WORK.GR1], ws[WORK.GR2]
    e1, e2 = ws[WORK.E1], ws[WORK.E2]
    fb_applied = coach[OUTPUT.FB_APPLIED]
    f_trac, f_grade, f_res = coach[OUTPUT.F_TRAC], coach[OUTPUT.F_GRADE], coach[OUTPUT.F_RES]
    for i in range(held.shape[0]):
        dx = x_new[i] - x[i]
        r = rstat[i]
        if held[i]:
            b = hold[i]
            res = min(max(b, -r), r)
        else:
            b = signed[i]
            vs = v_start[i]
            res = r if vs > 0.0 else (-r if vs < 0.0 else rel_dir[i] * r)
        brake = b - res
        wb += brake * dx
        fb_applied[i] = abs(brake)
        wr += (res + 0.5 * (rd1[i] + rd2[i])) * dx
        wt += 0.5 * (tr1[i] + tr2[i]) * dx
        wg += 0.5 * (gr1[i] + gr2[i]) * dx
        pext += 0.5 * (e1[i] + e2[i]) - b
        f_trac[i] = tr2[i]
        f_grade[i] = gr2[i]
        f_res[i] = -(res + rd2[i])
    sc[TOTAL.WR] += wr
    sc[TOTAL.WT] += wt
    sc[TOTAL.WG] += wg
    sc[TOTAL.PEXT] += h * pext
    return wb


@jit(inline=True)
def static_resistance(coach, iv, gprof, cprof, ws):
    """
    Add the static resistance at the step's start to the friction WORK.FB [N].

    WORK.FBRAKE keeps the braking force [N]; WORK.RSTAT = Davis A + curve resistance (Roeckl,
    averaged over the vehicle's length) joins it in WORK.FB: like the brake it holds a vehicle
    at rest and never pushes it. WORK.GR1 = the gradient force at the step's start [N]
    (stage 1's, computed here once per step on the same span, not once per active-set pass).
    Both depend on the vehicle's position alone (its constants and the track are fixed per
    simulator): they are kept while STATE.X is the WORK.XKEY they were computed at (a
    vehicle at rest).
    """
    cx = cprof[0]
    cv = cprof[1]
    cc = cprof[2]
    curves = iv[OPTION.TRACK] and cx.shape[0] > 0
    gx = gprof[0]
    gv = gprof[1]
    gpc = gprof[2]
    grades = iv[OPTION.TRACK] and gx.shape[0] > 0
    gr1 = ws[WORK.GR1]
    davis_a = coach[VEHICLE.DAVIS_A]
    rstat = ws[WORK.RSTAT]
    fb = ws[WORK.FB]
    fbrake = ws[WORK.FBRAKE]
    xkey = ws[WORK.XKEY]
    for i in range(fb.shape[0]):
        xi = coach[STATE.X, i]
        if xi != xkey[i]:
            r = davis_a[i]
            hi = coach[VEHICLE.FRONT0, i] + xi
            lo = hi - coach[VEHICLE.LENGTH, i]
            if curves:
                r += coach[VEHICLE.WEIGHT, i] * 1e-3 * profile_mean(lo, hi, cx, cv, cc)
            gr = 0.0
            if grades:
                gr = -coach[VEHICLE.WEIGHT, i] * 1e-3 * profile_mean(lo, hi, gx, gv, gpc)
            gr1[i] = gr
            rstat[i] = r
            xkey[i] = xi
        fbrake[i] = fb[i]
        fb[i] += rstat[i]
