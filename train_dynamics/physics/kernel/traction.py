"""
Traction and dynamic (electric) braking of a locomotive.

The command c in [-1, 1] (input ``coach_<i>/traction/command``) is a fraction of the force
available at the present speed v [m/s]: c > 0 traction, forward; c < 0 dynamic braking,
against the motion. The force follows the command through a rate limit: it takes
``traction_build_up_time`` seconds to go from 0 to the full command (the locomotive's
control ramps the motor current; UIC 544-1 / EN 14198 expect a few seconds).

Available force (the locomotive's tractive-effort curve, e.g. a manufacturer's data sheet):

- traction: min(max_tractive_force, max_power / |v|, mu(v) m g)
- dynamic brake: min(max_dynamic_brake_force, max_dynamic_brake_power / |v|, mu(v) m g),
  faded linearly to 0 below ``dynamic_brake_fade_speed`` (the motors generate no force at rest)

mu(v) = traction_adhesion * f(v) / f(0) with Curtius and Kniffler's adhesion law
f(v) = 0.161 + 7.5 / (3.6 |v| + 44) (v in m/s, 3.6 v in km/h): 0.33 at rest, 0.21 at 100 km/h.
"""
from __future__ import annotations

from train_dynamics.physics.kernel.compiler import jit

#: Curtius-Kniffler adhesion at standstill, 0.161 + 7.5 / 44
CK_AT_REST = 0.161 + 7.5 / 44.0


@jit
def adhesion(speed: float, mu0: float) -> float:
    """Return the available adhesion coefficient at speed [m/s] (Curtius-Kniffler, mu(0) = mu0)."""
    return mu0 * (0.161 + 7.5 / (3.6 * abs(speed) + 44.0)) / CK_AT_REST


@jit
def available_force(speed: float, f_max: float, p_max: float, mu0: float, weight: float) -> float:
    """Return min(f_max, p_max / |v|, mu(v) m g) [N]; weight = m g [N]."""
    f = min(f_max, adhesion(speed, mu0) * weight)
    s = abs(speed)
    if p_max * 1.0 < f * s:         # the power limit binds (never at rest)
        f = p_max / s
    return f


@jit
def traction_force(command: float, speed: float, f_t: float, p_t: float, f_db: float,
                   p_db: float, v_fade: float, mu0: float, weight: float) -> float:
    """
    Return the force [N, forward > 0] of a locomotive at the (effective) ``command``.

    command > 0: command * traction available at ``speed`` [m/s], forward; command < 0:
    |command| * dynamic braking available, against the motion, faded below v_fade [m/s].
    """
    if command > 0.0:
        return command * available_force(speed, f_t, p_t, mu0, weight)
    if command < 0.0 and speed != 0.0:
        f = available_force(speed, f_db, p_db, mu0, weight) * min(abs(speed) / v_fade, 1.0)
        return command * f if speed > 0.0 else -command * f
    return 0.0


@jit
def ramp(current: float, target: float, dt: float, build_up_time: float) -> float:
    """Return the effective command after dt [s]: toward target at 1 / build_up_time per s."""
    if build_up_time <= 0.0:
        return target
    step = dt / build_up_time
    if target > current:
        return min(target, current + step)
    return max(target, current - step)
