"""
The compiled drivers behind one signature: ``driver(n_steps, sync, arrays)``.

:class:`KernelArrays` names the packed arrays a driver advances in place (layouts:
:mod:`.layout`); :data:`DRIVERS` maps each ``integrator`` method
(:mod:`train_dynamics.physics.config.integrator`) to its driver. ``fixed`` and ``multirate``
share the fixed-step driver (:func:`.fixed_step.advance_chain`; multirate acts where the
``MRTOL`` row is > 0), ``adaptive`` is error control (:func:`.adaptive.advance_adaptive`). Each
returns (steps, status). Plain Python (not compiled): the jitted drivers keep their own
argument lists.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from train_dynamics.physics.kernel import adaptive, fixed_step


class KernelArrays(NamedTuple):
    """The packed arrays of one train (:mod:`.layout`), as the drivers take them."""

    coach: np.ndarray     # per-vehicle rows (COACH)
    cpl: np.ndarray       # per-coupler rows (COUPLER)
    sc: np.ndarray        # scalars (SCALAR)
    iv: np.ndarray        # integers (INTEGER)
    fill: np.ndarray      # cylinder filling characteristic
    rel: np.ndarray       # cylinder release characteristic
    ring: np.ndarray      # brake-pipe delay line [Pa]
    ws: np.ndarray        # workspace (WORK)
    gprof: np.ndarray     # gradient profile
    cprof: np.ndarray     # curve profile
    aprof: np.ndarray     # adhesion profile
    tick_fb: np.ndarray   # error control: available braking force per tick [N]
    tick_te: np.ndarray   # error control: traction force per tick [N]


def advance_fixed(n_steps: int, sync: bool, a: KernelArrays) -> tuple[int, int]:
    """Advance ``n_steps`` fixed steps (``sync`` unused: the chain is always at the tick)."""
    return fixed_step.advance_chain(n_steps, a.coach, a.cpl, a.sc, a.iv, a.fill, a.rel,
                                    a.ring, a.ws, a.gprof, a.cprof, a.aprof)


def advance_error_controlled(n_steps: int, sync: bool, a: KernelArrays) -> tuple[int, int]:
    """Advance ``n_steps`` ticks with error control; ``sync``: bring the chain to the tick."""
    return adaptive.advance_adaptive(n_steps, sync, a.coach, a.cpl, a.sc, a.iv, a.fill, a.rel,
                                     a.ring, a.ws, a.gprof, a.cprof, a.aprof, a.tick_fb,
                                     a.tick_te)


Driver = Callable[[int, bool, KernelArrays], tuple[int, int]]

#: integrator method -> driver
DRIVERS: dict[str, Driver] = {'fixed': advance_fixed, 'multirate': advance_fixed,
                              'adaptive': advance_error_controlled}
