"""
The fixed-step driver: brakes and coach chain advanced by whole steps of ``integration_step``.

Each step of :func:`advance_chain` is made of the pieces of :mod:`.step`: the brake system to
the step's end, the braking force over the step (trapezoid), the external forces, one ROS2
step with the active set of held coaches, the fault check, then the new state is accepted,
the work booked and the couplers evaluated at the new state (their rows are the next step's
start).

Standstill cache (results bit for bit): at a standstill whose inputs did not change the
active-set step would repeat the last one exactly (:func:`_repeats_standstill`); it is
skipped and the step booked from the rows the last one left in ``ws`` (CACHE.STEADY,
WORK.FBPREV, TEPREV). In a 120 s freight run (47 vehicles) the train stands still from 53 s
on: the skipped steps cost ~30 ns per vehicle instead of ~100.

Compiled apart. The large pieces of a step are compiled functions of their own, called by
the driver, not inlined into it (numba's ``inline='always'`` copies a function's IR into
every caller and compiles the result as one; the compilation grows faster than the code):
the active-set step, the multirate refinement (:func:`.multirate.refine`), the first
call's set-up, the wheelsets' (and bogies') pieces and the external forces' (the last two
run only with their options). Measured with an empty kernel cache, one core, the paper group
(``cli/prebuild.py``): 119 s of CPU time with them inlined (``advance_chain`` alone 85-90 %),
57 s apart (the refinement 19 s, the active-set step 12 s, the wheelsets and bogies 12 s,
the driver itself 7 s), and :func:`parts` lets two processes compile them side by side. A
call passes its arrays (reference counting each): the paper's 3-coach step and the 100-coach
step ran as fast within the host's noise (1-2 %), and the results are bit for bit the same.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel import brakes, wheelset
from train_dynamics.physics.kernel.active_set import active_set_step
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.coupler_rows import (eval_couplers, eval_couplers_work,
                                                        invalidate_caches)
from train_dynamics.physics.kernel.couplers import TANH
from train_dynamics.physics.kernel.layout import CACHE, OPTION, PARAM, STATE, TOTAL, VEHICLE, WORK
from train_dynamics.physics.kernel.multirate import refine, scratch_size
from train_dynamics.physics.kernel.rosenbrock2 import GAMMA
from train_dynamics.physics.kernel.step import (accept_external, accept_step, brake_system_step,
                                                braking_force_trapezoid, external_step,
                                                fault_check, OK)


@jit(inline=True)
def _repeats_standstill(coach, iv, ws):
    """
    Tell whether this step would repeat the last one exactly: a standstill, same inputs.

    The last step started and ended with every vehicle held (CACHE.STEADY): held rows have
    zero stages, so it left x' = x, v' = 0 exactly. The active-set step is a function of
    the state (STATE.X, V, HELD and the couplers' rows at (x, v) in ws), the friction over
    the step (WORK.FB: brake and static resistance), the traction command (WORK.TEFF) and
    constants. When these equal the last step's (WORK.XOLD, FBPREV, TEPREV) it would write
    to ws the very rows it left there (holding forces, stage forces, the new state): the
    caller skips it and books the step from them (bit for bit).
    """
    if iv[CACHE.STEADY] == 0:
        return False
    x = coach[STATE.X]
    v = coach[STATE.V]
    is_held = coach[STATE.HELD]
    x_old = ws[WORK.XOLD]
    fb = ws[WORK.FB]
    fb_prev = ws[WORK.FBPREV]
    te = ws[WORK.TEFF]
    te_prev = ws[WORK.TEPREV]
    for i in range(x.shape[0]):
        if (fb[i] != fb_prev[i] or te[i] != te_prev[i] or v[i] != 0.0 or x[i] != x_old[i]
                or is_held[i] < 0.5):
            return False
    return True


@jit(inline=True)
def _all_held(coach):
    """Tell whether every vehicle is held at rest (STATE.HELD)."""
    is_held = coach[STATE.HELD]
    for i in range(is_held.shape[0]):
        if is_held[i] < 0.5:
            return False
    return True


@jit(inline=True)
def _note_standstill(started_held, coach, iv, ws):
    """
    Set CACHE.STEADY when the step started and ended with every vehicle held.

    Keeps the step's WORK.FB and TEFF (in FBPREV, TEPREV) for :func:`_repeats_standstill`.
    """
    steady = started_held and _all_held(coach)
    iv[CACHE.STEADY] = 1 if steady else 0
    if steady:
        fb = ws[WORK.FB]
        fb_prev = ws[WORK.FBPREV]
        te = ws[WORK.TEFF]
        te_prev = ws[WORK.TEPREV]
        for i in range(fb.shape[0]):
            fb_prev[i] = fb[i]
            te_prev[i] = te[i]


@jit
def _first_call(coach, cpl, sc, iv, ws, gh):
    """Split the pipe delays and evaluate the couplers at (x, v) into ``ws``; mark it valid."""
    brakes.delay_split(coach[VEHICLE.DELAY], ws[WORK.K0], ws[WORK.FRAC])
    eval_couplers(coach[STATE.X], coach[STATE.V], cpl, iv[OPTION.MODEL], sc[PARAM.U], gh, ws)
    invalidate_caches(ws)
    iv[CACHE.STEADY] = 0
    iv[CACHE.WS_VALID] = 1


@jit
def advance_chain(n_steps, coach, cpl, sc, iv, fill, rel, ring, ws, gprof, cprof, aprof):
    """
    Advance brakes and chain ``n_steps`` fixed steps, in place; return (steps, status).

    coach: (len(COACH), N) per-vehicle constants, state, inputs, outputs; cpl:
    (len(COUPLER), N-1) k_e, k_f, k_ec, k_fc [N/m], slack, strokes [m], K_b [N/m]; sc, iv:
    float and integer scalars (constants, totals, clocks, counters); fill, rel:
    (2 R, L) cylinder table sets (times [s], p/p_max; brakes.make_tables); ring:
    head-pressure history [Pa]; ws:
    :func:`make_workspace`; gprof, cprof: (3, K) gradient and curve-resistance profiles
    (breakpoints, values, integrals; ``track``), used when OPTION.TRACK is set; aprof: (3, K)
    the track's adhesion profile (OPTION.ADHESION; :mod:`.wheelset`). The layouts are
    in :mod:`.layout`. Each step: the brake system to the step's end,
    the braking force over the step (trapezoid), one ROS2 step with the active set of held
    coaches, the fault check, then the new state is accepted and the work booked. At a
    standstill with unchanged inputs the active-set step repeats the last one exactly and is
    skipped (:func:`_repeats_standstill`). With wheelsets (OPTION.WHEELS) the slide
    protection acts on the cylinders after the brake system and the wheelsets' creep force
    replaces the braking force (:mod:`.wheelset`); without them the braking force is at most
    what the adhesion carries (PARAM.ADHLIM, :func:`.wheelset.adhesion_limit`), the steps
    where it binds booked as sliding. With PARAM.MRTOL > 0
    (``multirate_tolerance``, the default) and the tanh law the groups of vehicles around
    couplers over that tolerance are re-integrated in sub-steps before the fault check
    (:func:`.multirate.refine`); with
    wheelsets too, the creep force of the long step acts on them as a constant force over
    the sub-steps, as the braking force does (the wheel speeds are integrated over the long
    step).
    """
    gh = GAMMA * sc[PARAM.H]
    held = np.empty(coach.shape[1], dtype=np.bool_)
    tables = brakes.make_tables(fill, rel)
    if iv[CACHE.WS_VALID] == 0:
        # first call after reset()/set_model(); later calls find ws as the last step left it
        _first_call(coach, cpl, sc, iv, ws, gh)
    wheels = iv[OPTION.WHEELS]
    multirate = sc[PARAM.MRTOL] > 0.0 and iv[OPTION.MODEL] == TANH
    # the refinement's memory, once per call (its groups allocate nothing)
    n = coach.shape[1]
    mr_scratch = np.empty(scratch_size(coach.shape[0], ws.shape[0], n) if multirate else 0)
    mr_held = np.empty(n if multirate else 0, dtype=np.bool_)
    for step in range(n_steps):
        if iv[OPTION.ADHESION]:
            wheelset.track_adhesion(coach, aprof)
        if wheels:
            ws[WORK.PCYL0] = coach[STATE.PCYL]
        brake_system_step(coach, sc, iv, ring, tables, ws)
        if wheels:
            wheelset.wsp_valves(coach, sc, iv, ws)
        braking_force_trapezoid(coach, sc, ws)
        if wheels:
            wheelset.wheelset_substep(coach, sc, ws)
        if iv[OPTION.EXT]:
            external_step(coach, sc, iv, gprof, cprof, ws)
        started_held = _all_held(coach)
        work_fix = 0.0
        if started_held and _repeats_standstill(coach, iv, ws):
            held[:] = True
            extra_work = 0.0
        else:
            extra_work = active_set_step(sc[PARAM.H], coach, cpl, sc, iv, held, ws, gprof)
            # multirate: events re-integrated in sub-steps; the tanh law only (the sign law
            # jumps at zero relative speed: no local error estimate converges there)
            if multirate:
                work_fix = refine(sc[PARAM.H], coach, cpl, sc, iv, held, ws, gprof,
                                  mr_scratch, mr_held)
        status = fault_check(ws, sc[PARAM.YLIM])
        if status != OK:
            return step, status
        if iv[OPTION.EXT]:
            sc[TOTAL.WB] += accept_external(sc[PARAM.H], coach, sc, held, ws)
        sc[TOTAL.WB] += accept_step(coach, held, extra_work, ws, iv[OPTION.EXT])
        if wheels:
            wheelset.book_wheelsets(coach, sc, ws)
        elif sc[PARAM.ADHLIM] != 0.0:
            wheelset.book_adhesion_slide(coach, sc[PARAM.H])
        # the couplers at the new state: their work over the step, and the next step's start
        sc[TOTAL.WC] += eval_couplers_work(coach, cpl, iv[OPTION.MODEL], sc[PARAM.U], gh,
                                           ws) + work_fix
        _note_standstill(started_held, coach, iv, ws)
    return n_steps, OK


def parts(coach, cpl, sc, iv, ws, gprof, cprof):
    """
    Return the functions :func:`advance_chain` calls compiled apart, with arguments of its types.

    A list of (name, seconds, function, arguments), the arguments built from a train's arrays
    as the driver passes them (what counts is their types: numba compiles a function for the
    types of its arguments). ``cli/prebuild.py`` compiles them in parallel processes before the
    driver (``function.compile(types)``), whose compilation then loads them from the kernel
    cache; a list that no longer matches the calls costs only time (the driver compiles what
    it does not find). Plain Python. The seconds: each one's compilation alone (one core,
    measured), to share them out between the processes.
    """
    n = coach.shape[1]
    h = sc[PARAM.H]
    held = np.zeros(n, dtype=np.bool_)
    scratch = np.zeros(1)
    return [
        ('refine', 19.0, refine, (h, coach, cpl, sc, iv, held, ws, gprof, scratch, held)),
        ('wheelsets', 12.0, wheelset.wheelset_substep, (coach, sc, ws)),
        ('active_set', 12.0, active_set_step, (h, coach, cpl, sc, iv, held, ws, gprof)),
        ('first_call', 2.0, _first_call, (coach, cpl, sc, iv, ws, GAMMA * h)),
        ('wsp_valves', 0.9, wheelset.wsp_valves, (coach, sc, iv, ws)),
        ('external', 0.8, external_step, (coach, sc, iv, gprof, cprof, ws)),
        ('book_wheelsets', 0.7, wheelset.book_wheelsets, (coach, sc, ws)),
        ('accept_external', 0.3, accept_external, (h, coach, sc, held, ws)),
    ]
