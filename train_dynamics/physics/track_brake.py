"""
Magnetic track brakes and linear eddy-current brakes: forces on the rail, not through wheels.

Each car with ``track_brake_force`` F_0 > 0 [N] (all its magnets together, at rest) brakes,
once applied, with

    F(v) = F_0 / (1 + |v| / v_h),

v_h = ``track_brake_half_speed`` [m/s] the speed at which the force has fallen to half (the
magnets' friction coefficient on the rail falls with speed; this hyperbolic law and its
default v_h = 30 m/s are a guess shaped after manufacturers' curves, which give about half
the standstill force near 100 km/h). The force does not depend on the wheel-rail adhesion:
it acts between the magnet and the rail (a large v_h gives a constant force).

A car with ``eddy_brake_force`` F_e > 0 [N] (its linear eddy-current brake at the critical
speed and the nominal air gap) brakes, once applied, with

    F(v, g) = F_e (g_0 / g)^2 2 (|v| / v_c) / (1 + (|v| / v_c)^2),

the classical eddy-current brake curve (rising from 0 at rest to its peak at the critical
speed v_c = ``eddy_brake_critical_speed``, then falling as 1 / v; the force of a magnet
scales as the square of its flux, hence (g_0 / g)^2 with the air gap g =
``eddy_brake_air_gap``, g_0 = 7 mm). Shape, v_c and g_0 are guesses marked as such; limits:
no heating of the rail, no field build-up beyond the delay, 0 at rest (it cannot hold a
train). It is applied and released with the track brakes.

The brakes are applied with the emergency brake (``blending: builtin``,
:mod:`train_dynamics.physics.blending`) after ``track_brake_delay`` [s] (lowering the magnets
and building up their field; a guess of 0.5 s), released at once with it. The force acts as
a static friction on the rail: the kernel's Davis-A channel (``kernel/step.py``,
``static_resistance``: it holds a vehicle at rest and never pushes it), so its work is in
``TrainSimulator.work_resistance``; :class:`TrackBrakes` books its own work [J] and impulse
[N s] (:attr:`TrackBrakes.work`, :attr:`TrackBrakes.impulse`) so a report can tell them
apart.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.kernel.layout import STATE, VEHICLE, WORK


#: nominal air gap g_0 of the eddy-current brake [m] (a guess: 7 mm, the order of the
#: ICE 3's)
EDDY_NOMINAL_GAP = 0.007


def eddy_brake_force(speed: np.ndarray, f_e: np.ndarray, v_c: np.ndarray,
                     gap: np.ndarray) -> np.ndarray:
    """Return F_e (g_0 / g)^2 2 (|v| / v_c) / (1 + (|v| / v_c)^2) [N] at ``speed`` [m/s]."""
    r = np.abs(speed) / v_c
    return f_e * (EDDY_NOMINAL_GAP / gap) ** 2 * 2.0 * r / (1.0 + r * r)


def track_brake_force(speed: np.ndarray, f0: np.ndarray, v_half: np.ndarray) -> np.ndarray:
    """Return the track brake force F_0 / (1 + |v| / v_h) [N] of each car at ``speed`` [m/s]."""
    return f0 / (1.0 + np.abs(speed) / v_half)


class TrackBrakes:
    """The magnetic track brakes of one train (cars with ``track_brake_force`` > 0)."""

    def __init__(self, sim) -> None:
        """Attach to ``sim``; the cars' Davis A is restored at :meth:`reset`."""
        self.sim = sim
        consist = sim.consist
        self.f0 = np.array(consist['track_brake_force'], dtype=float)
        self.v_half = np.array(consist['track_brake_half_speed'], dtype=float)
        self.eddy = np.array(consist['eddy_brake_force'], dtype=float)
        self.v_c = np.array(consist['eddy_brake_critical_speed'], dtype=float)
        self.gap = np.array(consist['eddy_brake_air_gap'], dtype=float)
        self.delay = float(sim.cfg.track_brake_delay)
        self.cars = np.flatnonzero((self.f0 > 0.0) | (self.eddy > 0.0))
        self.davis_a = sim.coach[VEHICLE.DAVIS_A].copy()
        self.reset()

    def reset(self) -> None:
        """Released, nothing booked."""
        self.applied_at: float | None = None      # [s] the application's instant
        self.force = np.zeros(self.sim.n)         # [N] acting now, per car
        self.work = 0.0                           # [J] since t = 0
        self.impulse = 0.0                        # [N s] since t = 0
        self._last: tuple[float, np.ndarray] | None = None   # (t [s], x [m]) of the last cycle
        self._write()

    def set_applied(self, applied: bool) -> None:
        """Apply (from now, acting after the delay) or release (at once) the track brakes."""
        if applied and self.applied_at is None:
            self.applied_at = self.sim.t
        elif not applied:
            self.applied_at = None

    def update(self) -> None:
        """Book the last period's force, then set the force for the next one (each cycle)."""
        if not self.cars.size:
            return
        sim = self.sim
        t = sim.t
        v = sim.coach[STATE.V]
        x = sim.coach[STATE.X].copy()
        if self._last is not None:       # the force held over the last cycle (zero-order hold)
            t0, x0 = self._last
            self.impulse += float(np.sum(self.force[v != 0.0])) * (t - t0)
            self.work += float(np.sum(self.force * np.abs(x - x0)))
        self._last = (t, x)
        active = self.applied_at is not None and t >= self.applied_at + self.delay - 1e-9
        force = np.zeros(sim.n)
        if active:
            k = self.cars
            force[k] = (track_brake_force(v[k], self.f0[k], self.v_half[k])
                        + eddy_brake_force(v[k], self.eddy[k], self.v_c[k], self.gap[k]))
        if np.any(force != self.force):
            self.force = force
            self._write()

    def restore(self) -> None:
        """Give the cars their own Davis A back (released; ``TrainSimulator.reset``)."""
        self.applied_at = None
        self.force = np.zeros(self.sim.n)
        self.sim.coach[VEHICLE.DAVIS_A] = self.davis_a

    def _write(self) -> None:
        """Put Davis A + the track brake force into the kernel's static resistance."""
        sim = self.sim
        sim._sync()
        sim.coach[VEHICLE.DAVIS_A] = self.davis_a + self.force
        sim.ws[WORK.XKEY] = np.nan      # recompute the static resistance at the next step
