"""
Multirate refinement of the fixed step: events resolved where they happen, in sub-steps.

A coupler that crosses its friction reversal, enters or leaves its free play or blocks
limits the step only around itself. After the long ROS2 step h of the whole train
(:func:`~.active_set.active_set_step`), :func:`refine`:

1. estimates each coupler's local force error with the embedded first-order solution of
   ROS2 (Verwer et al. 1999; as the error-controlled driver, :mod:`.adaptive`, but per
   coupler): e_j = |dF/dy e_yj + dF/dydot e_ydotj| [N], the stage difference h/2 (k1 + k2)
   weighted into the coupler's force (:func:`coupler_errors`); with
   ``multirate_reversal_weight`` w > 0 at least w k |y| u times the relative-velocity error,
   the error the reversal it shifts will make (tanh law, eq. 14);
2. flags the couplers with e_j > tol * max(max_k |F_k|, F_floor) (``multirate_tolerance``
   tol [-], the same norm as ``integration_tolerance``: relative to the largest coupler
   force in the train, F_floor = 1e-3 of the heaviest vehicle's weight);
3. groups each flagged coupler with EXTEND vehicles on either side, widened until each
   end of the group is a sliding coupler (below), groups that touch merged, and integrates
   each group alone over the same h in error-controlled ROS2 sub-steps
   (:func:`_refine_group`; the same per-coupler estimate, elementary controller, landing
   on h), the rest of the train keeping the long step's result.

A group ends at sliding couplers. A coupler inside the tanh band (|u ydot| < EDGE_BAND,
eq. 14) is stiff in its relative velocity (dF/dydot = k |y| u sech^2(u ydot), ~3e7 N s/m
for the paper's couplers at u = 1e3): at a group's edge, the small difference between the
sub-stepped end vehicle's velocity and the long step's velocity of its outer neighbour
moves its force by whole per cents of the train's peak for one step (a spike that L-stable
ROS2 damps in the next step: 31 kN in 794 kN at one 10 ms sample of 100 coaches, the
largest error of the whole run against the reference). A boundary coupler in the band, or
reversing within the step, whose friction's full swing 2 k |y| exceeds the tolerance, is
therefore taken into the group and the group widened past it.

Coupling to the rest of the train. ROS2's update is separable per coupler: row i of either
stage reads m_i b_i = phi_{i-1} - phi_i + (external and brake forces), phi_j the coupler's
term (its force, the g h K_c velocity term and the stage-matrix term), and
m_i (v_i' - v_i) = h (phi1 + phi2)_{i-1} / 2 - h (phi1 + phi2)_i / 2 + h (E - Fb)_i with
E the stage mean of the external forces (the stage-2 row carries -2 m_i b1_i). So
I_j = h (phi1_j + phi2_j) / 2 is exactly the impulse coupler j passed over the long step
(:func:`coupler_impulse`). A group's boundary couplers keep theirs: it acts on the group's
end vehicles as the constant force I_j / h over the sub-steps, on the outer vehicles
through the long step. The external forces (brake signed against the motion, gradient,
traction, resistance) act as their long-step means, constant over the sub-steps. Hence
(exactly, to round-off) the train's momentum changes by the same impulses as without
refinement, and the work of brakes, resistance, traction and gravity, booked as these
constant forces times the displacement (:func:`~.step.accept_step`,
:func:`~.step.accept_external`), stays exact. The couplers' work inside a group is summed
over the sub-steps (trapezoid per sub-step; :func:`refine` returns the correction to the
long step's trapezoid that :func:`~.coupler_rows.eval_couplers_work` books).

Held vehicles: a group that contains a vehicle held at rest, released from rest, or
stopping within the step (or that would reverse in a sub-step) keeps the long step's result
(counted: COUNT.MR_DECLINED); the active set of the standstill is solved at the long step.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.coupler_rows import eval_couplers
from train_dynamics.physics.kernel.layout import (COUNT, COUPLER, OPTION, PARAM, STATE, VEHICLE,
                                                  WORK)
from train_dynamics.physics.kernel.rosenbrock2 import GAMMA, ros2_step

#: vehicles added to a flagged coupler's group on either side. Measured (bench/accuracy.py,
#: tolerance 1e-3 / 3e-4, force-sample error): 1: kHz case 1.01 / 0.34 %, free play 2.46 /
#: 0.95 %; 2: 0.76 / 0.27 %, 2.48 / 0.74 %; 3: 0.76 / 0.27 %, 2.43 / 0.74 %; the cost on
#: 100 coaches within this host's noise for all three
EXTEND = 2
#: a group's boundary coupler has |u ydot| >= EDGE_BAND [-] at both ends of the long step
#: and does not reverse within it (:func:`_in_band`). Measured (bench core's target case, 100
#: paper coaches, 0-51 s, tube +-10 ms against the Radau reference, % of its peak; CPU cost
#: against no widening): 0 (off) 2.015 %; 0.1 2.36 %; 0.3 1.22 % (+8-20 %); 0.5 1.23 %
#: (+35 %); 1 1.26 % (+60 %); with the mass of every coach x (1 +- 1e-5) 0.3 gives
#: 1.04 / 1.38 % where off gives 2.35 / 2.02 %. The four short accuracy cases unchanged.
EDGE_BAND = 0.3
#: sub-steps of one group in one long step at most; beyond, the rest is taken in equal
#: sub-steps accepted without error control (the work per long step stays bounded)
MAX_SUB = 200
#: elementary step-size controller of the sub-steps (local order 2 of the estimate)
SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 5.0


@jit(inline=True)
def coupler_errors(h, ws, out, cpl, u, w, x):
    """
    Write each coupler's local force error [N] of the ROS2 step just solved to ``out``.

    Embedded first-order solution: e_x = h/2 ((1 - g) h b1 + g h b2), e_v = h/2 (b1 + b2)
    per vehicle, e_j = |dF/dy (e_xj - e_xj+1) + dF/dydot (e_vj - e_vj+1)| with the stage
    matrix's slopes (dF/dydot = KK / (g h) - g h dF/dy). With w > 0 (PARAM.MRVW) at least
    w k |y| u |e_vj - e_vj+1|: the velocity error weighted by the slope the tanh law has at
    the coupler's next friction reversal (k = k_f in compression, k_fc in tension, u [s/m];
    y = x_j - x_j+1 from the positions x [m] at the step's start, |y| with the free play: an
    upper bound of the friction's amplitude), where outside the
    band dF/dydot ~ 0 hides it: a relative-velocity error of a sliding coupler shifts its
    next reversal, by ~ error / relative acceleration. Returns max_j |F_j| [N] at the step's
    start.
    """
    b1 = ws[WORK.B1]
    b2 = ws[WORK.B2]
    dfdy = ws[WORK.DFDY]
    kk = ws[WORK.KK]
    F0 = ws[WORK.F]
    gh = GAMMA * h
    cx = h - gh
    n = b1.shape[0]
    fmax = 0.0
    ex_prev = 0.5 * h * (cx * b1[0] + gh * b2[0])
    ev_prev = 0.5 * h * (b1[0] + b2[0])
    for i in range(1, n):
        ex = 0.5 * h * (cx * b1[i] + gh * b2[i])
        ev = 0.5 * h * (b1[i] + b2[i])
        j = i - 1
        dfdv = kk[j] / gh - gh * dfdy[j]
        out[j] = abs(dfdy[j] * (ex_prev - ex) + dfdv * (ev_prev - ev))
        if w > 0.0:
            y = x[j] - x[j + 1]
            k = cpl[COUPLER.KF, j] if y < 0.0 else cpl[COUPLER.KFC, j]
            out[j] = max(out[j], w * k * abs(y) * u * abs(ev_prev - ev))
        fmax = max(fmax, abs(F0[j]))
        ex_prev = ex
        ev_prev = ev
    return fmax


@jit(inline=True)
def coupler_impulse(j, h, ws):
    """
    Return the impulse [N s] coupler j passed over the ROS2 step h [s] just solved.

    I_j = h (phi1_j + phi2_j) / 2 with phi1_j = F_j + g h dF/dy (v_j - v_j+1)
    + KK_j (b1_j - b1_j+1) and phi2_j = F2_j + g h dF/dy (r_j - r_j+1) + KK_j (b2_j - b2_j+1),
    r = (h - 2 g h) b1 - v: the coupler's terms of the two stage rows
    (:func:`~.rosenbrock2.ros2_step`).
    """
    v = ws[WORK.VSTART]
    b1 = ws[WORK.B1]
    b2 = ws[WORK.B2]
    dfdy = ws[WORK.DFDY][j]
    kk = ws[WORK.KK][j]
    gh = GAMMA * h
    hr = h - 2.0 * gh
    phi1 = ws[WORK.F, j] + gh * dfdy * (v[j] - v[j + 1]) + kk * (b1[j] - b1[j + 1])
    dr = (hr * b1[j] - v[j]) - (hr * b1[j + 1] - v[j + 1])
    phi2 = ws[WORK.F2, j] + gh * dfdy * dr + kk * (b2[j] - b2[j + 1])
    return 0.5 * h * (phi1 + phi2)


@jit(inline=True)
def _declines(a, b, held, ws):
    """Tell whether vehicles a..b include one held, released or stopping within the step."""
    v0 = ws[WORK.VSTART]
    v1 = ws[WORK.VNEW]
    rel_dir = ws[WORK.RELDIR]
    for i in range(a, b + 1):
        if held[i] or rel_dir[i] != 0.0 or v0[i] * v1[i] <= 0.0:
            return True
    return False


@jit(inline=True)
def _in_band(j, u, tol_f, cpl, ws):
    """
    Tell whether coupler j's friction can jump by more than tol_f [N] at a group's edge.

    True when |u ydot_j| < EDGE_BAND at the long step's start (WORK.VSTART) or end
    (WORK.VNEW), or ydot_j changes sign within it (u [s/m], the tanh law's scale, eq. 14),
    and the friction's full swing 2 k |y| exceeds tol_f (k = k_f in compression, k_fc in
    tension; |y| at the step's end, WORK.XNEW, with the free play: an upper bound): a
    coupler carrying less cannot jump by more, whatever its relative velocity.
    """
    v0 = ws[WORK.VSTART]
    v1 = ws[WORK.VNEW]
    r0 = u * (v0[j] - v0[j + 1])
    r1 = u * (v1[j] - v1[j + 1])
    if abs(r0) >= EDGE_BAND and abs(r1) >= EDGE_BAND and r0 * r1 > 0.0:
        return False
    x1 = ws[WORK.XNEW]
    y = x1[j] - x1[j + 1]
    k = cpl[COUPLER.KF, j] if y < 0.0 else cpl[COUPLER.KFC, j]
    return 2.0 * k * abs(y) > tol_f


@jit(inline=True)
def _landing(hs, rem):
    """Return the sub-step [s] toward the end of the long step rem [s] away."""
    if hs >= rem * (1.0 - 1e-9):
        return rem
    if hs > 0.5 * rem:
        return 0.5 * rem
    return hs


@jit(inline=True)
def scratch_size(coach_rows, work_rows, n):
    """Return the length of :func:`refine`'s scratch for n vehicles (:func:`_refine_group`)."""
    return (coach_rows + work_rows + 5) * n


@jit(inline=True)
def _refine_group(a, b, h, tol_f, err0, coach, cpl, sc, iv, ws, gprof, scratch, sheld):
    """
    Re-integrate vehicles a..b over the long step h [s] in sub-steps; return (done, work).

    ROS2 on the sub-chain (:func:`~.rosenbrock2.ros2_step`) with each vehicle's constant force over
    the step (brake, external mean, boundary impulses / h), error-controlled against tol_f
    [N] per coupler, the first sub-step from the long step's error err0 [tol_f]; after
    MAX_SUB tries the rest in MAX_SUB equal sub-steps without control. Writes the new state
    of a..b to WORK.XNEW, VNEW, counts the sub-steps per coupler (WORK.NSUB), widens the
    force envelope (WORK.FHI, FLO) with every sub-step's forces. Returns (False, 0) without
    writing when a vehicle would reverse (the long step stands), else (True, the correction
    [J] of the couplers' work: sub-step trapezoids less the long step's).

    No allocation: the group's arrays are views of ``scratch`` (:func:`scratch_size`) and
    ``sheld`` (n flags), made once per driver call. The sub-chain's vehicle rows hold only
    what :func:`~.rosenbrock2.ros2_step` reads without external forces (STATE.X, V,
    VEHICLE.MASS; the other rows are not initialised), its couplers are a view of ``cpl``
    (read only), its workspace is zeroed as a new one would be. (Copying every row of the
    vehicles and couplers and allocating nine arrays cost ~60 kB of memory traffic per
    group of 30 vehicles.)
    """
    n = coach.shape[1]
    nc = b - a + 1
    model = iv[OPTION.MODEL]
    u = sc[PARAM.U]
    rows_c = coach.shape[0]
    rows_w = ws.shape[0]
    sub = scratch[:rows_c * nc].reshape((rows_c, nc))
    off = rows_c * nc
    sws = scratch[off:off + rows_w * nc].reshape((rows_w, nc))
    off += rows_w * nc
    rows = scratch[off:off + 5 * (nc - 1)].reshape((5, nc - 1))
    sws[:, :] = 0.0
    scpl = cpl[:, a:b]
    held = sheld[:nc]
    held[:] = False
    x = sub[STATE.X]
    v = sub[STATE.V]
    mass = sub[VEHICLE.MASS]
    for i in range(nc):
        x[i] = coach[STATE.X, a + i]
        v[i] = coach[STATE.V, a + i]
        mass[i] = coach[VEHICLE.MASS, a + i]
    signed = sws[WORK.SIGNED]
    for i in range(nc):
        k = a + i
        f = ws[WORK.SIGNED, k]          # retarding
        if iv[OPTION.EXT]:
            f -= 0.5 * (ws[WORK.E1, k] + ws[WORK.E2, k])
        signed[i] = f
    if a > 0:
        signed[0] -= coupler_impulse(a - 1, h, ws) / h
    if b < n - 1:
        signed[nc - 1] += coupler_impulse(b, h, ws) / h
    v_new = sws[WORK.VNEW]
    x_new = sws[WORK.XNEW]
    F = sws[WORK.F]
    err = sws[WORK.ERR]
    f_old = rows[0]
    f_hi = rows[1]
    f_lo = rows[2]
    y_old = rows[3]
    work = rows[4]
    f_hi[:] = 0.0
    f_lo[:] = 0.0
    work[:] = 0.0
    s = 0.0
    hs = h * min(0.5, max(0.05, SAFETY / np.sqrt(err0)))
    nsub = 0
    tries = 0
    forced = 0.0            # after MAX_SUB: equal sub-steps without error control
    eval_couplers(x, v, scpl, model, u, GAMMA * _landing(hs, h), sws)
    while s < h:
        rem = h - s
        tries += 1
        if tries > MAX_SUB and forced == 0.0:
            forced = rem / MAX_SUB
        hl = _landing(forced if forced > 0.0 else hs, rem)
        if sws[WORK.VKEY, nc - 1] != GAMMA * hl:
            eval_couplers(x, v, scpl, model, u, GAMMA * hl, sws)
        sws[WORK.VSTART][:] = v
        ros2_step(hl, sub, scpl, model, u, held, sws, False, False, gprof)
        e = 0.0
        if forced == 0.0:       # equal sub-steps without control need no estimate
            coupler_errors(hl, sws, err, scpl, u, sc[PARAM.MRVW], x)
            for j in range(nc - 1):
                e = max(e, err[j])
            e /= tol_f
        if e > 1.0 and forced == 0.0:
            hs = hl * max(FAC_MIN, SAFETY / np.sqrt(e))
            continue
        for i in range(nc):
            if v[i] * v_new[i] <= 0.0:
                return False, 0.0
        for j in range(nc - 1):
            f_old[j] = F[j]
            y_old[j] = x[j] - x[j + 1]
        for i in range(nc):
            x[i] = x_new[i]
            v[i] = v_new[i]
        nsub += 1
        s = h if hl >= rem else s + hl
        fac = min(FAC_MAX, max(FAC_MIN, SAFETY / np.sqrt(max(e, 1e-4))))
        if forced == 0.0:
            hs = hl * fac if (hl < rem or fac < 1.0) else max(hs, hl * fac)
        hn = _landing(hs, h - s) if s < h else hs
        eval_couplers(x, v, scpl, model, u, GAMMA * hn, sws)
        for j in range(nc - 1):
            f = F[j]
            work[j] += 0.5 * (f_old[j] + f) * ((x[j] - x[j + 1]) - y_old[j])
            f_hi[j] = max(f_hi[j], f)
            f_lo[j] = min(f_lo[j], f)
    iv[COUNT.MR_SUBSTEPS] += nsub
    corr = 0.0
    for j in range(nc - 1):
        k = a + j
        dy = (x[j] - x[j + 1]) - (coach[STATE.X, k] - coach[STATE.X, k + 1])
        corr += work[j] - 0.5 * (ws[WORK.F, k] + F[j]) * dy
        ws[WORK.NSUB, k] += nsub
        ws[WORK.FHI, k] = max(ws[WORK.FHI, k], f_hi[j])
        ws[WORK.FLO, k] = min(ws[WORK.FLO, k], f_lo[j])
    for i in range(nc):
        ws[WORK.XNEW, a + i] = x[i]
        ws[WORK.VNEW, a + i] = v[i]
    return True, corr


@jit
def refine(h, coach, cpl, sc, iv, held, ws, gprof, scratch, sheld):
    """
    Re-integrate in sub-steps the groups around couplers over tolerance; return work [J].

    After the long ROS2 step h [s] (state in WORK.XNEW, VNEW, stages in ws): the couplers'
    errors (:func:`coupler_errors`) against PARAM.MRTOL * max(max |F|, PARAM.FFLOOR); each
    flagged coupler with EXTEND vehicles either side, widened past boundary couplers in the
    tanh band (:func:`_in_band`), touching groups merged, is
    re-integrated (:func:`_refine_group`) unless it holds a vehicle at rest or stopping
    (:func:`_declines`). Returns the correction of the couplers' work [J] for TOTAL.WC.
    ``scratch``, ``sheld``: the groups' memory (:func:`_refine_group`).
    """
    n = coach.shape[1]
    m = n - 1
    err = ws[WORK.ERR]
    fmax = coupler_errors(h, ws, err, cpl, sc[PARAM.U], sc[PARAM.MRVW], coach[STATE.X])
    tol_f = sc[PARAM.MRTOL] * max(fmax, sc[PARAM.FFLOOR])
    u = sc[PARAM.U]
    corr = 0.0
    pa = -1                 # the pending group: vehicles pa..pb, its largest error pe [N]
    pb = -1
    pe = 0.0
    a = 0
    b = 0
    e0 = 0.0
    j = 0
    while j <= m:
        if j < m and err[j] <= tol_f:
            j += 1
            continue
        if j < m:           # flagged coupler j: its group, widened to sliding edges
            a = max(0, j - EXTEND)
            b = min(m, j + 1 + EXTEND)
            e0 = err[j]
            while a > 0 and _in_band(a - 1, u, tol_f, cpl, ws):
                a -= 1
            while b < m and _in_band(b, u, tol_f, cpl, ws):
                b += 1
            if pa >= 0 and a <= pb + 1:          # touches the pending group: merged
                pb = max(pb, b)
                pe = max(pe, e0)
                j += 1
                continue
        if pa >= 0:         # the pending group is complete: re-integrated
            if _declines(pa, pb, held, ws):
                iv[COUNT.MR_DECLINED] += 1
            else:
                done, dw = _refine_group(pa, pb, h, tol_f, pe / tol_f, coach, cpl, sc, iv,
                                         ws, gprof, scratch, sheld)
                if done:
                    iv[COUNT.MR_CLUSTERS] += 1
                    corr += dw
                else:
                    iv[COUNT.MR_DECLINED] += 1
        pa = a
        pb = b
        pe = e0
        j += 1
    return corr
