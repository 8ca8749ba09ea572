"""
The step of the coach chain: the named pieces both drivers share, and the step's base.

One step, in named parts (the drivers: :mod:`.fixed_step` and :mod:`.adaptive`):

1. :func:`brake_system_step`: brake pipe, distributors and cylinders to t + h (they do not
   depend on the motion);
2. :func:`braking_force_trapezoid`: the braking force over the step, eq. (13);
3. :func:`~.active_set.active_set_step`: :func:`~.rosenbrock2.ros2_step` with the active set of
   held coaches; the fixed-step driver skips it at a standstill whose inputs did not change
   (it would repeat the last step exactly);
4. :func:`fault_check`, then :func:`accept_step` and the couplers at the new state
   (:func:`~.coupler_rows.eval_couplers_work`, which keeps a coupler's law where its
   (y, ydot) did not change).

The method and its parts, one per module: :mod:`.ros2` (the Rosenbrock stages),
:mod:`.coupler_rows` (the couplers' rows the stages solve with), :mod:`.active_set` (the
vehicles held at rest, with :mod:`.standstill`); this module: the brake system, the
external forces, the fault check and the acceptance of a step.

Caches (results bit for bit): the couplers' rows carry their (y, ydot) (WORK.YKEY, VKEY;
:mod:`.coupler_rows`), the static resistance and gradient force their position (WORK.XKEY,
:func:`static_resistance`); the fixed-step driver's standstill cache is described in
:mod:`.fixed_step`.

The packed arrays the kernel works on are laid out in :mod:`.layout`.
Speed: the steps take the packed arrays and are inlined into the drivers by numba
(``@jit(inline=True)``, as are the brake-system functions they call). A compiled function
that takes arrays, or makes row views, pays their reference counting at every call, and
a call left inside an inlined step stops LLVM from removing that counting: split into
ordinary calls, a 3-coach step ran 1.5-2 times slower. Large pieces called once per step are
ordinary calls all the same (:func:`external_step`, :func:`accept_external`, the active-set
step, the wheelsets' pieces): inlined, they made the driver one function that took minutes
to compile, and a few calls per step cost nothing measurable (``fixed_step.py``).
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel import brakes, friction, traction, wheelset
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.coupler_rows import invalidate_caches
from train_dynamics.physics.kernel.layout import (CLOCK, INPUT, OPTION, OUTPUT, PARAM,
                                                  SCALAR_INPUT, STATE, TOTAL, VEHICLE, WORK)
from train_dynamics.physics.kernel.track import profile_mean

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
        brakes.cylinder_advance(p_cyl, target, sc[PARAM.H], p_max, tables,
                                coach[VEHICLE.TABLE])


@jit(inline=True)
def available_braking_force(coach, sc, out):
    """
    Write the braking force available at the cylinder pressures [N] to ``out``.

    Eq. (13) limited by eq. (12) (:func:`~.brakes.braking_force`); then, when some vehicle
    brakes with a friction material (PARAM.FRICTION), its force at its speed
    (:func:`~.friction.friction_braking_force`; the speed of the chain's present state);
    then, on a train without wheelsets (PARAM.ADHLIM, ``adhesion_limit``), at most what the
    wheel-rail adhesion carries, mu(v) m g (:func:`~.wheelset.adhesion_limit`).
    """
    brakes.braking_force(coach[STATE.PCYL], sc[PARAM.PMAX], sc[PARAM.MU],
                         coach[VEHICLE.BMASS], sc[PARAM.G], out)
    if sc[PARAM.FRICTION] != 0.0:
        friction.friction_braking_force(coach[VEHICLE.MATERIAL],
                                        coach[VEHICLE.LAW0:VEHICLE.LAW0 + friction.LAW_LEN],
                                        coach[STATE.PCYL], coach[STATE.V],
                                        coach[VEHICLE.BRAKE_GAIN], coach[VEHICLE.BRAKE_OFF],
                                        coach[VEHICLE.BLOCKS], coach[VEHICLE.RHO], out)
    if sc[PARAM.ADHLIM] != 0.0:
        wheelset.adhesion_limit(coach, out)


@jit(inline=True)
def braking_force_trapezoid(coach, sc, ws):
    """
    Write the braking force over the step [N] to WORK.FB: the trapezoid of eq. (13).

    The mean of the available force (:func:`available_braking_force`) at both ends of the step,
    second order; STATE.FB_AVAIL moves on to the step's end (WORK.FBNEXT).
    """
    fb = ws[WORK.FB]
    fb_next = ws[WORK.FBNEXT]
    fb_avail = coach[STATE.FB_AVAIL]
    available_braking_force(coach, sc, fb_next)
    for i in range(fb.shape[0]):
        fb[i] = 0.5 * (fb_avail[i] + fb_next[i])
        fb_avail[i] = fb_next[i]


@jit
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


@jit
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
