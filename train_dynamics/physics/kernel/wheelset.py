"""
Wheel slide in the train, compiled: creep law, implicit wheelset sub-step, slide protection.

The model (one lumped wheelset per vehicle, its creep-force law after Polach, the
backward-Euler sub-step, the reference slide protection) is described in
:mod:`train_dynamics.physics.wheelset`; this module holds what the kernel evaluates every
step when the train has wheelsets (OPTION.WHEELS), and the track's available adhesion
(OPTION.ADHESION), written once for the kernel and the single-vehicle model. The contact
itself (creep law, brake at the wheel, the implicit solve, the builtin valve) is in
:mod:`.creep`; two wheelsets per vehicle, one per bogie (PARAM.BOGIES), in :mod:`.bogie`.

Per step, in :func:`~.fixed_step.advance_chain`:

1. :func:`wsp_valves` after the brake system: each vehicle's valve (0 normal, 1 hold,
   2 vent; the builtin controller's or the input INPUT.VALVE) acts on its brake cylinder:
   hold keeps the pressure of the step's start, vent lets it fall with the dump valve's
   time constant VENT_TAU, both whatever an input commands (``cylinder_per_coach``, the
   pneumatic brake: the valves cut the cylinder off it, and a new input does not refill it,
   ``TrainSimulator._hold_cylinders``); after a release by the valves such a cylinder
   refills toward a higher input with REFILL_TAU, falls to a lower one at once (the
   distributors of the pipe modes refill it along their filling table);
2. :func:`wheelset_substep` after the braking force: the wheel speed to the step's end
   (backward Euler, :func:`wheelset_solve`) under the brake at the wheel's speed and the
   creep force at the vehicle's speed of the step's start; the vehicle's friction over the
   step (WORK.FB) becomes the creep force (positive retarding);
3. :func:`book_wheelsets` after the step is accepted: the creep work, sliding time and
   distance.
"""
from __future__ import annotations

import math

from train_dynamics.physics.kernel import bogie, friction
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.creep import (  # noqa: F401 (the model's names, here too)
    ACCEL_HOLD, builtin_valve, creep_and_slope, creep_coefficient, DECEL_VENT, DRY_ADHESION,
    HOLD, ITERATIONS, NORMAL, POLACH_A, POLACH_B, REFILL_TAU, sliding, SLIP_HOLD_A,
    SLIP_HOLD_B, SLIP_VENT_A, SLIP_VENT_B, U_TOL, V0, V_STICK, VENT, VENT_TAU, wheel_brake,
    wheelset_solve, WSP_BUILTIN, WSP_EXTERNAL, WSP_MIN_SPEED, WSP_MODES, WSP_NONE, XI0)
from train_dynamics.physics.kernel.layout import (INPUT, OPTION, OUTPUT, PARAM, STATE, TOTAL,
                                                  VEHICLE, WORK)
from train_dynamics.physics.kernel.track import profile_mean
from train_dynamics.physics.kernel.traction import adhesion


@jit
def track_adhesion(coach, aprof):
    """
    Write each vehicle's available adhesion at low speed [-] to OUTPUT.ADH_LOW.

    The mean over the vehicle's length of the track's adhesion (``aprof``: its deviation
    from DRY_ADHESION as a piecewise-constant profile, :class:`~.track`'s layout; 0 before
    the first position, so dry there).
    """
    ax = aprof[0]
    av = aprof[1]
    ac = aprof[2]
    out = coach[OUTPUT.ADH_LOW]
    for i in range(out.shape[0]):
        hi = coach[VEHICLE.FRONT0, i] + coach[STATE.X, i]
        out[i] = DRY_ADHESION + profile_mean(hi - coach[VEHICLE.LENGTH, i], hi, ax, av, ac)


@jit
def wsp_valves(coach, sc, iv, ws):
    """
    Apply each vehicle's slide-protection valve to its brake cylinder (module docstring).

    WORK.PCYL0 holds the cylinder pressures of the step's start [Pa]; OUTPUT.VALVE gets the
    valve state of the step. STATE.WSP_CUT marks a cylinder the valves have held or vented
    (cut off its input; cylinder inputs refill from there once the valves are normal).
    Per-bogie wheelsets (PARAM.BOGIES): :func:`~.bogie.bogie_valves` instead.
    """
    if sc[PARAM.BOGIES] != 0.0:
        bogie.bogie_valves(coach, sc, iv)
        return
    mode = iv[OPTION.WSP]
    h = sc[PARAM.H]
    p_cyl = coach[STATE.PCYL]
    p0 = ws[WORK.PCYL0]
    valve_out = coach[OUTPUT.VALVE]
    cut = coach[STATE.WSP_CUT]
    by_input = iv[OPTION.MODE] == 2      # brakes.CYLINDER_PER_COACH
    vent = math.exp(-h / VENT_TAU)
    refill = 1.0 - math.exp(-h / REFILL_TAU)
    for i in range(p_cyl.shape[0]):
        if mode == WSP_BUILTIN:
            valve = builtin_valve(abs(coach[STATE.V, i]), coach[STATE.WHEEL, i],
                                  coach[STATE.WDECEL, i])
        elif mode == WSP_EXTERNAL:
            valve = int(coach[INPUT.VALVE, i])
        else:
            valve = NORMAL
        valve_out[i] = valve
        if valve == HOLD:
            p_cyl[i] = p0[i]
            cut[i] = 1.0
        elif valve == VENT:
            # the valves cut an input-driven cylinder off its input, whatever it commands; a
            # distributor that releases faster than the dump valve is left to do so
            if by_input or p0[i] * vent < p_cyl[i]:
                p_cyl[i] = p0[i] * vent
            cut[i] = 1.0
        elif cut[i] != 0.0:
            if by_input and p_cyl[i] > p0[i]:
                p_cyl[i] = p0[i] + (p_cyl[i] - p0[i]) * refill
                if p_cyl[i] >= coach[INPUT.CYL, i] * (1.0 - 1e-3):
                    cut[i] = 0.0
            else:
                cut[i] = 0.0


@jit
def wheelset_substep(coach, sc, ws):
    """
    Advance every wheelset over the step; make its creep force the vehicle's friction.

    WORK.FB (the braking force over the step) is replaced by the creep force [N, positive
    retarding] of a moving vehicle; a vehicle at rest keeps its brake as the friction that
    holds it, limited by the adhesion (its wheel at rest). Books the brake's work at the
    wheel (TOTAL.WWB: h F_b (u0 + u1) / 2, exact for backward Euler with the wheel's
    kinetic energy) and leaves the step's mean wheel speed and start speed in WORK.UMEAN,
    VABS for :func:`book_wheelsets`. Per-bogie wheelsets (PARAM.BOGIES):
    :func:`~.bogie.bogie_substep` instead.
    """
    if sc[PARAM.BOGIES] != 0.0:
        bogie.bogie_substep(coach, sc, ws)
        return
    h = sc[PARAM.H]
    g = sc[PARAM.G]
    fb = ws[WORK.FB]
    fb_next = ws[WORK.FBNEXT]
    umean = ws[WORK.UMEAN]
    vabs = ws[WORK.VABS]
    wheel = coach[STATE.WHEEL]
    wdecel = coach[STATE.WDECEL]
    wwb = 0.0
    for i in range(fb.shape[0]):
        s = abs(coach[STATE.V, i])
        load = coach[VEHICLE.WEIGHT, i]
        mu = adhesion(s, coach[OUTPUT.ADH_LOW, i])
        u0 = wheel[i]
        vabs[i] = s
        coach[OUTPUT.ADH_AVAIL, i] = mu
        if s < V_STICK:     # at rest or nearly: Coulomb friction, wheels rolling
            fb[i] = min(fb[i], mu * load)
            wheel[i] = s
            wdecel[i] = 0.0
            umean[i] = -1.0         # book_wheelsets: the friction's work is the brake's
            coach[OUTPUT.F_CREEP, i] = fb[i] if s > 0.0 else 0.0
            coach[OUTPUT.ADH_USED, i] = coach[OUTPUT.F_CREEP, i] / load
            continue
        material = coach[VEHICLE.LAW0:VEHICLE.LAW0 + friction.LAW_LEN, i]
        normal = max(coach[STATE.PCYL, i] * coach[VEHICLE.BRAKE_GAIN, i]
                     - coach[VEHICLE.BRAKE_OFF, i], 0.0)
        # the first guess: the wheel's last deceleration carried on over the step
        u1, fc, fbw = wheelset_solve(u0, s, h, coach[VEHICLE.WHEEL_MASS, i], load, mu,
                                     fb_next[i], material, normal, coach[VEHICLE.BLOCKS, i],
                                     coach[VEHICLE.RHO, i], g, u0 - h * wdecel[i])
        wwb += h * fbw * 0.5 * (u0 + u1)
        umean[i] = 0.5 * (u0 + u1)
        wheel[i] = u1
        wdecel[i] = (u0 - u1) / h
        fb[i] = fc
        coach[OUTPUT.F_CREEP, i] = fc
        coach[OUTPUT.ADH_USED, i] = fc / load
    sc[TOTAL.WWB] += wwb


@jit
def book_wheelsets(coach, sc, ws):
    """
    Book the creep work and the sliding of the accepted step.

    Creep work h F_c ((|v0| + |v1|) / 2 - (u0 + u1) / 2) [J] (TOTAL.WCREEP); below V_STICK
    the friction's work F |dx| is the brake's (TOTAL.WWB: the wheel rolls); a wheel that
    ends the step sliding (:func:`sliding`) adds h to OUTPUT.SLIDE_T [s] and the vehicle's
    displacement to OUTPUT.SLIDE_X [m]. A vehicle that stopped keeps its wheel at rest.
    Per-bogie wheelsets (PARAM.BOGIES): :func:`~.bogie.book_bogies` instead.
    """
    if sc[PARAM.BOGIES] != 0.0:
        bogie.book_bogies(coach, sc, ws)
        return
    h = sc[PARAM.H]
    wcreep = 0.0
    umean = ws[WORK.UMEAN]
    vabs = ws[WORK.VABS]
    x_old = ws[WORK.XOLD]
    for i in range(umean.shape[0]):
        if vabs[i] == 0.0:
            continue
        v1 = abs(coach[STATE.V, i])
        if umean[i] < 0.0:
            sc[TOTAL.WWB] += coach[OUTPUT.F_CREEP, i] * abs(coach[STATE.X, i] - x_old[i])
            coach[STATE.WHEEL, i] = v1
            continue
        if v1 == 0.0:
            coach[STATE.WHEEL, i] = 0.0
        wcreep += h * coach[OUTPUT.F_CREEP, i] * (0.5 * (vabs[i] + v1) - umean[i])
        if sliding(v1, coach[STATE.WHEEL, i]):
            coach[OUTPUT.SLIDE_T, i] += h
            coach[OUTPUT.SLIDE_X, i] += abs(coach[STATE.X, i] - x_old[i])
    sc[TOTAL.WCREEP] += wcreep


@jit(inline=True)
def adhesion_limit(coach, out):
    """
    Limit each vehicle's braking force ``out`` [N] to what the adhesion carries (in place).

    A train without wheelsets (PARAM.ADHLIM): a braked wheel cannot pass more force to the
    rail than the available adhesion, Fb_i <= mu(|v_i|) m_i g (mu: Curtius-Kniffler's law
    from the vehicle's low-speed adhesion OUTPUT.ADH_LOW, the track's or dry, as the
    wheelsets take it, :func:`~.traction.adhesion`; m_i g = VEHICLE.WEIGHT [N], the
    vehicle's weight on its wheels; v_i the chain's present speed [m/s]). The demand beyond it
    goes to OUTPUT.ADH_CUT [N] (0 where the limit does not bind): those wheels slide
    (:func:`book_adhesion_slide`). Where it does not bind ``out`` is left untouched, bit for
    bit.
    """
    for i in range(out.shape[0]):
        cap = adhesion(coach[STATE.V, i], coach[OUTPUT.ADH_LOW, i]) * coach[VEHICLE.WEIGHT, i]
        if out[i] > cap:
            coach[OUTPUT.ADH_CUT, i] = out[i] - cap
            out[i] = cap
        else:
            coach[OUTPUT.ADH_CUT, i] = 0.0


@jit(inline=True)
def book_adhesion_slide(coach, h):
    """
    Count the sliding of a train without wheelsets over a step of h [s] (adhesion limit).

    A moving vehicle whose braking force the adhesion limited (OUTPUT.ADH_CUT > 0,
    :func:`adhesion_limit`) slides: h to OUTPUT.SLIDE_T [s] and h |v| (its speed at the
    step's end) to OUTPUT.SLIDE_X [m], as the wheelsets book a sliding wheel.
    """
    for i in range(coach.shape[1]):
        s = abs(coach[STATE.V, i])
        if coach[OUTPUT.ADH_CUT, i] > 0.0 and s > 0.0:
            coach[OUTPUT.SLIDE_T, i] += h
            coach[OUTPUT.SLIDE_X, i] += h * s
