"""
The ED brake commanded as a force [N] (``blending: external``): ``coach_<i>/ed_brake/force``.

The controller under test asks motor car k (a vehicle with ``max_dynamic_brake_force`` > 0
that takes commands) for an ED force F_k >= 0 [N]. At once and then once per
``blending_period`` T the simulator turns it into the car's ED command

    c_k = -min(F_k / E_k(v_k), 1)      (0 when E_k = 0: at rest, or below no speed at all)

E_k(v) the ED force available at the car's present speed
(:func:`train_dynamics.physics.blending.ed_available`: the force, power, adhesion and
fade-out limits of ``kernel/traction.py``), so the achieved ED force is min(F_k, E_k) once
the command has built up (``traction_build_up_time``). Between two cycles the command is held
as a fraction: the force drifts with E_k(v) by at most T |dE_k/dt| (power-limited above the
corner speed: E = P / v, |dE/dt| = E a / v, 0.1 % of E at 300 km/h and 1 m/s^2 over 10 ms).

A motor car that has received a force command is owned by it: its fraction command
(``coach_<i>/traction/command``) is overwritten at the next cycle; F_k = 0 releases the ED.
"""
from __future__ import annotations

import math

import numpy as np

from train_dynamics.physics.blending import ed_available
from train_dynamics.physics.kernel.layout import INPUT, VEHICLE


def ed_force_rejection(value: float) -> str | None:
    """Return why an ED force command [N] is refused ('non_finite', 'out_of_range')."""
    if not math.isfinite(value):
        return 'non_finite'
    return 'out_of_range' if value < 0.0 else None


class EdForceCommands:
    """The motor cars' ED force commands of one train (see the module's text)."""

    def __init__(self, sim) -> None:
        """Attach to ``sim`` (a TrainSimulator with ``blending: external``)."""
        self.sim = sim
        c = sim.coach
        self.motors = [i for i in sim.consist.commanded if c[VEHICLE.DB_FORCE, i] > 0.0]
        self.period_steps = max(1, int(round(float(sim.cfg.blending_period) / sim.h)))
        self.reset()

    def reset(self) -> None:
        """
        No force commanded: the cars' fraction commands are their own.

        The cycles start with the first force command (a run without one is the run of
        before, step for step).
        """
        self.force: dict[int, float] = {}       # motor car (0-based) -> commanded ED force [N]
        self._running = False

    def set_force(self, value: float, index: int) -> None:
        """Command ED force ``value`` [N, >= 0] of motor car ``index`` (0-based)."""
        f = float(value)
        if ed_force_rejection(f) is not None:
            raise ValueError(f'ED force must be finite and >= 0 [N], got {value!r}')
        if index not in self.motors:
            raise ValueError(f'vehicle {index + 1} is not a motor car taking commands '
                             '(no ED brake)')
        self.force[index] = f
        self._command([index])
        if not self._running:           # the first cycle one period after this command
            self._running = True
            self._next_tick = self.sim.steps
            self._schedule_next()

    def _command(self, cars: list[int]) -> None:
        """Set the ED command of ``cars`` from their force commands at their present speeds."""
        if not cars:
            return
        c = self.sim.coach
        avail = ed_available(c, cars)
        want = np.array([self.force[i] for i in cars])
        cmd = np.zeros(len(cars))
        ok = avail > 0.0
        cmd[ok] = -np.minimum(want[ok] / avail[ok], 1.0)
        c[INPUT.T_CMD, np.asarray(cars, dtype=int)] = cmd

    def _cycle(self) -> None:
        """Refresh the commands at the present speeds; schedule the next cycle."""
        self._command(sorted(self.force))
        self._schedule_next()

    def _schedule_next(self) -> None:
        self._next_tick += self.period_steps
        self.sim.schedule(self._next_tick * self.sim.h, self._cycle)
