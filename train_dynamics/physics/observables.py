"""
What the train shows: its outputs and its energy and momentum balances (read-only views).

:class:`TrainOutputs` reads the published quantities (positions, speeds, coupler and braking
forces, brake pressures, the vehicles' external forces) and :class:`TrainBalances` the terms
of the balances the tests check (eq. 8: momentum and impulse; kinetic + potential energy lost =
brake + resistance work + coupler dissipation - traction work). Both are mixins of
:class:`train_dynamics.physics.train.TrainSimulator`: they read its packed arrays (``coach``,
``cpl``, ``sc``, ``iv``, ``ws``; :mod:`train_dynamics.physics.kernel.layout`) after
``_sync()`` brings the error-controlled chain to the present tick, and copy what they return.
They change nothing.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics import couplers
from train_dynamics.physics.kernel.bogie import conditioned
from train_dynamics.physics.kernel.couplers import coupler_force_travel
from train_dynamics.physics.kernel.layout import (COUPLER, OUTPUT, PARAM, STATE, TABLE_ROWS,
                                                  TOTAL, VEHICLE, WORK)
from train_dynamics.physics.kernel.traction import adhesion


class TrainOutputs:
    """The train's published quantities (SI units; arrays are copies)."""

    @property
    def x(self) -> np.ndarray:
        self._sync()
        return self.coach[STATE.X].copy()

    @property
    def v(self) -> np.ndarray:
        self._sync()
        return self.coach[STATE.V].copy()

    @property
    def track_position(self) -> np.ndarray:
        """Return the track position of each vehicle's front [m]: its front at t = 0 + x_i."""
        self._sync()
        return self.coach[VEHICLE.FRONT0] + self.coach[STATE.X]

    @property
    def held(self) -> np.ndarray:
        """Coaches at rest, held by their brakes."""
        self._sync()
        return self.coach[STATE.HELD] > 0.5

    @property
    def y(self) -> np.ndarray:
        self._sync()
        x = self.coach[STATE.X]
        return x[:-1] - x[1:]

    @property
    def ydot(self) -> np.ndarray:
        self._sync()
        v = self.coach[STATE.V]
        return v[:-1] - v[1:]

    @property
    def coupler_force(self) -> np.ndarray:
        """F_i [N] at the present state: F at the end of the last step (t = 0: the law at y)."""
        self._sync()
        if self.steps == 0:
            y = self.y
            if not np.any(y):
                return np.zeros(self.n - 1)
            c = self.cpl
            return coupler_force_travel(y, self.ydot, c[COUPLER.KE], c[COUPLER.KF],
                                        c[COUPLER.KEC], c[COUPLER.KFC], c[COUPLER.GT],
                                        c[COUPLER.GC], c[COUPLER.ST], c[COUPLER.SC],
                                        c[COUPLER.KB], self.model, self.u, c)
        return self.ws[WORK.F, :self.n - 1].copy()

    @property
    def coupler_force_envelope(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Return the in-train force envelope: (largest tension, largest compression) [N, >= 0].

        Per coupler, over every integration step since t = 0 (not only the output samples:
        a buffer-blocking impact lasts a few tens of ms, so 100 Hz samples can miss its peak
        by 10 % and more).
        """
        self._sync()
        m = self.n - 1
        return self.ws[WORK.FHI, :m].copy(), 0.0 - self.ws[WORK.FLO, :m]

    @property
    def brake_force(self) -> np.ndarray:
        self._sync()
        return self.coach[OUTPUT.FB_APPLIED].copy()

    @property
    def total_brake_force(self) -> float:
        """Return the train's braking force [N, >= 0]: the sum of every Fb_i (eq. 13)."""
        return float(np.sum(self.brake_force))

    @property
    def cylinder_pressure(self) -> np.ndarray:
        p = self.coach[STATE.PCYL].copy()
        if np.any(self.pmax_ratio != 1.0):
            p *= self.pmax_ratio
        return p

    @property
    def buffer_stroke(self) -> np.ndarray:
        """Return each coupler's buffer stroke S_c [m] (the connection's, N-1 values)."""
        return self.cpl[COUPLER.SC].copy()

    @property
    def draw_gear_stroke(self) -> np.ndarray:
        """Return each coupler's draw-gear stroke S_t [m]."""
        return self.cpl[COUPLER.ST].copy()

    @property
    def buffer_slack(self) -> np.ndarray:
        """Return each coupler's buffer free play g_c [m]."""
        return self.cpl[COUPLER.GC].copy()

    @property
    def draw_gear_slack(self) -> np.ndarray:
        """Return each coupler's draw-gear free play g_t [m]."""
        return self.cpl[COUPLER.GT].copy()

    @property
    def traction_force(self) -> np.ndarray:
        """Return each vehicle's traction / dynamic-brake force [N, forward > 0]."""
        self._sync()
        return self.coach[OUTPUT.F_TRAC].copy()

    @property
    def resistance_force(self) -> np.ndarray:
        """Return each vehicle's running + curve resistance [N, on the vehicle, forward > 0]."""
        self._sync()
        return self.coach[OUTPUT.F_RES].copy()

    @property
    def gradient_force(self) -> np.ndarray:
        """Return each vehicle's gradient force [N, forward > 0]."""
        self._sync()
        return self.coach[OUTPUT.F_GRADE].copy()

    # -- wheelsets (wheelset.py): zeros without them ----------------------------------------
    @property
    def wheel_speed(self) -> np.ndarray:
        """Return each vehicle's wheel peripheral speed [m/s] (wheelsets; else its speed)."""
        if not self.wheelsets:
            return np.abs(self.v)
        return self.coach[STATE.WHEEL].copy()

    @property
    def creep_force(self) -> np.ndarray:
        """Return each vehicle's creep force of the last step [N, positive retarding]."""
        return self.coach[OUTPUT.F_CREEP].copy()

    @property
    def adhesion_used(self) -> np.ndarray:
        """Return each vehicle's creep force over its axle load [-] (last step)."""
        return self.coach[OUTPUT.ADH_USED].copy()

    @property
    def adhesion_available(self) -> np.ndarray:
        """Return each vehicle's available adhesion at its speed [-] (track, Curtius-Kniffler)."""
        return np.array([adhesion(s, a) for s, a in zip(self.v, self.coach[OUTPUT.ADH_LOW])])

    @property
    def wsp_valve(self) -> np.ndarray:
        """Return each vehicle's slide-protection valve state of the last step (0, 1, 2)."""
        return self.coach[OUTPUT.VALVE].astype(np.int8)

    @property
    def sliding_time(self) -> np.ndarray:
        """Return the time each vehicle's wheels slid since t = 0 [s] (wheel-flat risk)."""
        return self.coach[OUTPUT.SLIDE_T].copy()

    @property
    def sliding_distance(self) -> np.ndarray:
        """Return the distance each vehicle ran on sliding wheels since t = 0 [m]."""
        return self.coach[OUTPUT.SLIDE_X].copy()

    # -- per wheelset: a vehicle's, or its two bogies' (bogie_wheelsets, kernel/bogie.py) ---
    def _per_wheelset(self, one, bogie1, bogie2) -> np.ndarray:
        """Return ``one`` row per vehicle, or bogie 1 and 2 of each vehicle in turn."""
        if not getattr(self, 'bogies', False):
            return self.coach[one].copy()
        out = np.empty(2 * self.coach.shape[1])
        out[0::2] = self.coach[bogie1]
        out[1::2] = self.coach[bogie2]
        return out

    @property
    def wheelset_speeds(self) -> np.ndarray:
        """Return each wheelset's peripheral speed [m/s] (names: ``topics.wheelset_names``)."""
        if not getattr(self, 'bogies', False):
            return self.wheel_speed
        return self._per_wheelset(STATE.WHEEL, STATE.WHEEL, STATE.WHEEL_B2)

    @property
    def wheelset_creep_forces(self) -> np.ndarray:
        """Return each wheelset's creep force of the last step [N, positive retarding]."""
        return self._per_wheelset(OUTPUT.F_CREEP, OUTPUT.F_CREEP, OUTPUT.F_CREEP_B2)

    @property
    def wheelset_adhesion_available(self) -> np.ndarray:
        """
        Return each wheelset's available adhesion at its vehicle's speed [-].

        Per bogie: the kernel's, at the speed of the last step's start (kernel/bogie.py; at
        t = 0 computed here, as there: the track's low-speed adhesion, the trailing bogie's
        conditioned, falling with speed as Curtius-Kniffler).
        """
        if not getattr(self, 'bogies', False):
            return self.adhesion_available
        if self.steps > 0:
            return self._per_wheelset(OUTPUT.ADH_AVAIL, OUTPUT.ADH_AVAIL, OUTPUT.ADH_AVAIL_B2)
        out = np.empty(2 * self.n)
        c = float(self.sc[PARAM.CONDITION])
        for i, (v, low) in enumerate(zip(self.v, self.coach[OUTPUT.ADH_LOW])):
            lows = conditioned(float(low), v >= 0.0, c)
            out[2 * i:2 * i + 2] = [adhesion(v, a) for a in lows]
        return out

    @property
    def wheelset_valves(self) -> np.ndarray:
        """Return each wheelset's slide-protection valve state of the last step (0, 1, 2)."""
        return self._per_wheelset(OUTPUT.VALVE, OUTPUT.VALVE, OUTPUT.VALVE_B2).astype(np.int8)

    @property
    def bogie_cylinder_pressures(self) -> np.ndarray:
        """Return each bogie's brake-cylinder pressure, gauge [Pa] (bogie_wheelsets; else [])."""
        if not getattr(self, 'bogies', False):
            return np.zeros(0)
        return self._per_wheelset(STATE.PCYL_B1, STATE.PCYL_B1, STATE.PCYL_B2)

    @property
    def pipe_pressure(self) -> np.ndarray:
        return self.coach[STATE.PPIPE].copy()

    @property
    def auxiliary_pressure(self) -> np.ndarray | None:
        """Auxiliary-reservoir gauge pressures [Pa] (pneumatic brake), else None."""
        return None if self.pneu is None else self.pneu.auxiliary_pressure

    @property
    def control_pressure(self) -> np.ndarray | None:
        """Control-reservoir gauge pressures [Pa] (pneumatic brake), else None."""
        return None if self.pneu is None else self.pneu.control_pressure

    @property
    def ep_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """
        Return the EP / ECP state per vehicle (pneumatic brake), else None.

        (command the vehicle's valves follow [fraction of full service, 0 with the train
        line lost], valve state [+1 filling, 0 lapped, -1 venting], train line [1 healthy,
        0 lost]).
        """
        pneu = self.pneu
        if pneu is None:
            return None
        n = pneu.n
        return (np.full(n, pneu.ep_command_at_vehicles), pneu.valve_state,
                np.full(n, 1.0 if pneu.train_line else 0.0))

    @property
    def radio_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """
        Return the distributed-power radio state per remote locomotive, else None.

        (link [1 up, 0 lost], age of the last radio message received [s], pressure the
        remote's brake valve regulates to [Pa gauge]); remotes in train order.
        """
        pneu = self.pneu
        if pneu is None or not self.remotes:
            return None
        k = len(self.remotes)
        return (np.full(k, 1.0 if pneu.radio_ok else 0.0), np.full(k, pneu.radio_age),
                pneu.remote_command[self.remotes])


class TrainBalances:
    """Work, energy and momentum since t = 0 (eq. 8 and the energy balance)."""

    @property
    def work_resistance(self) -> float:
        """Return the work done by running and curve resistance since t = 0 [J]."""
        self._sync()
        return float(self.sc[TOTAL.WR])

    @property
    def work_traction(self) -> float:
        """Return the work of traction and dynamic braking on the train since t = 0 [J]."""
        self._sync()
        return float(self.sc[TOTAL.WT])

    @property
    def work_gravity(self) -> float:
        """Return the work of gravity since t = 0 [J] (the potential energy lost)."""
        self._sync()
        return float(self.sc[TOTAL.WG])

    @property
    def external_impulse(self) -> float:
        """Return the impulse of every external force since t = 0 [N s]."""
        self._sync()
        return float(self.sc[TOTAL.PEXT])

    @property
    def potential_energy(self) -> float:
        """Return the potential energy on the line's gradients [J] (0 at the lowest start)."""
        self._sync()
        return self.track.potential_energy(self.coach[STATE.X], self.consist['length'],
                                           self.masses, float(self.cfg.gravity))

    @property
    def work_brake(self) -> float:
        """Work done by the brakes since t = 0 [J]."""
        self._sync()
        return float(self.sc[TOTAL.WB])

    @property
    def work_wheel_brake(self) -> float:
        """Return the work of the brakes at the wheels since t = 0 [J] (wheelsets)."""
        return float(self.sc[TOTAL.WWB])

    @property
    def work_creep(self) -> float:
        """Return the work of the creep forces in the wheel-rail contacts since t = 0 [J]."""
        return float(self.sc[TOTAL.WCREEP])

    @property
    def wheel_kinetic_energy(self) -> float:
        """Return the kinetic energy of the wheelsets' rotation [J] (0 without wheelsets)."""
        if not self.wheelsets:
            return 0.0
        if getattr(self, 'bogies', False):     # each bogie: half the reduced mass
            return float(0.25 * np.sum(self.coach[VEHICLE.WHEEL_MASS] * (
                self.coach[STATE.WHEEL] ** 2 + self.coach[STATE.WHEEL_B2] ** 2)))
        return float(0.5 * np.sum(self.coach[VEHICLE.WHEEL_MASS] * self.coach[STATE.WHEEL] ** 2))

    @property
    def work_coupler(self) -> float:
        """Work done on the couplers since t = 0 [J] (stored elastic + dissipated)."""
        self._sync()
        return float(self.sc[TOTAL.WC])

    @property
    def kinetic_energy(self) -> float:
        """Return the kinetic energy [J], rotating masses included."""
        self._sync()
        return float(0.5 * np.sum(self.inertia * self.coach[STATE.V] ** 2))

    @property
    def elastic_energy(self) -> float:
        """Return the energy stored in the couplers' springs [J] (free play and blocking)."""
        self._sync()
        c = self.cpl
        return float(np.sum(couplers.elastic_energy_travel(
            self.y, self.ke, self.kec, c[COUPLER.GT], c[COUPLER.GC], c[COUPLER.ST],
            c[COUPLER.SC], c[COUPLER.KB], c[TABLE_ROWS])))

    @property
    def momentum(self) -> float:
        """Return the momentum [N s], rotating masses included."""
        self._sync()
        return float(np.sum(self.inertia * self.coach[STATE.V]))
