"""
ROS2, the Rosenbrock method of every chain step: stage forces and the two stage solves.

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

:func:`ros2_step` solves both stages for a given set of held vehicles (their rows fixed
at zero velocity); :mod:`.active_set` finds that set, :mod:`.step` and the drivers do
the rest of the step.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel import couplers, traction
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import COUPLER, OUTPUT, STATE, VEHICLE, WORK
from train_dynamics.physics.kernel.track import profile_mean
from train_dynamics.physics.kernel.traction import CK_AT_REST as DRY_ADHESION

GAMMA = 1.0 + 1.0 / np.sqrt(2.0)


@jit(inline=True)
def _stage_external(coach, x, v, h, ws, gx, gv, gc, track, row_gr, row_rd, row_tr, row_e):
    """
    Write the external forces of every vehicle at a stage's point to four WORK rows.

    The point is (x + h (v + g h b1), v + h b1) with b1 = WORK.B1: stage 1 for h = 0,
    stage 2 for the step h [s]. Forces [N]:
    the gradient -m g (mean gradient over the vehicle) / 1000 (``track``; at stage 1 the
    WORK.GR1 that :func:`external_step` left, the same position), the speed-dependent
    resistance d (B |v| + C v^2) against the friction's direction d (Davis; A is with the
    brake), traction (``traction.traction_force``; its adhesion scaled by the track's,
    OUTPUT.ADH_LOW / DRY_ADHESION, where the rail is not dry), and E = gradient + traction -
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
            mu0 = coach[VEHICLE.T_ADH, i]
            low = coach[OUTPUT.ADH_LOW, i]
            if low != DRY_ADHESION:     # the track's adhesion scales the vehicle's
                mu0 *= low / DRY_ADHESION
            tr = traction.traction_force(
                teff, vi, coach[VEHICLE.T_FORCE, i], coach[VEHICLE.T_POWER, i],
                coach[VEHICLE.DB_FORCE, i], coach[VEHICLE.DB_POWER, i], coach[VEHICLE.DB_FADE, i],
                mu0, coach[VEHICLE.WEIGHT, i])
        out_gr[i] = gr
        out_rd[i] = rd
        out_tr[i] = tr
        out_e[i] = gr + tr - rd


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
    tab = cpl[COUPLER.TAB]
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
        if tab[j] != 0.0:     # preloaded or progressive ends: the coupling's tables
            f, _, _ = couplers.coupler_force_table_scalar(
                x[j] - x[j + 1] + h * (dv + gh * db), dv + h * db, gt[j], gc[j], st[j],
                scs[j], kb[j], model, u, cpl, j)
        else:
            f, _, _ = couplers.coupler_force_travel_scalar(
                x[j] - x[j + 1] + h * (dv + gh * db), dv + h * db, ke[j], kf[j], kec[j],
                kfc[j], gt[j], gc[j], st[j], scs[j], kb[j], model, u)
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
