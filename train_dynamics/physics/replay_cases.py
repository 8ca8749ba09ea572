"""
The kHz replay case: four unequal coaches whose cylinder pressures change at 1 kHz instants.

One case, written once, that the accuracy benchmark (``bench/accuracy.py``, case
``khz_unequal``) and the tests of inputs at their own instants and of the multirate step
(``test/input_cases.py``) run against the independent reference
(:func:`train_dynamics.physics.chain_reference.solve_chain`): coaches of 45, 30, 60 and 25 t,
the tanh coupler law with u = 700 s/m (a sharp friction band), the brake-cylinder pressures
given directly (``brake_input: cylinder_per_coach``, the paper's way with measured
fillings). At every millisecond a draw decides whether the pressures change; a change sets
each coach to 0, 30, 60 or 100 % of p_max at random, so edges fall between the 2 ms ticks.
Units SI: s, Pa, N, kg.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.config import SimConfig

#: the coaches' masses [kg]
KHZ_MASSES = (45000.0, 30000.0, 60000.0, 25000.0)
#: the case's parameters (u [s/m]); a run may add its own (integrator settings)
KHZ_SETTINGS = {'masses': list(KHZ_MASSES), 'brake_input': 'cylinder_per_coach',
                'scale_factor': 700.0}
#: the levels a change draws from, fractions of p_max [-]
KHZ_LEVELS = (0.0, 0.3, 0.6, 1.0)


def khz_config(**overrides) -> SimConfig:
    """Return the case's configuration, with ``overrides`` (parameters) on top."""
    return SimConfig.from_dict({**KHZ_SETTINGS, **overrides})


def khz_pressures(cfg: SimConfig, t_end: float, seed: int,
                  change_probability: float) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the replayed cylinder pressures: (instants [s], pressures [Pa] per coach).

    One draw per millisecond in [0, ``t_end``) (``numpy.random.default_rng(seed)``): with
    ``change_probability`` the pressures change to random :data:`KHZ_LEVELS` times
    ``cfg.max_cylinder_pressure``. Only t = 0 and the instants where a pressure changes are
    returned.
    """
    pmax = cfg.max_cylinder_pressure
    rng = np.random.default_rng(seed)
    times = np.arange(int(t_end * 1000)) * 1e-3
    n = len(KHZ_MASSES)
    levels = np.empty((times.size, n))
    cur = np.zeros(n)
    for k in range(times.size):
        if rng.random() < change_probability:
            cur = rng.choice(list(KHZ_LEVELS), size=n) * pmax
        levels[k] = cur
    keep = np.r_[True, np.any(np.diff(levels, axis=0) != 0.0, axis=1)]
    return times[keep], levels[keep]


def khz_braking_forces(cfg: SimConfig, levels: np.ndarray) -> np.ndarray:
    """Return the braking forces [N] of the pressures ``levels`` [Pa]: eq. 13, mu_a m g p/p_max."""
    full = cfg.adhesion_coefficient * np.array(KHZ_MASSES) * cfg.gravity
    return levels / cfg.max_cylinder_pressure * full
