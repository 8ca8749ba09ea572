"""
Running resistance on the Python side: the equivalent mass, the analytic coast-down speed.

The coast-down speed is a reference for the tests.

Davis (1926): R = A + B |v| + C v^2 [N], compiled in
:mod:`train_dynamics.physics.kernel.resistance`.
Inertia: a vehicle accelerates its rotating masses (wheelsets, gears, motors) too; the
equivalent mass for inertia is m (1 + rotating_mass_factor). Gravity, the braking force (paper
eq. 13) and the resistance use m. Typical factors (Wende, Fahrdynamik des Schienenverkehrs,
2003): locomotives 0.15-0.30, coaches 0.04-0.10, loaded wagons 0.03-0.05, empty 0.08-0.10.
"""
from __future__ import annotations

import numpy as np


def equivalent_mass(mass, rotating_mass_factor) -> np.ndarray:
    """Return m (1 + rotating_mass_factor) [kg]: the mass for inertia."""
    return np.asarray(mass, dtype=float) * (1.0 + np.asarray(rotating_mass_factor, dtype=float))


def coast_down_speed(t, v0: float, m_eq: float, a: float, b: float, c: float) -> np.ndarray:
    """
    Return v(t) [m/s] of a single vehicle coasting down from v0 under Davis resistance alone.

    m_eq dv/dt = -(a + b v + c v^2), closed form for c > 0 and 4 a c > b^2 (the usual case):
    with w = sqrt(4 a c - b^2) / 2, v(t) = (w tan(atan((v0 + b/2c) c / w) - w t / m_eq)
    - b/2) / c, until the vehicle stops (then 0). For c = 0 the linear law gives
    v = (v0 + a/b) exp(-b t/m) - a/b (b > 0) or v0 - a t / m.
    """
    t = np.asarray(t, dtype=float)
    if c > 0.0:
        disc = 4.0 * a * c - b * b
        if disc <= 0.0:
            raise ValueError('closed form needs 4 a c > b^2')
        w = 0.5 * np.sqrt(disc)
        phase = np.arctan((c * v0 + 0.5 * b) / w) - w * t / m_eq
        v = (w * np.tan(phase) - 0.5 * b) / c
        t_stop = m_eq / w * (np.arctan((c * v0 + 0.5 * b) / w) - np.arctan(0.5 * b / w))
    elif b > 0.0:
        v = (v0 + a / b) * np.exp(-b * t / m_eq) - a / b
        t_stop = m_eq / b * np.log((v0 + a / b) / (a / b)) if a > 0.0 else np.inf
    else:
        v = v0 - a * t / m_eq
        t_stop = m_eq * v0 / a if a > 0.0 else np.inf
    return np.where(t < t_stop, v, 0.0)
