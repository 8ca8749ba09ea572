"""
What a controller commands of the train: the inputs of :class:`~.train.TrainSimulator`.

Brake-pipe and brake-cylinder pressures (gauge [Pa], zero-order hold: a value takes effect at
once and holds until the next), the track's adhesion, the slide-protection valves, the
locomotives' traction commands and the EP / ECP train line. A mixin over the simulator's
packed state (:mod:`train_dynamics.physics.kernel.layout`): every setter writes the rows the
kernel reads at its next step; nothing here integrates.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics import track as track_module
from train_dynamics.physics.kernel import brakes, couplers, wheelset
from train_dynamics.physics.kernel.layout import (CACHE, CLOCK, INPUT, OPTION, OUTPUT, PARAM,
                                                  SCALAR_INPUT, STATE, VEHICLE)
from train_dynamics.physics.kernel.step import available_braking_force
from train_dynamics.physics.kernel.track import profile_mean
from train_dynamics.quoting import quote


class TrainInputs:
    """The setters of the train's inputs (mixed into :class:`~.train.TrainSimulator`)."""

    def set_model(self, model_type: str, scale_factor: float) -> None:
        """Switch the coupler friction law live (state untouched)."""
        if model_type not in couplers.MODEL_CODES:
            raise ValueError(f'model_type must be sign or tanh, got {quote(model_type)}')
        u = float(scale_factor)
        if not np.isfinite(u) or u <= 0.0:
            raise ValueError(f'scale_factor must be > 0, got {quote(scale_factor)}')
        self._sync()      # the chain reaches the present tick under the old law
        self.model_type = model_type
        self.model = couplers.MODEL_CODES[model_type]
        self.u = u
        self.sc[PARAM.U] = u
        self.iv[OPTION.MODEL] = self.model
        self.iv[CACHE.WS_VALID] = 0      # the couplers' Jacobian in ws depends on the model

    # -- inputs (gauge Pa) ------------------------------------------------------------------
    @staticmethod
    def _finite(p, what):
        arr = np.asarray(p, dtype=float)
        if not np.all(np.isfinite(arr)):
            raise ValueError(f'{what}: pressure must be finite, got {quote(p)}')
        return arr

    def set_head_pipe_pressure(self, p: float) -> None:
        """Set the head-end brake-pipe pressure, gauge [Pa] (``pipe_head``)."""
        self.sc[SCALAR_INPUT.HEAD] = float(self._finite(p, 'head pipe'))
        if self.pneu is not None:
            self.pneu.set_command(self.sc[SCALAR_INPUT.HEAD])

    def set_pipe_pressure(self, p, index: int | None = None) -> None:
        """Set the local brake-pipe pressure(s), gauge [Pa] (``pipe_per_coach``); 0-based."""
        arr = self._finite(p, 'pipe')
        if index is None:
            self.coach[INPUT.PIPE] = arr
        else:
            self.coach[INPUT.PIPE, index] = float(arr)
        if self.pneu is not None:
            self.pneu.set_pipe_pressure(arr, index)

    def set_cylinder_pressure(self, p, index: int | None = None) -> None:
        """Set the brake-cylinder pressure(s), gauge [Pa] (``cylinder_per_coach``); 0-based."""
        arr = self._finite(p, 'cylinder')
        ratio = self.pmax_ratio if index is None else self.pmax_ratio[index]
        if np.any(ratio != 1.0):       # a vehicle's own p_max: the kernel works in the train's
            arr = arr / ratio
        if index is None:
            self.coach[INPUT.CYL] = arr
        else:
            self.coach[INPUT.CYL, index] = float(arr)
        if self.pneu is None and self.mode == brakes.CYLINDER_PER_COACH:
            self._cylinders_set = True       # held from now: _hold_cylinders, next step

    def _hold_cylinders(self) -> None:
        """
        Make the cylinder inputs act from now: a step on the braking force (zero-order hold).

        The step's braking force is the mean of the available force (eq. 13, or the friction
        material's, ``step.available_braking_force``) at its two ends; an input that steps
        here sets the start value too, so a staircase input gives a staircase force (not a
        ramp over the next step). Error control: the chain is brought to the present tick
        first and the tick's force row restarts at the new value. Done once for all the inputs
        set at an instant, before the next step (the chain has not moved since they were set).
        """
        self._cylinders_set = False
        self._sync()
        c = self.coach
        if self.wheelsets:
            # the slide protection's valves sit between the input and the cylinder: one they
            # hold, vent or refill (STATE.WSP_CUT) keeps its pressure, the next step's valve
            # acts on it (kernel/wheelset.py, wsp_valves)
            c[STATE.PCYL] = np.where(c[STATE.WSP_CUT] != 0.0, c[STATE.PCYL], c[INPUT.CYL])
        else:
            c[STATE.PCYL] = c[INPUT.CYL]
        available_braking_force(c, self.sc, c[STATE.FB_AVAIL])
        if self.adaptive and self.iv[CACHE.WS_VALID]:
            self.tick_fb[self.iv[CLOCK.TICK] % self.tick_fb.shape[0]] = c[STATE.FB_AVAIL]

    def set_track_adhesion(self, positions, values) -> None:
        """
        Change the track's adhesion profile live (track_adhesion_positions, track_adhesion).

        Acts from the next step (the vehicles' means are taken each step); raises ValueError
        on a bad profile. A train built without wheelsets keeps none: the new rail limits
        its traction and dynamic braking only.
        """
        ax, av = track_module.adhesion_profile(positions, values)
        self._sync()
        self.track.ax, self.track.av = ax, av
        self.track.ac = track_module._cumulative(ax, av)
        self.aprof = self.track.adhesion_profile
        self.iv[OPTION.ADHESION] = int(ax.size > 0)
        self.coach[OUTPUT.ADH_LOW] = self.track_adhesion_low()

    def track_adhesion_low(self) -> np.ndarray:
        """Return each vehicle's available adhesion at low speed [-], mean over its length."""
        front = self.coach[VEHICLE.FRONT0] + self.coach[STATE.X]
        length = self.coach[VEHICLE.LENGTH]
        out = np.empty(self.n)
        for i in range(self.n):
            lo, hi = front[i] - length[i], front[i]
            out[i] = wheelset.DRY_ADHESION + profile_mean(lo, hi, *self.aprof)
        return out

    def set_wsp_valve(self, state: int, index: int, bogie: int = 0) -> None:
        """
        Set vehicle ``index``'s (0-based) slide-protection valve: 0, 1, 2 (wsp external).

        ``bogie`` 1 or 2: that bogie's valves only (``bogie_wheelsets``); 0: the vehicle's
        (with ``bogie_wheelsets`` both bogies' valves).
        """
        if self.wsp != wheelset.WSP_EXTERNAL:
            raise ValueError('coach_<i>/wsp/valve needs wsp external')
        if state not in (wheelset.NORMAL, wheelset.HOLD, wheelset.VENT):
            raise ValueError(f'wsp valve must be 0 (normal), 1 (hold) or 2 (vent), got '
                             f'{quote(state)}')
        if not 0 <= int(index) < self.n:
            raise ValueError(f'vehicle {int(index) + 1}: the train has {self.n} vehicles')
        if bogie not in ((0, 1, 2) if self.bogies else (0,)):
            raise ValueError(f'bogie {quote(bogie)}: needs bogie_wheelsets and 1 or 2')
        rows = {0: [INPUT.VALVE, INPUT.VALVE_B2], 1: [INPUT.VALVE], 2: [INPUT.VALVE_B2]}
        self.coach[rows[int(bogie)], int(index)] = float(state)

    @property
    def locomotives(self) -> list[int]:
        """
        Return the 0-based indices of the vehicles that take a traction command.

        The locomotives but the remotes (they follow the lead over the radio).
        """
        return self.consist.commanded

    def set_traction_command(self, command: float, index: int) -> None:
        """Set the traction command of locomotive ``index`` (0-based), in [-1, 1]."""
        c = float(command)
        if not (np.isfinite(c) and -1.0 <= c <= 1.0):
            raise ValueError(f'traction command must be in [-1, 1], got {quote(command)}')
        if index in self._remotes:
            raise ValueError(f'vehicle {index + 1} is a remote locomotive: it follows the '
                             'lead over the radio')
        if index not in self.consist.locomotives:
            raise ValueError(f'vehicle {index + 1} is not a locomotive (no traction)')
        self.coach[INPUT.T_CMD, index] = c
        if (self.steps == 0 and self.cfg.initial_state == 'equilibrium'
                and float(self.cfg.initial_speed) != 0.0):
            # a train running at t = 0 runs at this setting: its force is built up, in the
            # balance (a train at rest notches up from 0 through the build-up time)
            self.coach[STATE.T_EFF, index] = c
            self._settle()
        if self.remotes and index == self.lead:
            self.pneu.set_traction(c)

    @property
    def counts_sliding(self) -> bool:
        """Tell whether the run metrics take the sliding: wheelsets, or the limit slid a wheel."""
        return bool(self.wheelsets or np.any(self.coach[OUTPUT.SLIDE_T] > 0.0))

    @property
    def remotes(self) -> list[int]:
        """Return the 0-based indices of the distributed-power (remote) locomotives."""
        return self._remotes

    @property
    def lead(self) -> int | None:
        """Return the 0-based index of the lead locomotive (the first that is no remote)."""
        return next(iter(self.locomotives), None)

    def set_ep_command(self, fraction: float) -> None:
        """Set the EP / ECP train-line command, fraction of full service (``brake_system``)."""
        if self.pneu is None or self.pneu.brake_system == 'pneumatic':
            raise ValueError('brake_ep/command needs brake_model pneumatic and brake_system '
                             'ep or ecp')
        self.pneu.set_ep_command(fraction)

    def set_train_line(self, healthy: bool) -> None:
        """Set the state of the EP / ECP train line (lost: the documented fallback)."""
        if self.pneu is not None:
            self.pneu.set_train_line(healthy)
