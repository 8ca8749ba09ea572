"""
Error-controlled integration of the coach chain (``integration_tolerance`` > 0).

The chain takes the steps of :mod:`.step` (ROS2, the active
set of held vehicles, the external forces, the fault check) with a step size chosen per
step: the embedded first-order solution of ROS2 estimates the local error of every coupler
force, kept below tolerance x the largest coupler force in the train [-]
(:func:`_error_norm`); a PI controller (Gustafsson) sets the next step; steps land on every
output instant (:func:`_landing_step`). The brake system and the inputs keep the fixed tick
PARAM.H of the fixed-step kernel (:func:`_brake_tick`), and the braking and traction forces
are linear between ticks (:func:`_tick_means`), so the inputs act at the same tick as in the
fixed-step kernel, offline and in the node. OPTION.BUDGET bounds the accepted and the rejected
steps per output period: a period that runs out of either finishes in at most OPTION.BUDGET
equal steps without error control (never coarser than the tick), counted (COUNT.NFALLBACK): at
most three times the budget in all.
"""
from __future__ import annotations

import math

import numpy as np

from train_dynamics.physics.kernel import brakes, traction, wheelset
from train_dynamics.physics.kernel.active_set import active_set_step
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.coupler_rows import (eval_couplers, eval_couplers_work,
                                                        invalidate_caches)
from train_dynamics.physics.kernel.layout import (CACHE, CLOCK, CONTROL, COUNT, INPUT, OPTION,
                                                  PARAM, STATE, TOTAL, VEHICLE, WORK)
from train_dynamics.physics.kernel.rosenbrock2 import GAMMA
from train_dynamics.physics.kernel.step import (accept_external, accept_step,
                                                available_braking_force, brake_system_step,
                                                fault_check, OK, static_resistance)

#: [s] the error-controlled steps never go below this (a step this short is accepted)
H_MIN = 1e-6
#: PI controller (Gustafsson): exponents on the error of this and the last step, for an
#: estimate of local order 2 (the embedded first-order solution), safety factor, limits
PI_KI = 0.7 / 2.0
PI_KP = 0.4 / 2.0
SAFETY = 0.9
FAC_MIN = 0.2
FAC_MAX = 5.0


@jit(inline=True)
def _brake_tick(coach, sc, iv, ring, tables, ws, fbt, tet):
    """
    Advance the brake system one tick of PARAM.H; store its force and traction at the tick.

    The brake system does not depend on the motion: it runs on the fixed tick (brake pipe,
    distributors, cylinders, inputs as in :func:`advance_chain`), and the chain's steps take
    the braking force (eq. 13) and the traction command as piecewise linear between ticks
    (rows ``fbt``, ``tet`` of the tick ring, index tick mod its length).
    """
    brake_system_step(coach, sc, iv, ring, tables, ws)
    fb_next = ws[WORK.FBNEXT]
    available_braking_force(coach, sc, fb_next)
    if sc[PARAM.ADHLIM] != 0.0:     # the adhesion limit's sliding, at the chain's speeds
        wheelset.book_adhesion_slide(coach, sc[PARAM.H])
    tick = iv[CLOCK.TICK] + 1
    r = tick % fbt.shape[0]
    h = sc[PARAM.H]
    for i in range(fb_next.shape[0]):
        coach[STATE.FB_AVAIL, i] = fb_next[i]
        fbt[r, i] = fb_next[i]
        old = coach[STATE.T_EFF, i]
        if iv[OPTION.EXT] and coach[INPUT.T_CMD, i] != old:
            coach[STATE.T_EFF, i] = traction.ramp(old, coach[INPUT.T_CMD, i], h,
                                                  coach[VEHICLE.T_BUILD, i])
        tet[r, i] = coach[STATE.T_EFF, i]
    iv[CLOCK.TICK] = tick


@jit(inline=True)
def _tick_means(fbt, tet, ka, u0, u1, ws):
    """
    Write the means over [u0, u1] [ticks after tick ka] of the tick values to WORK.FB, TEFF.

    The braking force and the traction command are linear between ticks, so the means are
    exact: the fixed-step trapezoid when [u0, u1] is one tick.
    """
    R = fbt.shape[0]
    fb = ws[WORK.FB]
    te = ws[WORK.TEFF]
    n = fb.shape[0]
    for i in range(n):
        fb[i] = 0.0
        te[i] = 0.0
    j = int(math.floor(u0))
    span = u1 - u0
    while j < u1:
        s0 = max(u0, float(j))
        s1 = min(u1, j + 1.0)
        if s1 > s0:
            w = (s1 - s0) / span
            ca = 1.0 - (0.5 * (s0 + s1) - j)    # weight of tick j at the segment's middle
            ra = (ka + j) % R
            rb = (ka + j + 1) % R
            for i in range(n):
                fb[i] += w * (ca * fbt[ra, i] + (1.0 - ca) * fbt[rb, i])
                te[i] += w * (ca * tet[ra, i] + (1.0 - ca) * tet[rb, i])
        j += 1


@jit(inline=True)
def _error_norm(h, ws, tol, f_floor):
    """
    Return the local error of the last ROS2 step in units of the tolerance (<= 1: accept).

    Embedded first-order solution (Verwer et al. 1999): x^ = x + h a1, v^ = v + h b1, so
    the estimate is the difference h/2 (k1 + k2) of the stages. It is weighted into the
    couplers' forces, e_Fj = dF/dy e_yj + dF/dydot e_ydotj (the stage-matrix slopes), and
    measured against tol * max(max_j |F_j|, f_floor): the error of every coupler force
    relative to the largest force in the train.
    """
    b1 = ws[WORK.B1]
    b2 = ws[WORK.B2]
    dfdy = ws[WORK.DFDY]
    kk = ws[WORK.KK]
    F0 = ws[WORK.F]
    gh = GAMMA * h
    cx = h - gh
    n = b1.shape[0]
    fmax = f_floor
    emax = 0.0
    ex_prev = 0.0
    ev_prev = 0.0
    for i in range(n):
        ex = 0.5 * h * (cx * b1[i] + gh * b2[i])
        ev = 0.5 * h * (b1[i] + b2[i])
        if i > 0:
            j = i - 1
            dfdv = kk[j] / gh - gh * dfdy[j]
            e = abs(dfdy[j] * (ex_prev - ex) + dfdv * (ev_prev - ev))
            emax = max(emax, e)
            fmax = max(fmax, abs(F0[j]))
        ex_prev = ex
        ev_prev = ev
    return emax / (tol * fmax)


@jit(inline=True)
def _landing_step(h, rem):
    """Return the step [s] toward a landing point rem [s] away: h, all of rem, or half."""
    if h >= rem * (1.0 - 1e-9):
        return rem
    if h > 0.5 * rem:
        return 0.5 * rem
    return h


@jit(inline=True)
def _chain_to(coach, cpl, sc, iv, ws, gprof, cprof, fbt, tet, held):
    """
    Integrate the chain with error-controlled ROS2 steps from CHAIN_TICK to TICK exactly.

    Step-size control: :func:`_error_norm` <= 1 accepts, else the step is redone shorter;
    the next step from the PI controller, at most the landing period, clipped to land on
    the tick TICK. After OPTION.BUDGET accepted or OPTION.BUDGET rejected steps in the
    period the rest is done in at most OPTION.BUDGET equal steps, each at most PARAM.H,
    accepted without error control (counted in COUNT.NFALLBACK): the work per output period
    is bounded (three times the budget). The rejected steps count: a step landing a hair
    above H_MIN (half of what is left of the period) cannot be shortened and, at a tolerance
    no step meets (1e-15), was rejected for ever.
    Returns the status (OK or the fault).
    """
    h_tick = sc[PARAM.H]
    ka = iv[CLOCK.CHAIN_TICK]
    kb = iv[CLOCK.TICK]
    total = (kb - ka) * h_tick
    h_max = iv[OPTION.LAND] * h_tick
    model = iv[OPTION.MODEL]
    u = sc[PARAM.U]
    tol = sc[PARAM.TOL]
    ext = iv[OPTION.EXT]
    s = 0.0
    steps = 0
    rejected = 0
    int_hmin = h_max
    fallback = False
    h_fallback = h_tick
    h = min(sc[CONTROL.HPROP], h_max)
    while s < total:
        rem = total - s
        if (steps >= iv[OPTION.BUDGET] or rejected >= iv[OPTION.BUDGET]) and not fallback:
            fallback = True
            iv[COUNT.NFALLBACK] += 1
            # the rest of the period in at most BUDGET equal steps (never coarser than the
            # tick): the work stays bounded and the error keeps following the step
            h_fallback = max(min(rem / iv[OPTION.BUDGET], h_tick), H_MIN)
        if fallback:
            h = h_fallback
        hs = _landing_step(h, rem)
        if hs != sc[CONTROL.HEVAL]:
            eval_couplers(coach[STATE.X], coach[STATE.V], cpl, model, u, GAMMA * hs, ws)
            sc[CONTROL.HEVAL] = hs
        _tick_means(fbt, tet, ka, s / h_tick, (s + hs) / h_tick, ws)
        if ext:
            static_resistance(coach, iv, gprof, cprof, ws)
        pext = sc[TOTAL.PEXT]
        extra_work = active_set_step(hs, coach, cpl, sc, iv, held, ws, gprof)
        err = _error_norm(hs, ws, tol, sc[PARAM.FFLOOR])
        if err > 1.0 and not fallback and hs > H_MIN:
            sc[TOTAL.PEXT] = pext
            iv[COUNT.NREJ] += 1
            rejected += 1
            sc[CONTROL.HEVAL] = -1.0     # the active set may have left other slopes in ws
            h = max(hs * max(FAC_MIN, SAFETY * err ** -0.5), H_MIN)
            continue
        status = fault_check(ws, sc[PARAM.YLIM])
        if status != OK:
            return status
        if ext:
            sc[TOTAL.WB] += accept_external(hs, coach, sc, held, ws)
        sc[TOTAL.WB] += accept_step(coach, held, extra_work, ws, ext)
        steps += 1
        if hs < rem:
            int_hmin = min(int_hmin, hs)
            sc[CONTROL.HMIN] = min(sc[CONTROL.HMIN], hs)
        s = total if hs >= rem else s + hs
        # PI controller
        e = max(err, 1e-4)
        fac = SAFETY * e ** -PI_KI * sc[CONTROL.ERRPREV] ** PI_KP
        fac = min(FAC_MAX, max(FAC_MIN, fac))
        sc[CONTROL.ERRPREV] = e
        if not fallback:
            if hs < rem or fac < 1.0:
                h = hs * fac
            else:       # a step shortened to land: its error says nothing against h
                h = max(h, hs * fac)
            h = max(min(h, h_max), H_MIN)
            sc[CONTROL.HPROP] = h
        # the couplers at the new state, with the next step's stage weights
        hn = _landing_step(h, total - s) if s < total else h
        sc[TOTAL.WC] += eval_couplers_work(coach, cpl, model, u, GAMMA * hn, ws)
        sc[CONTROL.HEVAL] = hn
    iv[CLOCK.CHAIN_TICK] = kb
    iv[COUNT.NSTEPS] += steps
    iv[COUNT.INT_STEPS] = steps
    iv[COUNT.INT_STEPS_MAX] = max(iv[COUNT.INT_STEPS_MAX], steps)
    sc[CONTROL.INT_HMIN] = int_hmin
    return OK


@jit
def advance_adaptive(n_ticks, sync, coach, cpl, sc, iv, fill, rel, ring, ws, gprof, cprof,
                     aprof, fbt, tet):
    """
    Advance the brake system ``n_ticks`` ticks and the chain with error control; in place.

    Same arrays as :func:`advance_chain` (the track's adhesion at the chain's last landing,
    for traction; no wheelsets), plus the tick ring ``fbt``, ``tet`` (at least
    OPTION.LAND + 1 rows of N). The brake system and the inputs run on the fixed tick
    PARAM.H exactly as in the fixed-step kernel; the chain follows with error-controlled
    steps (:func:`_chain_to`) and lands on every multiple of OPTION.LAND ticks (the output
    instants) and, when ``sync`` is set, on the present tick. Between landings the chain
    lags the brake system (its state is read only where it landed). Return
    (ticks done, status).
    """
    held = np.empty(coach.shape[1], dtype=np.bool_)
    tables = brakes.make_tables(fill, rel)
    if iv[CACHE.WS_VALID] == 0:
        brakes.delay_split(coach[VEHICLE.DELAY], ws[WORK.K0], ws[WORK.FRAC])
        r = iv[CLOCK.TICK] % fbt.shape[0]
        for i in range(coach.shape[1]):
            fbt[r, i] = coach[STATE.FB_AVAIL, i]
            tet[r, i] = coach[STATE.T_EFF, i]
        sc[CONTROL.HEVAL] = -1.0
        invalidate_caches(ws)
        if iv[CLOCK.TICK] == 0:   # the couplers' forces at t = 0 (read before any step)
            eval_couplers(coach[STATE.X], coach[STATE.V], cpl, iv[OPTION.MODEL], sc[PARAM.U],
                          GAMMA * sc[PARAM.H], ws)
        iv[CACHE.WS_VALID] = 1
    land = iv[OPTION.LAND]
    for k in range(n_ticks):
        if iv[OPTION.ADHESION]:
            wheelset.track_adhesion(coach, aprof)
        _brake_tick(coach, sc, iv, ring, tables, ws, fbt, tet)
        if iv[CLOCK.TICK] % land == 0:
            status = _chain_to(coach, cpl, sc, iv, ws, gprof, cprof, fbt, tet, held)
            if status != OK:
                return k + 1, status
    if sync and iv[CLOCK.CHAIN_TICK] < iv[CLOCK.TICK]:
        status = _chain_to(coach, cpl, sc, iv, ws, gprof, cprof, fbt, tet, held)
        if status != OK:
            return n_ticks, status
    return n_ticks, OK
