"""
A traced copy of the error-controlled chain driver: every attempted step logged.

:func:`trace_adaptive` is :func:`train_dynamics.physics.kernel.adaptive.advance_adaptive` with
its ``_chain_to`` written out here, logging every attempted step (chain time, step [s], error
norm [-], accepted, the limiting coupler, whether its relative velocity is inside the 1/u
band, the position and velocity parts of its error) and taking the controller's constants and
the error norm's variant from an array (``ctl``), so that variants can be tried without
editing the driver (``bench/adaptive_trace.py`` runs cases through it). With the driver's
constants (:func:`default_ctl` ``(0)``) it leaves the very state the driver leaves, bit for
bit (``test/kernel/test_adaptive_trace.py``): the copy cannot drift from the driver. It lives
in the kernel folder so that the kernel cache's key covers it (a jitted function elsewhere
could run stale machine code after an edit: ``compiler.py``). Norm variants (``ctl[MODE]``):

0. the driver's: the embedded estimate weighted into coupler forces (stage-matrix slopes);
   with the driver's constants the step decisions use the driver's own functions
   (``ctl[EXACT]``), so the run is the driver's to the last bit;
1. the estimate filtered through the stage matrix, (I - g h J)^-1 e (Shampine), then 0;
2. filtered, then the force difference F(y, ydot) - F(y - e_y, ydot - e_ydot) (the law);
3. unfiltered force difference.

Nothing of the simulator calls it: :func:`traced` routes one simulator's kernel through it.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel import active_set, brakes, couplers
from train_dynamics.physics.kernel import adaptive as ad
from train_dynamics.physics.kernel import coupler_rows as rows, step as it
from train_dynamics.physics.kernel import rosenbrock2
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import (CACHE, CLOCK, CONTROL, COUNT, COUPLER,
                                                  OPTION, PARAM, STATE, TOTAL, VEHICLE, WORK)

#: ctl slots; EXACT = 1: the kernel's own norm and controller (mode 0, no --set)
MODE, SAFETY, FAC_MIN, FAC_MAX, KI, KP, FLOOR, EXACT = range(8)
#: log columns (BAND: u |ydot| of the limiting coupler, < 1 inside the tanh band)
T, H, ERR, ACC, JMAX, BAND, EPOS, EVEL, FALLBACK = range(9)


@jit(inline=True)
def _err(h, coach, cpl, model, u, held, ws, tol, f_floor, mode, scr, info):
    """Return the error norm of the last ROS2 step (variant ``mode``); details to info."""
    b1 = ws[WORK.B1]
    b2 = ws[WORK.B2]
    dfdy = ws[WORK.DFDY]
    kk = ws[WORK.KK]
    F0 = ws[WORK.F]
    gh = rosenbrock2.GAMMA * h
    cx = h - gh
    n = b1.shape[0]
    m = n - 1
    ex = scr[0]
    ev = scr[1]
    for i in range(n):
        ex[i] = 0.5 * h * (cx * b1[i] + gh * b2[i])
        ev[i] = 0.5 * h * (b1[i] + b2[i])
    if mode == 1 or mode == 2:
        masses = coach[VEHICLE.MASS]
        winv = ws[WORK.WINV]
        lower = ws[WORK.LOWER]
        c = ws[WORK.C]
        z = scr[2]
        for i in range(n):
            r = masses[i] * ev[i]
            if i < m:
                r -= gh * dfdy[i] * (ex[i] - ex[i + 1])
            if i > 0:
                r += gh * dfdy[i - 1] * (ex[i - 1] - ex[i])
            if held[i]:
                r = 0.0
            if i == 0:
                z[0] = r * winv[0]
            else:
                z[i] = (r - lower[i - 1] * z[i - 1]) * winv[i]
        for i in range(n - 2, -1, -1):
            z[i] -= c[i] * z[i + 1]
        for i in range(n):
            ev[i] = z[i]
            ex[i] = ex[i] + gh * z[i]
    fmax = f_floor
    for j in range(m):
        fmax = max(fmax, abs(F0[j]))
    x_new = ws[WORK.XNEW]
    v_new = ws[WORK.VNEW]
    emax = 0.0
    jmax = 0
    epos = 0.0
    evel = 0.0
    for j in range(m):
        dy = ex[j] - ex[j + 1]
        dyd = ev[j] - ev[j + 1]
        dfdv = kk[j] / gh - gh * dfdy[j]
        if mode >= 2:
            y = x_new[j] - x_new[j + 1]
            yd = v_new[j] - v_new[j + 1]
            fa, _, _ = couplers.coupler_force_travel_scalar(
                y, yd, cpl[COUPLER.KE, j], cpl[COUPLER.KF, j], cpl[COUPLER.KEC, j],
                cpl[COUPLER.KFC, j], cpl[COUPLER.GT, j], cpl[COUPLER.GC, j],
                cpl[COUPLER.ST, j], cpl[COUPLER.SC, j], cpl[COUPLER.KB, j], model, u)
            fb, _, _ = couplers.coupler_force_travel_scalar(
                y - dy, yd - dyd, cpl[COUPLER.KE, j], cpl[COUPLER.KF, j], cpl[COUPLER.KEC, j],
                cpl[COUPLER.KFC, j], cpl[COUPLER.GT, j], cpl[COUPLER.GC, j],
                cpl[COUPLER.ST, j], cpl[COUPLER.SC, j], cpl[COUPLER.KB, j], model, u)
            e = abs(fa - fb)
        else:
            e = abs(dfdy[j] * dy + dfdv * dyd)
        if e > emax:
            emax = e
            jmax = j
            epos = abs(dfdy[j] * dy)
            evel = abs(dfdv * dyd)
    scale = tol * fmax
    info[0] = jmax
    info[1] = abs(v_new[jmax] - v_new[jmax + 1]) * u
    info[2] = epos / scale
    info[3] = evel / scale
    return emax / scale


@jit(inline=True)
def _log(log, cnt, t, hs, err, acc, info, fallback):
    k = cnt[0]
    if k < log.shape[0]:
        log[k, T] = t
        log[k, H] = hs
        log[k, ERR] = err
        log[k, ACC] = acc
        log[k, JMAX] = info[0]
        log[k, BAND] = info[1]
        log[k, EPOS] = info[2]
        log[k, EVEL] = info[3]
        log[k, FALLBACK] = 1.0 if fallback else 0.0
    cnt[0] = k + 1


@jit
def _chain_to(coach, cpl, sc, iv, ws, gprof, cprof, fbt, tet, held, ctl, scr, log, cnt):
    """:func:`adaptive._chain_to` with ``ctl`` constants and the step log."""
    h_tick = sc[PARAM.H]
    ka = iv[CLOCK.CHAIN_TICK]
    kb = iv[CLOCK.TICK]
    total = (kb - ka) * h_tick
    t0 = ka * h_tick
    h_max = iv[OPTION.LAND] * h_tick
    model = iv[OPTION.MODEL]
    u = sc[PARAM.U]
    tol = sc[PARAM.TOL]
    ext = iv[OPTION.EXT]
    mode = int(ctl[MODE])
    exact = ctl[EXACT] == 1.0
    ki = ctl[KI]
    kp = ctl[KP]
    info = np.zeros(4)
    s = 0.0
    steps = 0
    int_hmin = h_max
    fallback = False
    h = min(sc[CONTROL.HPROP], h_max)
    while s < total:
        rem = total - s
        if steps >= iv[OPTION.BUDGET] and not fallback:
            fallback = True
            iv[COUNT.NFALLBACK] += 1
        if fallback:
            h = h_tick
        hs = ad._landing_step(h, rem)
        if hs != sc[CONTROL.HEVAL]:
            rows.eval_couplers(coach[STATE.X], coach[STATE.V], cpl, model, u,
                               rosenbrock2.GAMMA * hs, ws)
            sc[CONTROL.HEVAL] = hs
        ad._tick_means(fbt, tet, ka, s / h_tick, (s + hs) / h_tick, ws)
        if ext:
            it.static_resistance(coach, iv, gprof, cprof, ws)
        pext = sc[TOTAL.PEXT]
        extra_work = active_set.active_set_step(hs, coach, cpl, sc, iv, held, ws, gprof)
        err = _err(hs, coach, cpl, model, u, held, ws, tol, sc[PARAM.FFLOOR], mode, scr, info)
        if exact:       # the kernel's own expression (the same value, to the last bit)
            err = ad._error_norm(hs, ws, tol, sc[PARAM.FFLOOR])
        if err > 1.0 and not fallback and hs > ad.H_MIN:
            _log(log, cnt, t0 + s, hs, err, 0.0, info, fallback)
            sc[TOTAL.PEXT] = pext
            iv[COUNT.NREJ] += 1
            sc[CONTROL.HEVAL] = -1.0
            if exact:
                h = max(hs * max(ad.FAC_MIN, ad.SAFETY * err ** -0.5), ad.H_MIN)
            else:
                h = max(hs * max(ctl[FAC_MIN], ctl[SAFETY] * err ** -0.5), ad.H_MIN)
            continue
        _log(log, cnt, t0 + s, hs, err, 1.0, info, fallback)
        status = it.fault_check(ws, sc[PARAM.YLIM])
        if status != it.OK:
            return status
        if ext:
            sc[TOTAL.WB] += it.accept_external(hs, coach, sc, held, ws)
        sc[TOTAL.WB] += it.accept_step(coach, held, extra_work, ws, ext)
        steps += 1
        if hs < rem:
            int_hmin = min(int_hmin, hs)
            sc[CONTROL.HMIN] = min(sc[CONTROL.HMIN], hs)
        s = total if hs >= rem else s + hs
        e = max(err, 1e-4)
        if exact:
            fac = ad.SAFETY * e ** -ad.PI_KI * sc[CONTROL.ERRPREV] ** ad.PI_KP
            fac = min(ad.FAC_MAX, max(ad.FAC_MIN, fac))
        else:
            fac = ctl[SAFETY] * e ** -ki * sc[CONTROL.ERRPREV] ** kp
            fac = min(ctl[FAC_MAX], max(ctl[FAC_MIN], fac))
        sc[CONTROL.ERRPREV] = e
        if not fallback:
            if hs < rem or fac < 1.0:
                h = hs * fac
            else:
                h = max(h, hs * fac)
            h = max(min(h, h_max), ad.H_MIN)
            sc[CONTROL.HPROP] = h
        hn = ad._landing_step(h, total - s) if s < total else h
        sc[TOTAL.WC] += rows.eval_couplers_work(coach, cpl, model, u, rosenbrock2.GAMMA * hn, ws)
        sc[CONTROL.HEVAL] = hn
    iv[CLOCK.CHAIN_TICK] = kb
    iv[COUNT.NSTEPS] += steps
    iv[COUNT.INT_STEPS] = steps
    iv[COUNT.INT_STEPS_MAX] = max(iv[COUNT.INT_STEPS_MAX], steps)
    sc[CONTROL.INT_HMIN] = int_hmin
    return it.OK


@jit
def trace_adaptive(n_ticks, sync, coach, cpl, sc, iv, fill, rel, ring, ws, gprof, cprof,
                   fbt, tet, ctl, scr, log, cnt):
    """:func:`adaptive.advance_adaptive` through the traced :func:`_chain_to`."""
    held = np.empty(coach.shape[1], dtype=np.bool_)
    tables = brakes.make_tables(fill, rel)
    if iv[CACHE.WS_VALID] == 0:
        brakes.delay_split(coach[VEHICLE.DELAY], ws[WORK.K0], ws[WORK.FRAC])
        r = iv[CLOCK.TICK] % fbt.shape[0]
        for i in range(coach.shape[1]):
            fbt[r, i] = coach[STATE.FB_AVAIL, i]
            tet[r, i] = coach[STATE.T_EFF, i]
        sc[CONTROL.HEVAL] = -1.0
        if iv[CLOCK.TICK] == 0:
            rows.eval_couplers(coach[STATE.X], coach[STATE.V], cpl, iv[OPTION.MODEL],
                               sc[PARAM.U], rosenbrock2.GAMMA * sc[PARAM.H], ws)
        iv[CACHE.WS_VALID] = 1
    land = iv[OPTION.LAND]
    for k in range(n_ticks):
        ad._brake_tick(coach, sc, iv, ring, tables, ws, fbt, tet)
        if iv[CLOCK.TICK] % land == 0:
            status = _chain_to(coach, cpl, sc, iv, ws, gprof, cprof, fbt, tet, held, ctl, scr,
                               log, cnt)
            if status != it.OK:
                return k + 1, status
    if sync and iv[CLOCK.CHAIN_TICK] < iv[CLOCK.TICK]:
        status = _chain_to(coach, cpl, sc, iv, ws, gprof, cprof, fbt, tet, held, ctl, scr,
                           log, cnt)
        if status != it.OK:
            return n_ticks, status
    return n_ticks, it.OK


def traced(sim, ctl, max_log: int = 4_000_000):
    """Route ``sim``'s error-controlled kernel through :func:`trace_adaptive`; return the log."""
    scr = np.zeros((3, sim.n))
    log = np.zeros((max_log, 9))
    cnt = np.zeros(1, dtype=np.int64)

    def kernel(n_steps, sync=False):
        return trace_adaptive(int(n_steps), sync, sim.coach, sim.cpl, sim.sc, sim.iv, sim.fill,
                              sim.rel, sim.ring, sim.ws, sim.gprof, sim.cprof, sim.tick_fb,
                              sim.tick_te, ctl, scr, log, cnt)
    sim._kernel = kernel
    return lambda: log[:min(cnt[0], max_log)]


def default_ctl(mode: int = 0) -> np.ndarray:
    """Return the kernel's controller constants with norm variant ``mode`` (0: EXACT)."""
    ctl = np.zeros(8)
    ctl[[MODE, SAFETY, FAC_MIN, FAC_MAX, KI, KP]] = [mode, ad.SAFETY, ad.FAC_MIN, ad.FAC_MAX,
                                                     ad.PI_KI, ad.PI_KP]
    ctl[EXACT] = 1.0 if mode == 0 else 0.0
    return ctl
