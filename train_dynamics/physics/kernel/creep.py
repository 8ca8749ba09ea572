"""
The wheel-rail contact of a lumped wheelset, compiled: creep law, brake at the wheel, sub-step.

What a wheelset of the train is made of, for the vehicle's lumped wheelset
(:mod:`.wheelset`) and the bogies' (:mod:`.bogie`): the constants of the creep-force law
after Polach and of the reference slide protection, the creep law and its slope, the
sliding test, the builtin valve, the brake's force at the wheel and the implicit sub-step
(backward Euler, safeguarded Newton). The model is described in
:mod:`train_dynamics.physics.wheelset`.
"""
from __future__ import annotations

import math

from train_dynamics.physics.kernel import friction
from train_dynamics.physics.kernel.compiler import jit
from train_dynamics.physics.kernel.traction import CK_AT_REST

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
