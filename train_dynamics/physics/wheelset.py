"""
Wheel slide: available adhesion, the creep-force law, the wheelset sub-step and slide protection.

One lumped wheelset per vehicle: all its wheelsets turn together (equal brake and equal
axle load), inertia J [kg m^2] (sum over the wheelsets), wheel radius r [m]; the reduced mass
J / r^2 [kg] carries the wheel's peripheral speed u [m/s].

**Available adhesion** (:func:`available_adhesion`): mu_avail(v) = mu_low f(v) / f(0), with
Curtius and Kniffler's dry-rail law f(v) = 0.161 + 7.5 / (3.6 v + 44) (the one traction uses,
:func:`~train_dynamics.physics.kernel.traction.adhesion`) and mu_low the available adhesion
at low speed: 0.33 on dry rail, the track's ``track_adhesion`` where given (UIC 541-05's
low-adhesion conditions are 0.02-0.10; the WSP tests of EN 15595 run at about 0.05-0.07).

**Creep-force law** (:func:`creep_coefficient`), a saturating law with a falling branch after
Polach (Polach, "Creep forces in simulations of traction vehicles running on adhesion
limit", Wear 258, 2005): with the slip speed w = v - u [m/s] and the creep xi = w / max(v, V0)

    f(w, v) = mu_avail(v) [(1 - A) exp(-B |w|) + A] tanh(xi / XI0)

rising over a creep of a few XI0 (0.2 %) to mu_avail, then falling with the slip speed to the
sliding friction A mu_avail (A = 0.4, B = 0.6 s/m: Polach's dry-rail parameters). The creep
force on the wheel is F_c = f N forward (N = m g the axle loads), minus that on the vehicle.

**Sub-step** (:func:`wheelset_step`, implicit): the wheelset's time constant is a few ms
(J / r^2 over the slope of the creep law), so it is integrated by backward Euler, a scalar
equation per vehicle solved by bisection (the residual is monotone: the creep law's
falling slope is small against J / (r^2 h)):

    J / r^2 (u1 - u0) = h (F_c(v0 - u1) - F_b(u1))

with the brake force at the wheel F_b (:mod:`~train_dynamics.physics.friction`) at the new
wheel speed; at u = 0 the brake is static friction up to F_b(0): the wheel stays locked while
J / r^2 u0 + h F_c(v0) <= h F_b(0). The vehicle then gets the creep force of the step,
F_c(v0 - u1): the coupling is explicit in the vehicle speed, implicit in the wheel speed.
The work of the step's forces is taken with the step's mean speeds, so the brake work
h F_b (u0 + u1) / 2 and the creep work h F_c ((v0 + v1) - (u0 + u1)) / 2 close the energy
balance of vehicle and wheelset exactly.

**Slide protection** (:func:`builtin_wsp`): per vehicle a hold and a vent valve on the brake
cylinder (0 normal, 1 hold, 2 vent), on slip and deceleration thresholds (EN 15595's
principle): vent when the slip exceeds SLIP_VENT or the wheel decelerates faster than
DECEL_VENT, hold while the slip exceeds SLIP_HOLD or the wheel accelerates back (faster than
ACCEL_HOLD), normal otherwise. The reference speed is the vehicle's speed (a perfect speed
estimate: the reference WSP is an upper bound of what a controller can do).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from train_dynamics.physics import friction
from train_dynamics.physics.kernel.traction import adhesion
from train_dynamics.physics.kernel.wheelset import (  # noqa: F401 (the model's names)
    ACCEL_HOLD, builtin_valve, creep_coefficient, DECEL_VENT, DRY_ADHESION, HOLD, NORMAL,
    POLACH_A, POLACH_B, sliding, SLIP_HOLD_A, SLIP_HOLD_B, SLIP_VENT_A, SLIP_VENT_B, V0, VENT,
    VENT_TAU, WSP_MODES, XI0)

#: bisection iterations of the single-vehicle implicit sub-step (a 2^-60 bracket: round-off)
ITERATIONS = 60


def available_adhesion(v: float, mu_low: float) -> float:
    """Return the available adhesion [-] at speed v [m/s] for mu_low at low speed."""
    return adhesion(v, mu_low)


def wheelset_step(u0: float, v0: float, h: float, reduced_mass: float, load: float,
                  mu_avail: float, brake) -> tuple[float, float, float]:
    """
    Return (u1, F_c, F_b): wheel speed [m/s] at the step's end, creep and brake force [N].

    Backward Euler of J/r^2 du/dt = F_c - F_b (module docstring); ``brake(u)`` the brake's
    force at the wheel [N] at wheel speed u; load = N [N]; v0 the vehicle speed [m/s].
    """
    def creep(u):
        return load * creep_coefficient(v0 - u, v0, mu_avail)

    fb0 = brake(0.0)
    if reduced_mass * u0 + h * creep(0.0) <= h * fb0:        # static friction holds it
        return 0.0, creep(0.0), (reduced_mass * u0 + h * creep(0.0)) / h
    lo, hi = 0.0, max(u0, v0) + h * load / reduced_mass + 1e-9
    for _ in range(ITERATIONS):
        mid = 0.5 * (lo + hi)
        if reduced_mass * (mid - u0) - h * (creep(mid) - brake(mid)) > 0.0:
            hi = mid
        else:
            lo = mid
    u1 = 0.5 * (lo + hi)
    return u1, creep(u1), brake(u1)


def builtin_wsp(v_ref: float, u: float, u_prev: float, h: float) -> int:
    """Return the valve state (NORMAL, HOLD, VENT) of the reference slide protection."""
    return builtin_valve(v_ref, u, (u_prev - u) / h)


@dataclass
class BrakeTest:
    """
    One vehicle braking from ``v0`` on the level: the single-vehicle brake test.

    Cylinder: first order toward the demanded pressure, time constant ``fill_tau`` [s] when
    filling, ``vent_tau`` [s] when the vent valve is open; held with the hold valve. Brake
    force at the wheel: the normal force ``normal_full`` [N] at full pressure scaled with
    p / p_max, through the friction ``material`` (a friction.MATERIAL_CODES value).
    """

    mass: float = 50_000.0
    v0: float = 100.0 / 3.6
    material: int = friction.DISC
    normal_full: float = 150_000.0
    blocks: int = 16
    radius_ratio: float = 1.0
    inertia: float = 4 * 110.0
    radius: float = 0.46
    mu_low: float = DRY_ADHESION
    wsp: str = 'none'
    fill_tau: float = 1.0
    vent_tau: float = VENT_TAU
    h: float = 0.005
    g: float = 9.81
    trace: dict = field(default_factory=dict)

    def brake_force(self, p_frac: float, u: float) -> float:
        """Return the brake's force at the wheel [N] at pressure p/p_max and wheel speed u."""
        normal = self.normal_full * p_frac
        if normal <= 0.0:
            return 0.0
        return friction.retarding_force(self.material, u, normal, self.blocks,
                                        self.radius_ratio, self.g)

    def run(self, t_end: float = 400.0) -> dict:
        """Brake fully at t = 0 until the vehicle stops; return the figures and the trace."""
        m, h, g = self.mass, self.h, self.g
        jr = self.inertia / self.radius ** 2
        load = m * g
        v = u = self.v0
        u_prev = u
        p = 0.0
        x = t = 0.0
        w_brake = w_creep = 0.0
        impulse = 0.0
        zero_time = longest_zero = slide_time = slide_distance = 0.0
        e0 = 0.5 * m * v * v + 0.5 * jr * u * u
        rows = []
        while v > 0.0 and t < t_end:
            valve = NORMAL
            if self.wsp == 'builtin':
                valve = builtin_wsp(v, u, u_prev, h)
            if valve == NORMAL:
                p += (1.0 - p) * (1.0 - math.exp(-h / self.fill_tau))
            elif valve == VENT:
                p *= math.exp(-h / self.vent_tau)
            mu = available_adhesion(v, self.mu_low)
            u1, fc, fb = wheelset_step(u, v, h, jr, load, mu,
                                       lambda w, pf=p: self.brake_force(pf, w))
            v1 = v - h * fc / m
            if v1 < 0.0:            # stops inside the step: end at the last full step
                break
            w_brake += h * fb * 0.5 * (u + u1)
            w_creep += h * fc * 0.5 * ((v + v1) - (u + u1))
            impulse += h * fc
            x += h * 0.5 * (v + v1)
            if sliding(v, u1):
                slide_time += h
                slide_distance += h * 0.5 * (v + v1)
            zero_time = zero_time + h if u1 == 0.0 else 0.0
            longest_zero = max(longest_zero, zero_time)
            u_prev, u, v = u, u1, v1
            t += h
            rows.append((t, v, u, p, fc, valve))
        e1 = 0.5 * m * v * v + 0.5 * jr * u * u
        self.trace = np.array(rows)
        return {'distance': x, 'time': t, 'v_end': v, 'brake_work': w_brake,
                'creep_work': w_creep, 'energy_drop': e0 - e1, 'initial_energy': e0,
                'impulse': impulse, 'momentum_drop': m * (self.v0 - v),
                'longest_locked': longest_zero, 'sliding_time': slide_time,
                'sliding_distance': slide_distance}


def speed_sensor(u: np.ndarray, t_ns: int, resolution: float, noise: float,
                 seed: int) -> np.ndarray:
    """
    Return the wheel speeds [m/s] a speed sensor reports for the true speeds ``u`` at ``t_ns``.

    u + noise n (n standard normal, one draw per vehicle from a generator seeded with
    (seed, t_ns): the same output time gives the same draws, in the node and offline), held
    >= 0, then rounded to the nearest multiple of ``resolution`` (a toothed wheel counted
    over a gate time: resolution = 2 pi r / (teeth gate)); 0 and 0: ``u`` itself.
    """
    if noise == 0.0 and resolution == 0.0:
        return u
    out = np.asarray(u, dtype=float)
    if noise > 0.0:
        draw = np.random.default_rng((int(seed), int(t_ns))).standard_normal(out.shape)
        out = np.maximum(out + noise * draw, 0.0)
    if resolution > 0.0:
        out = resolution * np.floor(out / resolution + 0.5)
    return out


def adhesion_limited_distance(v0: float, mu_low: float, g: float = 9.81, n: int = 2001) -> float:
    """Return the ideal stopping distance [m] at the available adhesion: int v dv / (mu(v) g)."""
    speeds = np.linspace(0.0, v0, n)
    f = speeds / np.array([available_adhesion(s, mu_low) * g for s in speeds])
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(speeds)))
