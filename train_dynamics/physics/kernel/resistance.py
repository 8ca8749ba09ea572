"""
Running resistance of a vehicle (Davis 1926), compiled.

R = A + B |v| + C v^2 [N] for a vehicle at speed v [m/s], always against the motion: A
(journal and rolling resistance, the static part) [N], B (flange friction, oscillations)
[N s/m], C (air) [N s^2/m^2]. At standstill the resistance acts like a brake: it holds the
vehicle up to its static value A (plus the curve resistance) and never pushes it (the
integrator's active set does this, together with the brake). The equivalent mass for inertia
is in :mod:`train_dynamics.physics.resistance`.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.compiler import jit


@jit
def davis(speed: float, a: float, b: float, c: float) -> float:
    """Return the magnitude of the running resistance [N] at speed [m/s] (Davis)."""
    s = abs(speed)
    return a + (b + c * s) * s


@jit
def running_resistance(v: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                       out: np.ndarray) -> np.ndarray:
    """Fill ``out`` with each vehicle's resistance magnitude [N] at its speed v [m/s]."""
    for i in range(v.shape[0]):
        out[i] = davis(v[i], a[i], b[i], c[i])
    return out
