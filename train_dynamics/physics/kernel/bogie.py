"""
Per-bogie wheelsets, compiled: two lumped wheelsets per vehicle, one per bogie.

With ``bogie_wheelsets`` (PARAM.BOGIES) each vehicle runs on two lumped wheelsets, bogie 1
(the front one) and bogie 2 (the rear one), instead of one (:mod:`.wheelset`). Each bogie
carries half the vehicle's weight (N / 2 [N]), half its wheelset inertia (J / (2 r^2)
[kg]) and half its friction brake (half the blocks or discs: at equal cylinder pressure
half the normal force, eq. 13 halved for the paper's brake), and has its own brake cylinder
(STATE.PCYL_B1, PCYL_B2 [Pa]) behind its own pair of slide-protection valves (hold, vent;
OUTPUT.VALVE, VALVE_B2; the inputs INPUT.VALVE, VALVE_B2 with ``wsp: external``): the
valves sit between the vehicle's brake source and the bogie's cylinder, as a multiple
unit's per-bogie dump valves sit behind its relay or EP valve (EN 15595's principle: the
WSP acts on the cylinder of the wheelsets it protects). The source is STATE.PCYL, the
pressure the brake system gives (distributor, input, brake control unit), which the valves
never change here (with one wheelset per vehicle they act on STATE.PCYL itself).

Per step, called from :mod:`.wheelset`'s :func:`~.wheelset.wsp_valves`,
:func:`~.wheelset.wheelset_substep` and :func:`~.wheelset.book_wheelsets`:

1. :func:`bogie_valves`: each bogie's valve (the builtin controller on the bogie's own
   wheel, or the input) acts on its cylinder: hold keeps its pressure, vent lets it fall
   with VENT_TAU (the supply cut off, whatever the source does); after a release by the
   valves (CUT_B1, CUT_B2) it refills toward a higher source with REFILL_TAU and falls to
   a lower one at once; otherwise it is the source's pressure;
2. :func:`bogie_substep`: each bogie's wheel over the step (backward Euler,
   :func:`~.creep.wheelset_solve`, with the bogie's load, inertia, adhesion and brake);
   the vehicle's friction over the step (WORK.FB) is the sum of both creep forces; below
   V_STICK the brake holds the vehicle, each bogie limited by its adhesion;
3. :func:`book_bogies`: the creep work of both wheels, the vehicle's sliding (either
   bogie sliding counts: OUTPUT.SLIDE_T, SLIDE_X).

Two equal bogies on the same rail (no valve acting) give the vehicle's lumped wheelset bit
for bit: each bogie's masses and forces are the vehicle's halved (a power of two, exact in
floating point), so the solve runs the same iterates and the halves sum to the whole.

**Rail conditioning.** The leading bogie (bogie 1 when the vehicle moves forward, bogie 2
backward) runs first over the rail and conditions it for the trailing one: a contaminated
rail's adhesion recovers under the passage and the creep of wheels (the cleaning effect:
Voltr and Lata, "Transient wheel-rail adhesion characteristics under the cleaning effect of
sliding", Vehicle System Dynamics 53(5), 2015; the adhesion improves along a train on a
low-adhesion section, which EN 15595's WSP tests see as the train's conditioning). The
model: the trailing bogie's available adhesion at low speed is

    mu_t = mu_l + c max(mu_dry - mu_l, 0),

mu_l the leading bogie's (the track's, OUTPUT.ADH_LOW), mu_dry = DRY_ADHESION, c =
``rail_conditioning`` (PARAM.CONDITION) in [0, 1]: 0 no conditioning (the default), 1 a
clean rail behind the first bogie. c is a model figure, not a measured one (a guess: the
cited measurements show the recovery, its size depends on the contaminant), constant, not
tied to the leading wheel's slip; it acts within a vehicle only (the next vehicle's leading
bogie sees the track's adhesion again).
"""
from __future__ import annotations

import math

from train_dynamics.physics.kernel import friction
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.creep import (
    builtin_valve, DRY_ADHESION, HOLD, NORMAL, REFILL_TAU, sliding, V_STICK, VENT, VENT_TAU,
    wheel_brake, wheelset_solve, WSP_BUILTIN, WSP_EXTERNAL)
from train_dynamics.physics.kernel.layout import (INPUT, OPTION, OUTPUT, PARAM, STATE, TOTAL,
                                                  VEHICLE, WORK)
from train_dynamics.physics.kernel.traction import adhesion


@jit(inline=True)
def _valve(mode, v_ref, u, decel, command):
    """Return a bogie's valve state: the builtin controller's, the input's or NORMAL."""
    if mode == WSP_BUILTIN:
        return builtin_valve(v_ref, u, decel)
    if mode == WSP_EXTERNAL:
        return int(command)
    return NORMAL


@jit(inline=True)
def _cylinder(p, source, valve, cut, vent, refill):
    """
    Return (pressure [Pa], cut) of a bogie's cylinder after the step (module docstring).

    p its pressure at the step's start, source the brake system's pressure at the step's
    end, vent = exp(-h / VENT_TAU), refill = 1 - exp(-h / REFILL_TAU).
    """
    if valve == HOLD:
        return p, 1.0
    if valve == VENT:
        return p * vent, 1.0
    if cut != 0.0 and source > p:
        p = p + (source - p) * refill
        return p, (0.0 if p >= source * (1.0 - 1e-3) else 1.0)
    return source, 0.0


@jit(inline=True)
def bogie_valves(coach, sc, iv):
    """Apply each bogie's slide-protection valves to its cylinder (module docstring, 1)."""
    mode = iv[OPTION.WSP]
    h = sc[PARAM.H]
    vent = math.exp(-h / VENT_TAU)
    refill = 1.0 - math.exp(-h / REFILL_TAU)
    for i in range(coach.shape[1]):
        v = abs(coach[STATE.V, i])
        source = coach[STATE.PCYL, i]
        valve = _valve(mode, v, coach[STATE.WHEEL, i], coach[STATE.WDECEL, i],
                       coach[INPUT.VALVE, i])
        coach[OUTPUT.VALVE, i] = valve
        coach[STATE.PCYL_B1, i], coach[STATE.CUT_B1, i] = _cylinder(
            coach[STATE.PCYL_B1, i], source, valve, coach[STATE.CUT_B1, i], vent, refill)
        valve = _valve(mode, v, coach[STATE.WHEEL_B2, i], coach[STATE.WDECEL_B2, i],
                       coach[INPUT.VALVE_B2, i])
        coach[OUTPUT.VALVE_B2, i] = valve
        coach[STATE.PCYL_B2, i], coach[STATE.CUT_B2, i] = _cylinder(
            coach[STATE.PCYL_B2, i], source, valve, coach[STATE.CUT_B2, i], vent, refill)


@jit(inline=True)
def conditioned(mu_low, forward, c):
    """
    Return the low-speed adhesion [-] of bogie 1 and bogie 2 (rail conditioning).

    The trailing bogie's mu_l + c max(DRY_ADHESION - mu_l, 0), the leading one's mu_l;
    ``forward``: the vehicle moves forward (bogie 1 leads).
    """
    trailing = mu_low + c * max(DRY_ADHESION - mu_low, 0.0)
    if forward:
        return mu_low, trailing
    return trailing, mu_low


@jit(inline=True)
def _paper_half(p, sc, bmass):
    """Return half the paper's braking force, eq. (13), at cylinder pressure p [Pa] [N]."""
    ratio = min(max(p / sc[PARAM.PMAX], 0.0), 1.0)
    return 0.5 * (sc[PARAM.MU] * bmass * sc[PARAM.G] * ratio)


@jit
def bogie_substep(coach, sc, ws):
    """
    Advance both wheelsets of every vehicle over the step (module docstring, 2).

    WORK.FB becomes the sum of the bogies' creep forces [N, positive retarding]; a vehicle
    below V_STICK keeps its brake (the trapezoid WORK.FB while both cylinders are the
    source's; else the bogies' brakes at the step's end), each bogie's half limited by its
    adhesion. Books the brakes' work at the wheels (TOTAL.WWB) and leaves the mean wheel
    speeds in WORK.UMEAN, UMEAN_B2 and the start speed in VABS for :func:`book_bogies`.
    """
    h = sc[PARAM.H]
    g = sc[PARAM.G]
    c = sc[PARAM.CONDITION]
    fb = ws[WORK.FB]
    vabs = ws[WORK.VABS]
    wwb = 0.0
    for i in range(fb.shape[0]):
        s = abs(coach[STATE.V, i])
        load = 0.5 * coach[VEHICLE.WEIGHT, i]
        low1, low2 = conditioned(coach[OUTPUT.ADH_LOW, i], coach[STATE.V, i] >= 0.0, c)
        mu1 = adhesion(s, low1)
        mu2 = adhesion(s, low2)
        vabs[i] = s
        coach[OUTPUT.ADH_AVAIL, i] = mu1
        coach[OUTPUT.ADH_AVAIL_B2, i] = mu2
        p1 = coach[STATE.PCYL_B1, i]
        p2 = coach[STATE.PCYL_B2, i]
        material = coach[VEHICLE.LAW0:VEHICLE.LAW0 + friction.LAW_LEN, i]
        gain = coach[VEHICLE.BRAKE_GAIN, i]
        off = coach[VEHICLE.BRAKE_OFF, i]
        blocks = 0.5 * coach[VEHICLE.BLOCKS, i]
        rho = coach[VEHICLE.RHO, i]
        bmass = coach[VEHICLE.BMASS, i]
        normal1 = 0.5 * max(p1 * gain - off, 0.0)
        normal2 = 0.5 * max(p2 * gain - off, 0.0)
        paper1 = _paper_half(p1, sc, bmass)
        paper2 = _paper_half(p2, sc, bmass)
        if s < V_STICK:     # at rest or nearly: Coulomb friction, wheels rolling
            source = coach[STATE.PCYL, i]
            if p1 == source and p2 == source:
                f1 = 0.5 * fb[i]
                f2 = f1
            else:
                f1 = wheel_brake(s, paper1, material, normal1, blocks, rho, g)
                f2 = wheel_brake(s, paper2, material, normal2, blocks, rho, g)
            f1 = min(f1, mu1 * load)
            f2 = min(f2, mu2 * load)
            fb[i] = f1 + f2
            coach[STATE.WHEEL, i] = s
            coach[STATE.WHEEL_B2, i] = s
            coach[STATE.WDECEL, i] = 0.0
            coach[STATE.WDECEL_B2, i] = 0.0
            ws[WORK.UMEAN, i] = -1.0    # book_bogies: the friction's work is the brakes'
            if s == 0.0:
                f1 = 0.0
                f2 = 0.0
            coach[OUTPUT.F_CREEP, i] = f1
            coach[OUTPUT.F_CREEP_B2, i] = f2
            coach[OUTPUT.ADH_USED, i] = f1 / load
            coach[OUTPUT.ADH_USED_B2, i] = f2 / load
            continue
        jr = 0.5 * coach[VEHICLE.WHEEL_MASS, i]
        u0 = coach[STATE.WHEEL, i]
        d0 = coach[STATE.WDECEL, i]
        u1, fc1, fbw = wheelset_solve(u0, s, h, jr, load, mu1, paper1, material, normal1,
                                      blocks, rho, g, u0 - h * d0)
        wwb += h * fbw * 0.5 * (u0 + u1)
        ws[WORK.UMEAN, i] = 0.5 * (u0 + u1)
        coach[STATE.WHEEL, i] = u1
        coach[STATE.WDECEL, i] = (u0 - u1) / h
        u0 = coach[STATE.WHEEL_B2, i]
        d0 = coach[STATE.WDECEL_B2, i]
        u1, fc2, fbw = wheelset_solve(u0, s, h, jr, load, mu2, paper2, material, normal2,
                                      blocks, rho, g, u0 - h * d0)
        wwb += h * fbw * 0.5 * (u0 + u1)
        ws[WORK.UMEAN_B2, i] = 0.5 * (u0 + u1)
        coach[STATE.WHEEL_B2, i] = u1
        coach[STATE.WDECEL_B2, i] = (u0 - u1) / h
        fb[i] = fc1 + fc2
        coach[OUTPUT.F_CREEP, i] = fc1
        coach[OUTPUT.F_CREEP_B2, i] = fc2
        coach[OUTPUT.ADH_USED, i] = fc1 / load
        coach[OUTPUT.ADH_USED_B2, i] = fc2 / load
    sc[TOTAL.WWB] += wwb


@jit(inline=True)
def book_bogies(coach, sc, ws):
    """
    Book the creep work of both wheels and the vehicle's sliding (module docstring, 3).

    As :func:`~.wheelset.book_wheelsets`, per bogie: h F_c,j ((|v0| + |v1|) / 2 - u_mean,j)
    [J] to TOTAL.WCREEP; below V_STICK the friction's work is the brakes' (TOTAL.WWB).
    """
    h = sc[PARAM.H]
    wcreep = 0.0
    vabs = ws[WORK.VABS]
    x_old = ws[WORK.XOLD]
    for i in range(vabs.shape[0]):
        if vabs[i] == 0.0:
            continue
        v1 = abs(coach[STATE.V, i])
        dx = abs(coach[STATE.X, i] - x_old[i])
        f1 = coach[OUTPUT.F_CREEP, i]
        f2 = coach[OUTPUT.F_CREEP_B2, i]
        if ws[WORK.UMEAN, i] < 0.0:
            sc[TOTAL.WWB] += (f1 + f2) * dx
            coach[STATE.WHEEL, i] = v1
            coach[STATE.WHEEL_B2, i] = v1
            continue
        if v1 == 0.0:
            coach[STATE.WHEEL, i] = 0.0
            coach[STATE.WHEEL_B2, i] = 0.0
        vm = 0.5 * (vabs[i] + v1)
        wcreep += h * f1 * (vm - ws[WORK.UMEAN, i]) + h * f2 * (vm - ws[WORK.UMEAN_B2, i])
        if sliding(v1, coach[STATE.WHEEL, i]) or sliding(v1, coach[STATE.WHEEL_B2, i]):
            coach[OUTPUT.SLIDE_T, i] += h
            coach[OUTPUT.SLIDE_X, i] += dx
    sc[TOTAL.WCREEP] += wcreep
