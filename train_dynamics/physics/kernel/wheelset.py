"""
Wheel slide in the train, compiled: creep law, implicit wheelset sub-step, slide protection.

The model (one lumped wheelset per vehicle, its creep-force law after Polach, the
backward-Euler sub-step, the reference slide protection) is described in
:mod:`train_dynamics.physics.wheelset`; this module holds what the kernel evaluates every
step when the train has wheelsets (OPTION.WHEELS), and the track's available adhesion
(OPTION.ADHESION), written once for the kernel and the single-vehicle model.

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

from train_dynamics.physics.kernel import friction
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.layout import (INPUT, OPTION, OUTPUT, PARAM, STATE, TOTAL,
                                                  VEHICLE, WORK)
from train_dynamics.physics.kernel.track import profile_mean
from train_dynamics.physics.kernel.traction import adhesion, CK_AT_REST

#: dry-rail available adhesion at low speed (Curtius-Kniffler at rest, 0.331)
DRY_ADHESION = CK_AT_REST
#: Polach's falling friction on dry rail: sliding fraction A [-] and decay B [s/m] (Polach,
#: Wear 258, 2005, table of the parameters for dry rail)
POLACH_A = 0.4
POLACH_B = 0.6
#: creep scale of the rising branch [-] (0.2 %: the adhesion maximum at a creep of a few
#: tenths of a per cent, Polach's figures) and the smallest reference speed of the creep [m/s]
XI0 = 0.002
V0 = 0.5
#: valve states of the slide protection (input ``coach_<i>/wsp/valve``)
NORMAL, HOLD, VENT = 0, 1, 2
#: the parameter ``wsp``: its choices in the order of their codes
WSP_MODES = ('none', 'builtin', 'external')
WSP_NONE, WSP_BUILTIN, WSP_EXTERNAL = range(len(WSP_MODES))
#: builtin WSP thresholds: slip speed w > min(a + b v_ref, c v_ref) ([m/s], [-]; c = 0.5 to
#: vent, 0.25 to hold, so a wheel at rest under a moving vehicle is always vented), wheel
#: deceleration and acceleration [m/s^2]; chosen on the single-vehicle test at 0.05 adhesion
#: (EN 15595 describes the principle, slip and deceleration thresholds, not their values)
SLIP_VENT_A = 0.5
SLIP_VENT_B = 0.03
SLIP_HOLD_A = 0.2
SLIP_HOLD_B = 0.01
DECEL_VENT = 2.0
ACCEL_HOLD = 3.0
#: [m/s] below this reference speed the slide protection leaves the brake alone (normal): a
#: train at rest must stay braked (a vent on the creep of a stopped train's couplers would
#: release it); EN 15595 lets WSP switch off at a low speed, this figure is our choice
WSP_MIN_SPEED = 0.05
#: [s] cylinder vent time constant through the dump valve (a guess: WSP dump valves empty a
#: passenger cylinder from 3.8 bar to below 0.5 bar in about 0.3 s)
VENT_TAU = 0.15
#: [s] refill time constant of an input-driven cylinder after the valves released it (a
#: guess, of the order of the P brake's first filling second)
REFILL_TAU = 1.0
#: [m/s] below this speed a vehicle's wheels roll with it and the rail's friction is the
#: brake's, limited by the adhesion (Coulomb, as at rest): the creep law's slip reference V0
#: makes the friction vanish with the slip, so without this a stopped train on locked wheels
#: would creep on for ever at micrometres per second (our choice, in the WSP's dead band)
V_STICK = WSP_MIN_SPEED
#: iterations of the safeguarded Newton solve at most, and its tolerance on the wheel speed
#: relative to 1 m/s + the vehicle's speed (1e-10: the wheel's momentum balance to about
#: 1e-7 N s per step; the energy identity of the step holds with the converged speed)
ITERATIONS = 60
U_TOL = 1e-10


@jit(inline=True)
def creep_coefficient(w: float, v: float, mu_avail: float) -> float:
    """
    Return the creep-force coefficient f [-] at slip speed w = v - u [m/s], speed v [m/s].

    f = mu_avail [(1 - A) exp(-B |w|) + A] tanh(xi / XI0), xi = w / max(|v|, V0).
    """
    xi = w / max(abs(v), V0)
    return mu_avail * ((1.0 - POLACH_A) * math.exp(-POLACH_B * abs(w)) + POLACH_A) \
        * math.tanh(xi / XI0)


@jit(inline=True)
def creep_and_slope(w: float, v: float, mu_avail: float):
    """Return (f, df/dw) of :func:`creep_coefficient` with one exp and one tanh."""
    ref = max(abs(v), V0)
    e = math.exp(-POLACH_B * abs(w))
    th = math.tanh(w / ref / XI0)
    sgn = 1.0 if w > 0.0 else (-1.0 if w < 0.0 else 0.0)
    fall = (1.0 - POLACH_A) * e + POLACH_A
    return (mu_avail * fall * th,
            mu_avail * (-(1.0 - POLACH_A) * POLACH_B * sgn * e * th
                        + fall * (1.0 - th * th) / (ref * XI0)))


@jit(inline=True)
def sliding(v: float, u: float) -> bool:
    """Tell whether a wheel at u [m/s] slides under a vehicle at v [m/s] (the vent threshold)."""
    return v - u > min(SLIP_VENT_A + SLIP_VENT_B * v, 0.5 * v)


@jit(inline=True)
def builtin_valve(v_ref: float, u: float, decel: float) -> int:
    """Return the valve state of the reference slide protection (module docstring)."""
    if v_ref < WSP_MIN_SPEED:
        return NORMAL
    slip = v_ref - u
    if sliding(v_ref, u) or decel > DECEL_VENT:
        return VENT
    if slip > min(SLIP_HOLD_A + SLIP_HOLD_B * v_ref, 0.25 * v_ref) or -decel > ACCEL_HOLD:
        return HOLD
    return NORMAL


@jit(inline=True)
def wheel_brake(u: float, fb_paper: float, material, normal: float, blocks: float,
                rho: float, g: float) -> float:
    """
    Return the brake's force at the wheel [N] at wheel speed u [m/s] (paper: fb_paper).

    ``material`` the vehicle's friction law (kernel/friction.py: LAW_LEN numbers, kind first).
    """
    if material[0] == friction.PAPER_LAW:
        return fb_paper
    if normal <= 0.0:
        return 0.0
    return friction.law_friction(material, u, normal / blocks) * normal * rho


@jit(inline=True)
def wheelset_solve(u0, v, h, jr, load, mu, fb_paper, material, normal, blocks, rho, g,
                   guess):
    """
    Return (u1, F_c, F_b): the wheel speed [m/s] after h [s], creep and brake force [N].

    Backward Euler of jr du/dt = F_c(v - u) - F_b(u) (jr = J / r^2 [kg], load = N [N],
    v >= 0 the vehicle's speed [m/s], mu the available adhesion): static friction holds a
    locked wheel while jr u0 + h F_c(v) <= h F_b(0) (F_b then the friction that holds it;
    only looked at when the brake could stop the wheel within the step); else a safeguarded
    Newton iteration from ``guess`` [m/s] (the caller's extrapolation of the wheel speed) on
    the bracket [0, u_max] (bisection where a Newton step leaves it; the derivative leaves out
    the brake's slow change with speed), ending at the first Newton point whose residual is
    within the tolerance (d U_TOL, d the residual's slope): with the creep force linearised
    at the point it stepped from (the residual then the brake's change and the creep law's
    curvature over the step), or at a point whose Newton step is at most U_TOL, with that
    point's forces. The caller's guess makes one evaluation of the creep law the rule.
    """
    fb0 = wheel_brake(0.0, fb_paper, material, normal, blocks, rho, g)
    if jr * u0 <= h * fb0:      # the brake could stop the wheel within the step
        fc0 = load * creep_coefficient(v, v, mu)
        if jr * u0 + h * fc0 <= h * fb0:
            return 0.0, fc0, (jr * u0 + h * fc0) / h
    lo = 0.0
    hi = max(u0, v) + h * load / jr + 1e-9
    u = min(max(guess, 0.0), hi)
    tol = U_TOL * (1.0 + v)
    c2 = (max(v, V0) * XI0) ** 2
    fc = 0.0
    fb = 0.0
    for _ in range(ITERATIONS):
        f, slope = creep_and_slope(v - u, v, mu)
        fc = load * f
        fb = wheel_brake(u, fb_paper, material, normal, blocks, rho, g)
        r = jr * (u - u0) - h * (fc - fb)
        d = jr + h * load * slope
        if d > 0.0:
            step = r / d
            un = u - step
            # accept the Newton point with the creep force linearised at u when the
            # linearisation error h N |f''| step^2 / 2 (|f''| <= mu / c^2, c = ref XI0, for
            # c <= 0.29: speeds below 145 m/s) and the brake's change h |F_b(un) - F_b(u)|
            # leave a residual of at most d tol, as a converged point's own forces do
            if un >= 0.0 and h * load * mu * step * step <= 2.0 * d * tol * c2:
                fbn = wheel_brake(un, fb_paper, material, normal, blocks, rho, g)
                if h * abs(fbn - fb) <= d * tol:
                    return un, fc + load * slope * step, fbn
        else:
            un = -1.0
        if r > 0.0:
            hi = u
        else:
            lo = u
        if hi - lo <= tol:
            break
        if not (lo < un < hi):
            un = 0.5 * (lo + hi)
        u = un
    return u, fc, fb


@jit(inline=True)
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


@jit(inline=True)
def wsp_valves(coach, sc, iv, ws):
    """
    Apply each vehicle's slide-protection valve to its brake cylinder (module docstring).

    WORK.PCYL0 holds the cylinder pressures of the step's start [Pa]; OUTPUT.VALVE gets the
    valve state of the step. STATE.WSP_CUT marks a cylinder the valves have held or vented
    (cut off its input; cylinder inputs refill from there once the valves are normal).
    """
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


@jit(inline=True)
def wheelset_substep(coach, sc, ws):
    """
    Advance every wheelset over the step; make its creep force the vehicle's friction.

    WORK.FB (the braking force over the step) is replaced by the creep force [N, positive
    retarding] of a moving vehicle; a vehicle at rest keeps its brake as the friction that
    holds it, limited by the adhesion (its wheel at rest). Books the brake's work at the
    wheel (TOTAL.WWB: h F_b (u0 + u1) / 2, exact for backward Euler with the wheel's
    kinetic energy) and leaves the step's mean wheel speed and start speed in WORK.UMEAN,
    VABS for :func:`book_wheelsets`.
    """
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


@jit(inline=True)
def book_wheelsets(coach, sc, ws):
    """
    Book the creep work and the sliding of the accepted step.

    Creep work h F_c ((|v0| + |v1|) / 2 - (u0 + u1) / 2) [J] (TOTAL.WCREEP); below V_STICK
    the friction's work F |dx| is the brake's (TOTAL.WWB: the wheel rolls); a wheel that
    ends the step sliding (:func:`sliding`) adds h to OUTPUT.SLIDE_T [s] and the vehicle's
    displacement to OUTPUT.SLIDE_X [m]. A vehicle that stopped keeps its wheel at rest.
    """
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
