"""The brake system: braking force (paper eqs. 12-13), brake pipe, distributors, cylinders.

Chain of the ``pipe_head`` mode, from the driver's brake valve to the wheel:

1. **Brake pipe** (:func:`delay_line_read`): the head-end pipe pressure reaches coach i after
   (i-1) * coach_length / brake_propagation_speed seconds (0.1 s per 25 m coach at 250 m/s,
   the paper's delay). A pure transport delay, as in the paper's numerical application.
2. **Distributor** (:func:`distributor_target`): turns the pipe-pressure drop below the
   running pressure (5 bar) into a target cylinder pressure. A drop within its sensitivity
   (default 0.3 bar) is ignored; beyond it the brake applies (first stage, 0.2 p_max),
   graduated, linearly up to p_max at full service (3.5 bar, a 1.5 bar drop); any deeper
   drop (emergency venting) gives p_max. When the pipe is recharged the target falls with it
   (graduated release) and the distributor releases completely once the pipe is back within
   half the sensitivity of the running pressure.
3. **Brake cylinder** (:func:`cylinder_advance`): follows its target along the filling
   characteristic when it must rise and along the release characteristic when it must fall.
   Both are tables of p/p_max against time, as measured on a test stand (paper Fig. 4):
   wherever the cylinder stands, it moves along the curve from the point of the curve at its
   present pressure, so a fill from empty reproduces the table exactly.
4. **Braking force** (:func:`braking_force`): eq. (13), Fb = mu_a m g p / p_max, bounded by
   the adhesion limit of eq. (12), Fb <= mu_a m g.

The ``pipe_per_coach`` mode enters at step 2, ``cylinder_per_coach`` at step 4. All pressures
are gauge [Pa]; all functions are vectorised over the coaches and compiled with numba.
"""
from __future__ import annotations

import numpy as np

from ._jit import jit

#: brake_input mode codes used inside the compiled kernels
PIPE_HEAD = 0
PIPE_PER_COACH = 1
CYLINDER_PER_COACH = 2
MODE_CODES = {'pipe_head': PIPE_HEAD, 'pipe_per_coach': PIPE_PER_COACH,
              'cylinder_per_coach': CYLINDER_PER_COACH}

#: fraction of p_max applied at the distributor's first stage (drop = sensitivity)
RELEASE_FRACTION_OF_SENSITIVITY = 0.5


@jit
def braking_force(p_cyl: np.ndarray, p_max: float, mu_a: float, mass: np.ndarray,
                  g: float) -> np.ndarray:
    """Braking force Fb_i [N], eq. (13), limited by adhesion, eq. (12).

    p_cyl gauge [Pa]; p_max gauge [Pa]; mass [kg]; g [m/s^2]. A cylinder pressure above
    p_max cannot brake harder than mu_a m g; a negative one does not brake at all.
    """
    out = np.empty(p_cyl.shape[0])
    for i in range(p_cyl.shape[0]):
        ratio = min(max(p_cyl[i] / p_max, 0.0), 1.0)
        out[i] = mu_a * mass[i] * g * ratio
    return out


def pipe_delays(n: int, coach_length: float, speed: float) -> np.ndarray:
    """Delay [s] of the brake wave at each coach: (i-1) L / c for coach i = 1..n."""
    return np.arange(n, dtype=float) * coach_length / speed


@jit
def delay_line_push(ring: np.ndarray, pos: int, value: float) -> int:
    """Store the head pressure of a new step in the ring buffer; return the new position."""
    pos = (pos + 1) % ring.shape[0]
    ring[pos] = value
    return pos


@jit
def delay_line_read(ring: np.ndarray, pos: int, delay_steps: np.ndarray, out: np.ndarray) -> None:
    """Head pressure ``delay_steps`` integration steps ago (linear interpolation) [Pa]."""
    size = ring.shape[0]
    for i in range(delay_steps.shape[0]):
        k0 = int(np.floor(delay_steps[i]))
        frac = delay_steps[i] - k0
        out[i] = (1.0 - frac) * ring[(pos - k0) % size] + frac * ring[(pos - k0 - 1) % size]


@jit
def distributor_target(p_pipe: np.ndarray, applied: np.ndarray, p_nominal: float,
                       p_full_service: float, sensitivity: float, p_max: float) -> np.ndarray:
    """Target cylinder pressure [Pa] of each distributor; updates ``applied`` in place.

    drop = p_nominal - p_pipe. Applies when drop > sensitivity, releases when
    drop < sensitivity/2 (hysteresis); while applied, target = p_max * drop /
    (p_nominal - p_full_service), limited to [0, p_max].
    """
    out = np.empty(p_pipe.shape[0])
    span = p_nominal - p_full_service
    for i in range(p_pipe.shape[0]):
        drop = p_nominal - p_pipe[i]
        if drop > sensitivity:
            applied[i] = True
        elif drop < RELEASE_FRACTION_OF_SENSITIVITY * sensitivity:
            applied[i] = False
        out[i] = p_max * min(max(drop / span, 0.0), 1.0) if applied[i] else 0.0
    return out


@jit
def cylinder_advance(p_cyl: np.ndarray, target: np.ndarray, dt: float, p_max: float,
                     fill_t: np.ndarray, fill_f: np.ndarray,
                     rel_t: np.ndarray, rel_f: np.ndarray) -> None:
    """Move the cylinder pressures ``p_cyl`` [Pa] (in place) ``dt`` seconds toward ``target``.

    Rising: along the filling table (fill_t [s], fill_f = p/p_max rising 0 -> 1).
    Falling: along the release table (rel_t [s], rel_f = p/p_max falling 1 -> 0).
    """
    rel_f_rising = rel_f[::-1].copy()
    rel_t_rising = rel_t[::-1].copy()
    for i in range(p_cyl.shape[0]):
        frac = min(max(p_cyl[i] / p_max, 0.0), 1.0)
        goal = min(max(target[i] / p_max, 0.0), 1.0)
        if goal > frac:      # time on the filling curve at this pressure, then dt further
            tau = np.interp(frac, fill_f, fill_t)
            frac = min(np.interp(tau + dt, fill_t, fill_f), goal)
        elif goal < frac:
            tau = np.interp(frac, rel_f_rising, rel_t_rising)
            frac = max(np.interp(tau + dt, rel_t, rel_f), goal)
        p_cyl[i] = frac * p_max
