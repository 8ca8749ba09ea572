"""
The brake system: braking force (paper eqs. 12-13), brake pipe, distributors, cylinders.

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

from collections import namedtuple

import numpy as np

from train_dynamics.physics.kernel.compiler import jit

#: brake_input mode codes used inside the compiled kernels
PIPE_HEAD = 0
PIPE_PER_COACH = 1
CYLINDER_PER_COACH = 2
MODE_CODES = {'pipe_head': PIPE_HEAD, 'pipe_per_coach': PIPE_PER_COACH,
              'cylinder_per_coach': CYLINDER_PER_COACH}

#: fraction of p_max applied at the distributor's first stage (drop = sensitivity)
RELEASE_FRACTION_OF_SENSITIVITY = 0.5


@jit(inline=True)
def braking_force(p_cyl: np.ndarray, p_max: float, mu_a: float, mass: np.ndarray,
                  g: float, out: np.ndarray) -> np.ndarray:
    """
    Write the braking force Fb_i [N] of eq. (13), limited by adhesion (eq. 12), to ``out``.

    p_cyl gauge [Pa]; p_max gauge [Pa]; mass [kg]; g [m/s^2]. A cylinder pressure above
    p_max cannot brake harder than mu_a m g; a negative one does not brake at all.
    """
    for i in range(p_cyl.shape[0]):
        ratio = min(max(p_cyl[i] / p_max, 0.0), 1.0)
        out[i] = mu_a * mass[i] * g * ratio
    return out


def pipe_delays(n: int, coach_length: float, speed: float) -> np.ndarray:
    """Delay [s] of the brake wave at each coach: (i-1) L / c for coach i = 1..n."""
    return np.arange(n, dtype=float) * coach_length / speed


@jit
def delay_split(delay_steps: np.ndarray, k0: np.ndarray, frac: np.ndarray) -> None:
    """Split delays in steps into whole steps k0 and a fraction for interpolation."""
    for i in range(delay_steps.shape[0]):
        k0[i] = int(np.floor(delay_steps[i]))
        frac[i] = delay_steps[i] - k0[i]


@jit(inline=True)
def delay_line_push(ring: np.ndarray, pos: int, value: float) -> int:
    """Store the head pressure of a new step in the ring buffer; return the new position."""
    pos += 1
    if pos >= ring.shape[0]:
        pos = 0
    ring[pos] = value
    return pos


@jit(inline=True)
def delay_line_read(ring: np.ndarray, pos: int, k0: np.ndarray, frac: np.ndarray,
                    out: np.ndarray) -> None:
    """Head pressure k0 + frac steps ago at each coach (linear interpolation) [Pa]."""
    size = ring.shape[0]
    for i in range(k0.shape[0]):
        i0 = pos - int(k0[i])
        if i0 < 0:
            i0 += size
        i1 = i0 - 1
        if i1 < 0:
            i1 += size
        out[i] = (1.0 - frac[i]) * ring[i0] + frac[i] * ring[i1]


@jit(inline=True)
def distributor_target(p_pipe: np.ndarray, applied: np.ndarray, p_nominal: float,
                       p_full_service: float, sensitivity: float, p_max: float,
                       out: np.ndarray) -> np.ndarray:
    """
    Write each distributor's target cylinder pressure [Pa] to ``out``; update ``applied``.

    drop = p_nominal - p_pipe. Applies when drop > sensitivity, releases when
    drop < sensitivity/2 (hysteresis); while applied, target = p_max * drop /
    (p_nominal - p_full_service), limited to [0, p_max].
    """
    span = p_nominal - p_full_service
    for i in range(p_pipe.shape[0]):
        drop = p_nominal - p_pipe[i]
        if drop > sensitivity:
            applied[i] = True
        elif drop < RELEASE_FRACTION_OF_SENSITIVITY * sensitivity:
            applied[i] = False
        out[i] = p_max * min(max(drop / span, 0.0), 1.0) if applied[i] else 0.0
    return out


CylinderTables = namedtuple('CylinderTables', ['fill_t', 'fill_f', 'rel_t', 'rel_f',
                                               'rel_t_rising', 'rel_f_rising'])
CylinderTables.__doc__ = """Filling (p/p_max rising 0 -> 1 against time [s]) and release
(falling 1 -> 0) characteristics, one row per table set (a vehicle reads the set of its
row VEHICLE.TABLE: its brake regime's); ``*_rising`` are the release tables reversed, for
the inverse look-up."""


@jit(inline=True)
def make_tables(fill: np.ndarray, rel: np.ndarray):
    """
    Return the :class:`CylinderTables` of ``fill``, ``rel`` (2 R, L).

    Rows 2 k and 2 k + 1: times [s] and p/p_max of table set k (k = 0 .. R - 1).
    """
    return CylinderTables(fill[0::2].copy(), fill[1::2].copy(), rel[0::2].copy(),
                          rel[1::2].copy(), rel[0::2, ::-1].copy(), rel[1::2, ::-1].copy())


@jit(inline=True)
def table_interp(x: float, xp: np.ndarray, fp: np.ndarray) -> float:
    """
    Return fp at x by piecewise-linear look-up in (xp, fp), clamped at both ends.

    np.interp for one point; a linear scan is fastest for the short characteristics used
    here.
    """
    if x <= xp[0]:
        return fp[0]
    last = xp.shape[0] - 1
    if x >= xp[last]:
        return fp[last]
    k = 1
    while xp[k] < x:
        k += 1
    w = (x - xp[k - 1]) / (xp[k] - xp[k - 1])
    return fp[k - 1] + w * (fp[k] - fp[k - 1])


@jit(inline=True)
def cylinder_advance(p_cyl: np.ndarray, target: np.ndarray, dt: float, p_max: float,
                     tables, which: np.ndarray) -> None:
    """
    Move the cylinder pressures ``p_cyl`` [Pa] (in place) ``dt`` seconds toward ``target``.

    Rising: along the filling table; falling: along the release table
    (:class:`CylinderTables`, vehicle i the table set ``which[i]``: its regime's). The time
    on the curve at the present pressure is found by inverse interpolation, and the
    cylinder moves dt further along the curve.
    """
    for i in range(p_cyl.shape[0]):
        frac = min(max(p_cyl[i] / p_max, 0.0), 1.0)
        goal = min(max(target[i] / p_max, 0.0), 1.0)
        k = int(which[i])
        if goal > frac:
            tau = table_interp(frac, tables.fill_f[k], tables.fill_t[k])
            frac = min(table_interp(tau + dt, tables.fill_t[k], tables.fill_f[k]), goal)
        elif goal < frac:
            tau = table_interp(frac, tables.rel_f_rising[k], tables.rel_t_rising[k])
            frac = max(table_interp(tau + dt, tables.rel_t[k], tables.rel_f[k]), goal)
        else:
            continue
        p_cyl[i] = frac * p_max
