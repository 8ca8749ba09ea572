"""
The line's forces, compiled: profile means, gradient force and curve resistance per vehicle.

The mean of a gradient or curve profile over a vehicle's length, and from it the gradient
force and the curve resistance of each vehicle.

The profiles, Roeckl's curve resistance and the sign conventions are described in
:mod:`train_dynamics.physics.track` (the :class:`~train_dynamics.physics.track.Track` that
builds the arrays these functions read).
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.compiler import jit


@jit(inline=True)
def profile_integral(s: float, xs: np.ndarray, vals: np.ndarray, cum: np.ndarray) -> float:
    """Return the integral of the piecewise-constant profile from -infinity to s."""
    if xs.shape[0] == 0 or s <= xs[0]:
        return 0.0
    k = np.searchsorted(xs, s, side='right') - 1
    return cum[k] + vals[k] * (s - xs[k])


@jit(inline=True)
def profile_mean(lo: float, hi: float, xs: np.ndarray, vals: np.ndarray,
                 cum: np.ndarray) -> float:
    """
    Return the mean of the profile over [lo, hi] (hi > lo) [the profile's unit].

    A span inside one piece gets that piece's value exactly; a span across pieces the
    difference of the running integrals over its length (whose rounding grows with the
    distance from the profile's first position: 1e-11 relative for a piece starting 1000 km
    back).
    """
    if xs.shape[0] == 0 or hi <= xs[0]:
        return 0.0
    k = np.searchsorted(xs, hi, side='right') - 1
    if lo >= xs[k]:
        return vals[k]
    return (cum[k] + vals[k] * (hi - xs[k]) - profile_integral(lo, xs, vals, cum)) / (hi - lo)


@jit
def track_forces(x: np.ndarray, front0: np.ndarray, lengths: np.ndarray, weight: np.ndarray,
                 gx: np.ndarray, gv: np.ndarray, gc: np.ndarray, cx: np.ndarray,
                 cv: np.ndarray, cc: np.ndarray, grade: np.ndarray, curve: np.ndarray) -> None:
    """
    Fill the gradient force [N, signed, forward > 0] and curve resistance [N, >= 0].

    x: travelled distances [m]; front0: the front of each vehicle at t = 0 [m]; weight: m g
    [N]; (gx, gv, gc) the gradient profile [per mille], (cx, cv, cc) the curve-resistance
    profile [per mille]. An empty profile gives 0.
    """
    for i in range(x.shape[0]):
        hi = front0[i] + x[i]
        lo = hi - lengths[i]
        grade[i] = 0.0
        curve[i] = 0.0
        if gx.shape[0] > 0:
            grade[i] = -weight[i] * profile_mean(lo, hi, gx, gv, gc) * 1e-3
        if cx.shape[0] > 0:
            curve[i] = weight[i] * profile_mean(lo, hi, cx, cv, cc) * 1e-3
