"""
The train: N coaches joined by N-1 couplers (paper eqs. 5-9, generalised to N coaches).

Coach i (1 = front) has mass m_i [kg], position x_i [m] (distance travelled since t = 0) and
speed v_i [m/s]. Coupler i joins coaches i and i+1: y_i = x_i - x_{i+1} (eq. 9), force F_i
(eq. 4, F > 0 tension). The equations of motion (5)-(7), for any N:

    m_i a_i = F_{i-1} - F_i - Fb_i,      F_0 = F_N = 0,

so the couplers' forces cancel in the sum and the centre of mass obeys eq. (8) exactly:
(sum m_i) a_cm = -sum Fb_i. In matrix form, with D the (N-1) x N difference matrix
(y = D x), M a = -D^T F(D x, D v) - Fb.

:class:`TrainSimulator` is the one model that ``sim_node`` and the offline command run: the
brake system (``kernel/brakes.py``) and the integrators (``kernel/``) advancing the
coach chain under zero-order-hold brake inputs.
"""
from __future__ import annotations

from collections.abc import Callable
import heapq
import itertools

import numpy as np

from train_dynamics.physics import blending, ed_force, equilibrium, friction, pneumatic
from train_dynamics.physics.config import Consist, SimConfig
from train_dynamics.physics.config.consist import check_friction_below_stiffness
from train_dynamics.physics.config.table import KERNEL_ROWS
from train_dynamics.physics.kernel import brakes, wheelset
from train_dynamics.physics.kernel.drivers import DRIVERS, KernelArrays
from train_dynamics.physics.kernel.layout import (CACHE, CLOCK, COACH, CONTROL, COUNT, COUPLER,
                                                  INPUT, INTEGER, OPTION, OUTPUT, PARAM, SCALAR,
                                                  SCALAR_INPUT, STATE, TABLE_ROWS, VEHICLE,
                                                  WORK)
from train_dynamics.physics.kernel.resistance import running_resistance
from train_dynamics.physics.kernel.step import make_workspace, OK, STATUS_TEXT
from train_dynamics.physics.kernel.traction import traction_force
from train_dynamics.physics.observables import TrainBalances, TrainOutputs
from train_dynamics.physics.resistance import equivalent_mass
from train_dynamics.physics.train_inputs import TrainInputs


class TrainSimulator(TrainInputs, TrainOutputs, TrainBalances):
    """
    Train, brake system and fixed-step integrator (eqs. 5-9, 12-16).

    Inputs are gauge pressures [Pa] held constant until the next ``set_*`` call; a new value
    takes effect at once (zero-order hold). An input due at a simulation time t [s] between
    two steps is handed to :meth:`schedule`: the step that spans t is split there
    (:attr:`exact_inputs`), so a 1 kHz input reaches the model at 1 kHz whatever the step.
    Outputs are numpy arrays (copies). The state lives in the packed arrays of
    :mod:`train_dynamics.physics.kernel.layout` (``coach``, ``cpl``, ``sc``, ``iv``, ``ws``)
    that the method's driver (:mod:`~.kernel.drivers`) advances in place.
    """

    #: per-coupler constants that ``coupler_constants`` may override (arrays of N-1) and
    #: their rows in ``cpl``
    _COUPLER_ROWS = {'buffer_stiffness': COUPLER.KE, 'buffer_friction': COUPLER.KF,
                     'draw_gear_stiffness': COUPLER.KEC, 'draw_gear_friction': COUPLER.KFC}
    COUPLER_CONSTANTS = tuple(_COUPLER_ROWS)
    #: connection constants of the consist with free play and blocking, and their rows
    _TRAVEL_ROWS = {'draw_gear_slack': COUPLER.GT, 'buffer_slack': COUPLER.GC,
                    'draw_gear_stroke': COUPLER.ST, 'buffer_stroke': COUPLER.SC,
                    'blocked_stiffness': COUPLER.KB}
    #: per-vehicle fields of the consist that the kernel reads as is, and their rows in
    #: ``coach``: derived from the ``row`` of their ParamSpec (config.table.KERNEL_ROWS). The
    #: other VEHICLE rows are transforms of fields, written in ``_set_constants``: MASS
    #: (mass, rotating_mass_factor), BMASS (mass, adhesion_coefficient), WEIGHT (mass),
    #: FRONT0 (length, initial_position), DELAY (length, brake_propagation_speed), BRAKE_GAIN
    #: and BRAKE_OFF (the friction-brake fields, physics/friction.force_rows).
    _VEHICLE_ROWS = {field: getattr(VEHICLE, row) for field, row in KERNEL_ROWS.items()}

    def __init__(self, cfg: SimConfig, coupler_constants: dict | None = None):
        """
        Build the train of ``cfg`` at t = 0.

        ``coupler_constants``: optional arrays of N-1 values per name of
        :attr:`COUPLER_CONSTANTS` [N/m], for a train that mixes vehicles (coupler i joins
        coaches i and i+1); the scalar parameters of ``cfg`` fill the rest.
        """
        self.cfg = cfg
        self.consist = consist = cfg.consist
        self.n = n = consist.n
        self.h = float(cfg.integration_step)
        self.masses = np.array(consist['mass'], dtype=float)
        #: mass for inertia [kg], m (1 + rotating_mass_factor)
        self.inertia = equivalent_mass(self.masses, consist['rotating_mass_factor'])
        self._build_couplers(consist, coupler_constants)
        self._build_brakes(cfg, consist)
        #: the line: gradient and curve profiles (track.py) as kernel arrays
        self.track = cfg.track
        self.gprof = np.array([self.track.gx, self.track.gv, self.track.gc], dtype=float)
        self.cprof = np.array([self.track.cx, self.track.cv, self.track.cc], dtype=float)
        self.aprof = self.track.adhesion_profile
        #: rotating wheelsets with the creep law (kernel/wheelset.py), and the WSP mode
        self.wheelsets = cfg.has_wheelsets
        self.wsp = wheelset.WSP_MODES.index(cfg.wsp)
        #: two wheelsets per vehicle, one per bogie (kernel/bogie.py)
        self.bogies = bool(cfg.bogie_wheelsets)
        self.ws = make_workspace(n)
        self.model_type = cfg.model_type
        self.u = float(cfg.scale_factor)
        #: error-controlled chain (integrator adaptive): the brake system keeps the
        #: fixed tick h, the chain lands on every output instant (``land`` ticks)
        method, self.tolerance, _ = cfg.integration
        self.adaptive = method == 'adaptive'
        #: the method's driver: driver(n_steps, sync, KernelArrays) -> (steps, status)
        self.driver = DRIVERS[method]
        self.land = _landing_ticks(float(cfg.publish_rate), self.h)
        self.tick_fb = np.zeros((self.land + 1, n))
        self.tick_te = np.zeros((self.land + 1, n))
        self.coach = np.zeros((len(COACH), n))
        self.sc = np.zeros(len(SCALAR))
        self.iv = np.zeros(len(INTEGER), dtype=np.int64)
        self._set_constants()
        self.reset()
        self.set_model(self.model_type, self.u)
        #: inputs are applied at their own instants, splitting a step (cylinder_per_coach,
        #: pipe_per_coach); the pipe-head delay line and the pneumatic brake run on the
        #: tick h: there an input at t acts from the first step k with k h >= t
        self.exact_inputs = self.pneu is None and self.mode != brakes.PIPE_HEAD
        #: blending builtin: the brake control unit (physics/blending.py), external: the ED
        #: force commands (physics/ed_force.py); None: not that mode
        self.bcu = blending.BrakeControlUnit(self) if cfg.blending == 'builtin' else None
        self.ed_force = ed_force.EdForceCommands(self) if cfg.blending == 'external' else None

    def _build_couplers(self, consist: Consist, coupler_constants: dict | None) -> None:
        """Fill ``cpl``: each connection's constants (eqs. 2-3, free play, strokes, K_b)."""
        n = self.n
        self.cpl = np.empty((len(COUPLER), n - 1))
        for name, row in self._TRAVEL_ROWS.items():
            self.cpl[row] = consist.coupler(name)
        self.cpl[TABLE_ROWS] = consist.tables      # preloaded or progressive ends
        extra = dict(coupler_constants or {})
        for name, row in self._COUPLER_ROWS.items():
            value = extra.pop(name, consist.coupler(name))
            arr = np.broadcast_to(np.asarray(value, dtype=float), (n - 1,))
            if not np.all(np.isfinite(arr)) or np.any(arr < 0.0):
                raise ValueError(f'{name}: need {n - 1} finite values >= 0')
            self.cpl[row] = arr
        if extra:
            raise ValueError(f'unknown coupler constants: {", ".join(sorted(extra))}')
        cpl = self.cpl
        if coupler_constants:     # the consist's connections hold it (its vehicles' do)
            check_friction_below_stiffness({n: cpl[row] for n, row in self._COUPLER_ROWS.items()},
                                           'coupler_constants: ')
        self.ke, self.kf, self.kec, self.kfc = (cpl[COUPLER.KE], cpl[COUPLER.KF],
                                                cpl[COUPLER.KEC], cpl[COUPLER.KFC])

    def _build_brakes(self, cfg: SimConfig, consist: Consist) -> None:
        """Set up the brake system (eq. 13): mode, cylinder tables, pipe delays, pneumatics."""
        n = self.n
        self.mode = brakes.MODE_CODES[cfg.brake_input]
        self.fill, self.rel, self.table_set = _cylinder_tables(cfg, consist)
        if cfg.consist_file:     # the pipe runs along the vehicles' lengths
            ahead = np.concatenate(([0.0], np.cumsum(consist['length'][:-1])))
            self.delays = ahead / float(cfg.brake_propagation_speed)
        else:
            self.delays = brakes.pipe_delays(n, cfg.coach_length, cfg.brake_propagation_speed)
        #: p_max of each vehicle over the train's (eq. 13 works with p / p_max)
        self.pmax_ratio = consist['max_cylinder_pressure'] / float(cfg.max_cylinder_pressure)
        # brake_model pneumatic: the pneumatic brake hands its cylinder pressures to the
        # chain step by step (the chain then runs as in cylinder_per_coach); the bypass
        # cylinder_per_coach keeps the input cylinders
        self.pneu = None
        self._remotes: list[int] = []
        if cfg.brake_model == 'pneumatic' and self.mode != brakes.CYLINDER_PER_COACH:
            per_vehicle = {'accelerators': consist['emergency_accelerator'] > 0.5,
                           'remotes': consist['remote'] > 0.5}
            per_vehicle.update(_cylinder_fields(consist))
            if cfg.consist_file:     # the consist's lengths, cylinder pressures and regimes
                per_vehicle.update({'lengths': np.array(consist['length']),
                                    'p_max': np.array(consist['max_cylinder_pressure']),
                                    'regimes': list(consist.regimes)})
            self.pneu = pneumatic.from_config(cfg, self.h,
                                              external_pipe=self.mode == brakes.PIPE_PER_COACH,
                                              **per_vehicle)
            self._trace = np.zeros((0, n))
            self._traction_trace = np.zeros(0)
            self._remotes = [int(i) for i in np.flatnonzero(per_vehicle['remotes'])]

    # -- constants and state -----------------------------------------------------------------
    def _set_constants(self) -> None:
        """Fill the constant groups of the packed arrays: VEHICLE, PARAM, OPTION (layout.py)."""
        cfg = self.cfg
        c = self.coach
        consist = self.consist
        mu = float(cfg.adhesion_coefficient)
        own = consist['adhesion_coefficient']
        c[VEHICLE.MASS] = self.inertia
        c[VEHICLE.BMASS] = np.where(own == mu, self.masses, self.masses * own / mu)
        c[VEHICLE.WEIGHT] = self.masses * float(cfg.gravity)
        c[[VEHICLE.BRAKE_GAIN, VEHICLE.BRAKE_OFF]] = friction.force_rows(
            consist, self.inertia, self.fill, float(cfg.gravity))
        laws = friction.law_rows(consist)
        c[VEHICLE.LAW0:VEHICLE.LAW0 + laws.shape[0]] = laws
        for name, row in self._VEHICLE_ROWS.items():
            c[row] = consist[name]
        c[VEHICLE.FRONT0] = self.track.fronts(consist['length'])
        c[VEHICLE.DELAY] = self.delays / self.h
        c[VEHICLE.WHEEL_MASS] = consist['wheelset_inertia'] / consist['wheel_radius'] ** 2
        c[VEHICLE.TABLE] = self.table_set
        sc, iv = self.sc, self.iv
        sc[[PARAM.H, PARAM.PMAX, PARAM.MU, PARAM.G, PARAM.PNOM, PARAM.PFS, PARAM.SENS,
            PARAM.YLIM, PARAM.TOL, PARAM.FFLOOR]] = [
            self.h, cfg.max_cylinder_pressure, cfg.adhesion_coefficient, cfg.gravity,
            cfg.pipe_nominal_pressure, cfg.full_service_pressure, cfg.distributor_sensitivity,
            cfg.max_coupler_displacement, self.tolerance,
            1e-3 * float(np.max(self.masses)) * float(cfg.gravity)]
        sc[PARAM.FRICTION] = float(np.any(c[VEHICLE.MATERIAL] != friction.PAPER))
        sc[PARAM.MRTOL] = cfg.integration.multirate_tolerance
        sc[PARAM.MRVW] = float(cfg.multirate_reversal_weight)
        # braking force <= mu(v) m g; with wheelsets the creep law carries the limit
        sc[PARAM.ADHLIM] = float(bool(cfg.adhesion_limit) and not self.wheelsets)
        # the pneumatic brake hands the chain its cylinder pressures (cylinder_per_coach)
        iv[OPTION.MODE] = brakes.CYLINDER_PER_COACH if self.pneu is not None else self.mode
        iv[OPTION.EXT] = int(cfg.external_forces)
        iv[OPTION.TRACK] = int(not self.track.flat_and_straight)
        iv[OPTION.LAND] = self.land
        iv[OPTION.BUDGET] = int(cfg.integration_max_steps)
        iv[OPTION.WHEELS] = int(self.wheelsets)
        iv[OPTION.WSP] = self.wsp
        # two wheelsets per vehicle, one per bogie (kernel/bogie.py)
        sc[PARAM.BOGIES] = float(self.bogies)
        sc[PARAM.CONDITION] = float(cfg.rail_conditioning)
        iv[OPTION.ADHESION] = int(self.aprof.shape[1] > 0)

    def reset(self) -> None:
        """
        Go back to t = 0: coaches at ``initial_speed``, brakes released, couplers unstressed.

        ``initial_state: equilibrium``: the couplers then take their quasi-static deflections
        (:meth:`_settle`).
        """
        cfg = self.cfg
        p_nom = float(cfg.pipe_nominal_pressure)
        self.steps = 0
        #: inputs waiting for their instant: heap of (t [s], order, apply)
        self._pending: list = []
        self._order = itertools.count()
        #: [s] time past ``steps`` h reached inside a split step (0 between steps)
        self._within = 0.0
        #: cylinder inputs were set since the last step (:meth:`_hold_cylinders` due)
        self._cylinders_set = False
        c = self.coach
        c[len(VEHICLE):] = 0.0          # state, inputs, outputs; the constants stay
        c[STATE.V] = float(cfg.initial_speed)
        c[STATE.PPIPE] = p_nom
        c[INPUT.PIPE] = p_nom
        c[STATE.HELD] = (c[STATE.V] == 0.0)
        c[STATE.WHEEL] = abs(float(cfg.initial_speed))      # rolling
        c[STATE.WHEEL_B2] = c[STATE.WHEEL]
        c[OUTPUT.ADH_LOW] = wheelset.DRY_ADHESION
        if self.iv[OPTION.ADHESION]:
            c[OUTPUT.ADH_LOW] = self.track_adhesion_low()
        self.ring = np.full(int(np.floor(c[VEHICLE.DELAY, -1])) + 2, p_nom)
        sc = self.sc
        sc[len(PARAM):] = 0.0           # work integrals, inputs, controller
        sc[SCALAR_INPUT.HEAD] = p_nom
        sc[CONTROL.HPROP] = self.h
        sc[CONTROL.HEVAL] = -1.0
        sc[CONTROL.ERRPREV] = 1.0
        sc[CONTROL.HMIN] = np.inf
        sc[CONTROL.INT_HMIN] = np.inf
        self.iv[len(OPTION):] = 0       # clocks, counters; CACHE.WS_VALID = 0
        self.ws[[WORK.FHI, WORK.FLO, WORK.NSUB]] = 0.0  # the force envelope starts again
        if self.pneu is not None:
            self.pneu.reset()
            c[INPUT.CYL] = self.pneu.cylinder_pressure
        self.fault: str | None = None
        bcu = getattr(self, 'bcu', None)
        if bcu is not None:         # the track brakes off before the couplers settle
            bcu.track.restore()
        self._settle()
        for part in filter(None, (bcu, getattr(self, 'ed_force', None))):
            part.reset()

    def _settle(self) -> None:
        """
        At t = 0 with ``initial_state: equilibrium``: put the couplers at their static deflections.

        The vehicles' forces at t = 0 (gradient, curve and running resistance at
        ``initial_speed``, traction at its command, brakes released) in the chain of
        :mod:`~train_dynamics.physics.equilibrium`; STATE.X takes the deflections (x_1 = 0).
        Nothing changes when every coupler force is 0 (a level train without resistance and
        traction: the paper's start).
        """
        if self.cfg.initial_state != 'equilibrium' or self.steps != 0:
            return
        c = self.coach
        n = self.n
        v0 = float(self.cfg.initial_speed)
        grade, curve = self.track.forces(np.zeros(n), c[VEHICLE.LENGTH], self.masses,
                                         float(self.cfg.gravity))
        external = grade.copy()
        if v0 != 0.0:
            res = running_resistance(np.full(n, v0), c[VEHICLE.DAVIS_A], c[VEHICLE.DAVIS_B],
                                     c[VEHICLE.DAVIS_C], np.empty(n))
            external -= np.sign(v0) * (res + curve)
        for i in self.consist.locomotives:
            if c[STATE.T_EFF, i] != 0.0:
                external[i] += traction_force(
                    c[STATE.T_EFF, i], v0, c[VEHICLE.T_FORCE, i], c[VEHICLE.T_POWER, i],
                    c[VEHICLE.DB_FORCE, i], c[VEHICLE.DB_POWER, i], c[VEHICLE.DB_FADE, i],
                    c[VEHICLE.T_ADH, i], c[VEHICLE.WEIGHT, i])
        force = equilibrium.chain_forces(external, self.inertia)
        if not np.any(force):
            c[STATE.X] = 0.0
            return
        cpl = self.cpl
        y = equilibrium.static_deflection(force, cpl[COUPLER.KE], cpl[COUPLER.KEC],
                                          cpl[COUPLER.GT], cpl[COUPLER.GC], cpl[COUPLER.ST],
                                          cpl[COUPLER.SC], cpl[COUPLER.KB], cpl[TABLE_ROWS])
        c[STATE.X] = equilibrium.positions(y)
        self.ws[WORK.XKEY] = np.nan      # the static resistance at the new positions
        self.iv[CACHE.WS_VALID] = 0

    # -- integration -------------------------------------------------------------------------
    @property
    def t(self) -> float:
        """Return the simulation time [s]."""
        return self.steps * self.h + self._within

    def schedule(self, t: float, apply: Callable[[], None]) -> None:
        """
        Apply an input at simulation time ``t`` [s]: call ``apply()`` when the run reaches t.

        ``apply`` sets inputs (``set_*``). With :attr:`exact_inputs` the step that spans t is
        split at t (:meth:`advance`); else the input acts from the first step k with
        k h >= t. An instant already reached (within 1e-6 h) applies now. Inputs due at the
        same instant apply in the order they were scheduled.
        """
        t = float(t)
        if not np.isfinite(t):
            raise ValueError(f'input time must be finite, got {t!r}')
        if t <= self.t + _INSTANT * self.h:
            apply()
            return
        heapq.heappush(self._pending, (t, next(self._order), apply))

    def missed(self, t: float) -> bool:
        """
        Return True if an input due at ``t`` [s] handed to :meth:`schedule` now acts late.

        With :attr:`exact_inputs`: t lies in the past (by more than 1e-6 h); else its step,
        the first k with k h >= t, is already done (an input handed over in time would have
        acted there).
        """
        if self.exact_inputs:
            return float(t) < self.t - _INSTANT * self.h
        return self._due_tick(float(t)) < self.steps

    def _due_tick(self, t: float) -> int:
        """Return the first step k with k h >= t [s] (within 1e-6 h)."""
        return max(0, int(np.ceil(t / self.h - _INSTANT)))

    def _apply_due(self) -> None:
        """Apply the scheduled inputs due now."""
        pending = self._pending
        limit = self.t + _INSTANT * self.h
        while pending and (pending[0][0] <= limit or (
                not self.exact_inputs and self._due_tick(pending[0][0]) <= self.steps)):
            heapq.heappop(pending)[2]()

    def advance(self, n_steps: int) -> int:
        """
        Integrate ``n_steps`` steps of h; return the steps done (fewer after a fault).

        A step that spans scheduled inputs (:meth:`schedule`, :attr:`exact_inputs`) is done
        in pieces ending at their instants; the inputs due at the end are applied.
        """
        if self.fault is not None or n_steps <= 0:
            return 0
        if not self._pending:
            return self._advance_ticks(int(n_steps))
        target = self.steps + int(n_steps)
        start = self.steps
        while self.fault is None and self.steps < target:
            self._apply_due()
            if not self._pending:
                self._advance_ticks(target - self.steps)
                break
            t_next = self._pending[0][0]
            if self.exact_inputs:
                k = int(np.floor(t_next / self.h + _INSTANT))   # the step that spans it
            else:
                k = self._due_tick(t_next)
            if k > self.steps:
                self._advance_ticks(min(k, target) - self.steps)
            else:
                self._split_step()
        if self.fault is None:
            self._apply_due()
        return self.steps - start

    def _split_step(self) -> None:
        """
        Do the next step of h in pieces that end at the scheduled inputs inside it.

        Each piece is one step of the driver with its length in PARAM.H: fixed step, one
        ROS2 step (the couplers' stage rows evaluated again for it); error control, one
        brake-system tick of the piece's length and the chain under error control to its
        end. The tick counters then count the whole step once.
        """
        self._sync()
        if self.fault is not None:
            return
        h = self.h
        t_end = (self.steps + 1) * h
        eps = _INSTANT * h
        pending = self._pending
        tick0 = int(self.iv[CLOCK.TICK])
        while True:
            t_piece = pending[0][0] if pending and pending[0][0] < t_end - eps else t_end
            dt = t_piece - self.t
            if dt > eps:
                status = self._piece(dt, tick0)
                if status != OK:
                    self.fault = STATUS_TEXT[status].format(t=self.t)
                    return
                self._within += dt
            if t_piece >= t_end:
                break
            while pending and pending[0][0] <= self.t + eps:
                heapq.heappop(pending)[2]()
        self._within = 0.0
        self.steps += 1
        if self.adaptive:
            self.iv[CLOCK.TICK] = self.iv[CLOCK.CHAIN_TICK] = tick0 + 1
            self.iv[CACHE.WS_VALID] = 0     # the tick ring restarts from the state here

    def _piece(self, dt: float, tick0: int) -> int:
        """Run one driver step of length ``dt`` [s] (< h) from tick ``tick0``; the status."""
        if self._cylinders_set:
            self._hold_cylinders()
        sc, iv = self.sc, self.iv
        sc[PARAM.H] = dt
        iv[CACHE.WS_VALID] = 0           # the couplers' rows (and tick ring) for this length
        if self.adaptive:
            iv[CLOCK.TICK] = iv[CLOCK.CHAIN_TICK] = tick0
        try:
            _, status = self._kernel(1, True)
        finally:
            sc[PARAM.H] = self.h
            iv[CACHE.WS_VALID] = 0
        return status

    def _advance_ticks(self, n_steps: int) -> int:
        """Integrate ``n_steps`` whole steps of h; return the steps done."""
        if n_steps <= 0:
            return 0
        if self._cylinders_set:
            self._hold_cylinders()
        if self.pneu is not None:
            return self._advance_pneumatic(int(n_steps))
        done, status = self._kernel(int(n_steps))
        self.steps += done
        if status != OK:
            self.fault = STATUS_TEXT[status].format(t=self.t)
        return done

    def _advance_pneumatic(self, n_steps: int) -> int:
        """Advance the pneumatic brake n_steps ahead, then the chain under its cylinders."""
        if self._trace.shape[0] < n_steps:
            self._trace = np.zeros((n_steps, self.n))
        trace = self._trace[:n_steps]
        remotes = self.remotes
        if remotes:            # the remotes' traction as the radio delivers it, step by step
            if self._traction_trace.shape[0] < n_steps:
                self._traction_trace = np.zeros(n_steps)
            traction = self._traction_trace[:n_steps]
            self.pneu.advance(n_steps, trace, traction)
        else:
            self.pneu.advance(n_steps, trace)
        cyl_in = self.coach[INPUT.CYL]
        done = 0
        status = OK
        scaled = bool(np.any(self.pmax_ratio != 1.0))   # vehicles' own p_max -> the train's
        for k in range(n_steps):
            if remotes:
                self.coach[INPUT.T_CMD, remotes] = traction[k]
            cyl_in[:] = trace[k] / self.pmax_ratio if scaled else trace[k]
            step, status = self._kernel(1)
            done += step
            if status != OK:
                break
        self.coach[STATE.PPIPE] = self.pneu.pipe_pressure
        self.steps += done
        if status != OK:
            self.fault = STATUS_TEXT[status].format(t=self.t)
        return done

    def _kernel(self, n_steps: int, sync: bool = False) -> tuple[int, int]:
        """Run the method's driver over the packed arrays; return (steps, status)."""
        return self.driver(n_steps, sync, KernelArrays(
            self.coach, self.cpl, self.sc, self.iv, self.fill, self.rel, self.ring, self.ws,
            self.gprof, self.cprof, self.aprof, self.tick_fb, self.tick_te))

    def _sync(self) -> None:
        """Bring the error-controlled chain to the present tick (it lands on outputs)."""
        if (not self.adaptive or self.fault is not None
                or self.iv[CLOCK.CHAIN_TICK] >= self.iv[CLOCK.TICK]):
            return
        _, status = self._kernel(0, True)
        if status != OK:
            self.fault = STATUS_TEXT[status].format(t=self.t)

    @property
    def integration_stats(self) -> dict:
        """
        Return the integration counters: error control (zeros at fixed step), holding.

        steps, rejected: chain steps since reset; h_min [s]: smallest step (not counting
        the steps shortened to land on an output); steps_last_period, h_min_last_period:
        of the last output period; steps_max_period; fallback_periods: periods that ran out
        of ``integration_max_steps`` and finished at the fixed step. Standstill (both
        stepping modes): hold_solves, the chain solves beyond the first of each step (the
        holding LCP's new sets, coaches stopping); hold_capped, steps that reached the
        iteration cap with the set still inconsistent (the step finishes all the same);
        block_solves, the chain solves redone with a blocked coupler's stiffness in the
        stage matrix (stiff blocking, both modes).
        Multirate (``multirate_tolerance`` > 0): mr_groups, the vehicle groups re-integrated
        in sub-steps, mr_substeps their sub-steps, mr_declined the groups left at the long
        step (a vehicle held or stopping); per coupler: :attr:`substeps_per_coupler`.
        """
        sc, iv = self.sc, self.iv
        return {'adaptive': self.adaptive, 'steps': int(iv[COUNT.NSTEPS]),
                'rejected': int(iv[COUNT.NREJ]), 'h_min': float(sc[CONTROL.HMIN]),
                'steps_last_period': int(iv[COUNT.INT_STEPS]),
                'h_min_last_period': float(sc[CONTROL.INT_HMIN]),
                'steps_max_period': int(iv[COUNT.INT_STEPS_MAX]),
                'fallback_periods': int(iv[COUNT.NFALLBACK]),
                'hold_solves': int(iv[COUNT.HOLD_SOLVES]),
                'hold_capped': int(iv[COUNT.HOLD_CAPPED]),
                'block_solves': int(iv[COUNT.BLOCK_SOLVES]),
                'mr_groups': int(iv[COUNT.MR_CLUSTERS]),
                'mr_substeps': int(iv[COUNT.MR_SUBSTEPS]),
                'mr_declined': int(iv[COUNT.MR_DECLINED])}

    @property
    def substeps_per_coupler(self) -> np.ndarray:
        """Return the multirate sub-steps each coupler took since reset (int, N-1; 0: none)."""
        return self.ws[WORK.NSUB, :self.n - 1].astype(int)

    def advance_to(self, t: float) -> int:
        """Integrate whole steps until ``self.t >= t - h/2``; return the steps done."""
        target = int(np.floor(t / self.h + 0.5))
        return self.advance(target - self.steps)


#: [steps of h] instants closer than this are the same instant (rounding of t = k h)
_INSTANT = 1e-6


def _landing_ticks(rate: float, h: float) -> int:
    """Return the output period in ticks of h [s] when whole (the chain lands there), else 1."""
    k = int(np.floor(1.0 / (rate * h) + 0.5))
    return k if k >= 1 and abs(k * h * rate - 1.0) < 1e-9 else 1


def _cylinder_fields(consist: Consist) -> dict[str, np.ndarray]:
    """
    Return the pneumatic cylinder keywords of a consist's vehicles (``PneumaticBrake``).

    First stage (``inshot_pressure``), dead volume; the stroke volume brake_cylinders x
    brake_cylinder_area x piston_stroke [m^3] and the return spring's pressure
    brake_spring_force / brake_cylinder_area [Pa] at which the pistons travel out (0 where
    the vehicle has no stroke).
    """
    area = np.asarray(consist['brake_cylinder_area'], dtype=float)
    stroke = np.asarray(consist['piston_stroke'], dtype=float)
    moving = (stroke > 0.0) & (area > 0.0)     # SimConfig refuses a stroke without an area
    safe = np.where(moving, area, 1.0)
    return {'inshot': np.array(consist['inshot_pressure'], dtype=float),
            'dead_volume': np.array(consist['cylinder_dead_volume'], dtype=float),
            'stroke_volume': np.where(moving, consist['brake_cylinders'] * area * stroke, 0.0),
            'spring_pressure': np.where(moving, consist['brake_spring_force'] / safe, 0.0)}


def _cylinder_tables(cfg: SimConfig,
                     consist: Consist) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the filling and release tables of the train's brake regimes, and each vehicle's.

    One table set per regime present (the vehicles', or ``brake_regime``), P before G:
    fill, rel (2 R, L), rows 2 k, 2 k + 1 the times [s] and p/p_max of set k, and the set
    of each vehicle (float, N). A regime's set is the parameters' own table when set (one
    for every vehicle), else the regime's standard one (config/table.py: UIC 540 P, and G
    the same shape six times slower), so a GP or LL train fills each vehicle by its own
    regime (SimConfig.fill_table, release_table).
    """
    regimes = sorted(set(consist.regimes) or {cfg.brake_regime}, reverse=True)   # P, G
    fills = [row for r in regimes for row in cfg.fill_table(r)]
    rels = [row for r in regimes for row in cfg.release_table(r)]
    which = np.array([regimes.index(r) for r in consist.regimes], dtype=float)
    return np.asarray(fills, dtype=float), np.asarray(rels, dtype=float), which
