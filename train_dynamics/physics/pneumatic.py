"""
Pneumatic brake: the brake pipe as 1-D compressible flow, relay valve, UIC distributors.

The ``pneumatic`` brake model. It does not depend on the train's motion, so it
advances on its own fixed step and hands each vehicle's cylinder pressure to the coach chain
(:meth:`PneumaticBrake.advance` fills a per-step trace). All pressures in the interface are
GAUGE [Pa]; inside, absolute pressures and air masses [kg]. Air is an ideal gas at a
constant temperature (isothermal: p V = m R T), a good model for the slow processes and
within the accuracy of the fast ones in a 32 mm pipe.

**Brake pipe** (``_pipe_transport``). The pipe of every vehicle is cut into cells of
about ``cell_length`` [m]; a staggered finite-volume grid keeps the air MASS of each cell
(centres) and the mass FLOW w [kg/s] through each face between two cells. Per cell
dm/dt = w_in - w_out (exactly conservative: the faces' flows telescope, a closed pipe keeps
its mass to round-off). Per face the momentum balance of the 1-D gas equations without the
convective term (pipe Mach number << 1 except at a vent, where the orifice law takes over):

    dw/dt = A (p_left - p_right) / dx - (f / D + K / dx) |w| w / (2 rho A),

f the Darcy friction factor (laminar 64/Re, turbulent Blasius 0.316 Re^-1/4, the larger);
K an extra loss at the faces that are hose couplings (hoses, angle cocks, couplings). Time
integration: symplectic (forward-backward) Euler, the flows first with the old pressures,
friction linearly implicit, then the masses with the new flows. For the acoustic part this
is the staggered leapfrog scheme: non-dissipative and stable for c h / dx <= 1 (c =
sqrt(R T), about 290 m/s: h <= 21 ms for 6 m cells; the step is sub-divided automatically
when h is larger); the implicit friction is unconditionally stable and damps. The closed
end faces and a closed angle cock are faces with w = 0.

**Valves and chokes** (``orifice_flow``): the isentropic nozzle law with the choked limit
(ISO 6358 style, the discharge coefficient folded into the effective area). Every exchange
between two volumes is limited to the mass that equalises them (or reaches a regulated
pressure) within the step, so no exchange can overshoot or chatter, whatever the step.

**Driver's brake valve** (relay valve at the head): regulates the head of the pipe to the
commanded equalising-reservoir pressure ``command`` (the ``brake_pipe/pressure`` input in
this mode): charges from the main reservoir (``main_reservoir_pressure``) through its
charging capacity, vents to atmosphere through its service port, both opened in proportion
to the pressure error (full opening at ``relay_band``); a command below
``emergency_threshold`` opens the emergency vent (the full bore of the pipe).

**UIC distributor** (three-pressure, graduable release; UIC 540, EN 15355) per vehicle:
control reservoir CR (the 5 bar reference), auxiliary reservoir AR, brake cylinder BC.
Released: CR follows the pipe through a fine nozzle (time constant ``cr_time_constant``):
a slow drop (leakage) is followed and ignores, a quick one opens a gap; when
p_CR - p_pipe > ``apply_threshold`` the distributor applies: CR is cut off, a quick-service
bulb draws a little pipe air locally (first stage, speeds up service propagation), and the
relay part regulates BC to p_max * (p_CR - p_pipe) / (p_nominal - p_full_service), at most
p_max: filling from AR through the application choke (P or G), venting through the release
choke (graduated release as the pipe rises); back in release once the gap is below
``release_threshold``. AR charges from the pipe through a check valve and choke.

**Emergency accelerator** (``_accelerator``, where a vehicle has one): a pipe falling fast
and deep (thresholds of :class:`PneumaticSpec`) opens a vent of ``accelerator_area`` to
atmosphere at the vehicle until the local pipe is below ``accelerator_close``. The area is a
guess, 4.9e-4 m^2 (25 mm, the brake valve's emergency vent): the orifice law takes the air
upstream at rest, so a vent as wide as the pipe (8e-4 m^2) emptied its cell faster than the
pipe's column could follow, and the column's inertia drew the pipe below atmospheric behind
it (-15 kPa for some 0.2 s in a 1 km passenger train; docs/brakes.md).

**Brake cylinder** (``cylinder_pressure``): dead volume V0 [m^3] (pistons released), stroke
volume Vs (pistons' area x stroke) and return-spring pressure p_s (spring force / piston
area) per vehicle; isothermal (Boyle): p = m R T / V0 while the pistons rest, p = patm + p_s
while they travel out, p = m R T / (V0 + Vs) at full stroke. Vs = 0 (the default): one fixed
volume. **First stage (inshot)**: below the vehicle's inshot pressure an applied
distributor also fills through ``inshot_area`` (UIC 540 / EN 15355 first stage; 0 = none).
The cylinder's valve (``V_VALVE``) is +1 filling, 0 lapped, -1 venting after each step.

The compiled part (the functions named above, the rows of the packed arrays) is
:mod:`train_dynamics.physics.kernel.pneumatic`; here the specification, the packing and the
brake object the simulator drives.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
import math

import numpy as np

from train_dynamics.physics.kernel import pneumatic as pk


#: [Pa gauge] distributor first stage (inshot), the default of the vehicle field
#: ``inshot_pressure``: UIC 540 / EN 15355 ask a distributor for one; 0.4 bar is the low end
#: of the 0.4-0.7 bar of KE-type distributors (manufacturers' figures, not the standards'
#: text); the application chokes of :class:`PneumaticSpec` are calibrated with it
INSHOT_PRESSURE = 40000.0

#: brake systems: UIC distributors only, EP valves on every vehicle, ECP car control devices
BRAKE_SYSTEMS = ('pneumatic', 'ep', 'ecp')


@dataclass(frozen=True)
class PneumaticSpec:
    """
    Constants of the pneumatic brake; gauge pressures [Pa], areas are effective areas [m^2].

    Defaults: a UIC train, 5 bar pipe of 32 mm bore (EN 15355 allows 25-32 mm), KE-type
    distributors; choke areas calibrated so that a single vehicle meets UIC 540's times
    (P: 95 % in 4 s, release to 0.4 bar in 17 s; G: 24 s and 52 s), the application chokes
    with the distributor's first stage (``inshot_pressure`` 0.4 bar: 4.0 s and 24.0 s from
    the emergency, 95 % of the final pressure; without it the same chokes fill in 4.3 s
    and 26.6 s).
    """

    pipe_diameter: float = 0.032
    cell_length: float = 6.5             # [m] target length of a pipe cell
    hose_loss: float = 1.5               # K per coupling (two hoses, angle cocks, heads)
    temperature: float = 293.15          # [K]
    viscosity: float = 1.81e-5           # [Pa s]
    atmospheric_pressure: float = 101325.0
    nominal_pressure: float = 500000.0
    full_service_pressure: float = 350000.0
    leakage: float = 0.0                 # [Pa/s] drop rate of the lapped pipe at nominal
    angle_cock_closed: int = 0           # coupling k (vehicles k, k+1) closed; 0 = none
    main_reservoir_pressure: float = 900000.0
    charge_area: float = 1.2e-4          # relay valve charging (~ 12 mm bore)
    vent_area: float = 1.2e-4            # relay valve service vent
    emergency_area: float = 4.9e-4       # emergency vent (25 mm bore)
    relay_band: float = 20000.0          # [Pa] error for full relay opening
    emergency_threshold: float = 100000.0   # command below it: emergency vent
    cr_volume: float = 0.009             # [m^3]
    aux_volume: float = 0.100
    cylinder_volume: float = 0.008      # dead volume (piston released), per vehicle
    qs_volume: float = 0.0004            # quick-service bulb
    cr_time_constant: float = 10.0       # [s] CR charging nozzle (released position)
    apply_threshold: float = 10000.0     # [Pa] p_CR - p_pipe that applies
    release_threshold: float = 4000.0    # [Pa] gap below which the distributor releases
    aux_charge_area: float = 3.0e-6      # AR charging choke (~ 2 mm)
    qs_area: float = 2.0e-5
    lap_band: float = 3000.0             # [Pa] relay part of the distributor: lap band
    relay_part_band: float = 50000.0     # [Pa] its error for full opening
    app_area_p: float = 6.12e-6
    rel_area_p: float = 3.0e-6
    app_area_g: float = 9.92e-7
    rel_area_g: float = 9.6e-7
    # emergency accelerator (where a vehicle has one)
    accelerator_rate: float = 100000.0   # [Pa/s] filtered pipe drop rate that opens it
    accelerator_drop: float = 100000.0   # [Pa] ... with the pipe this far below the CR
    accelerator_filter: float = 0.05     # [s] time constant of the rate filter
    accelerator_area: float = 4.9e-4     # vent to atmosphere: 25 mm, a guess (module docstring)
    accelerator_close: float = 30000.0   # [Pa] local pipe below it: closes and re-arms
    # distributor first stage (inshot): fast filling up to inshot_pressure (the default of
    # the vehicle field of the same name, config/table.py); 0 = none
    inshot_pressure: float = INSHOT_PRESSURE
    inshot_area: float = 2.0e-5          # a guess: about three times the P application choke
    # EP valves and ECP car control devices
    ep_valve_delay: float = 0.2          # [s] train-line command to valve action
    ep_application_area: float = 3.0e-5
    ep_release_area: float = 4.0e-5
    ecp_pipe_penalty: float = 300000.0   # [Pa] ECP: pipe below it applies in full
    # distributed power: radio link of the remote locomotives
    radio_delay: float = 0.5             # [s] lead to remote
    radio_loss: float = 0.0              # probability of losing one message
    radio_period: float = 0.5            # [s] the lead repeats its state this often
    radio_timeout: float = 2.0           # [s] no message for this long: link lost
    radio_seed: int = 0

    def replace(self, **changes) -> 'PneumaticSpec':
        """Return a copy with some fields changed."""
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return PneumaticSpec(**values)


class PneumaticBrake:
    """
    The pneumatic brake of a train of N vehicles (module docstring); gauge pressures [Pa].

    ``lengths`` (N,) vehicle lengths [m]; ``p_max`` (N,) maximum cylinder pressures [Pa];
    ``regimes`` (N,) 'P' or 'G'; ``h`` the step [s]. Starts charged: pipe, CR and AR at the
    nominal pressure, cylinders empty, command = nominal.
    """

    def __init__(self, lengths, p_max, regimes, h: float, spec: PneumaticSpec | None = None,
                 external_pipe: bool = False, accelerators=False, remotes=False,
                 brake_system: str = 'pneumatic', inshot=None, dead_volume=None,
                 stroke_volume=0.0, spring_pressure=0.0):
        """
        Build the grid (cells per vehicle from ``spec.cell_length``) and charge it.

        ``accelerators`` (N,) or scalar: vehicles with an emergency accelerator; ``remotes``
        (N,) or scalar: distributed-power locomotives with their own brake valve on the pipe
        (radio link, :meth:`advance`); ``brake_system``: one of :data:`BRAKE_SYSTEMS`.
        Cylinders, (N,) or scalar: ``inshot`` first-stage pressure [Pa gauge] (default
        ``spec.inshot_pressure``), ``dead_volume`` [m^3] (default ``spec.cylinder_volume``),
        ``stroke_volume`` [m^3] (pistons' area x stroke, 0: a fixed volume),
        ``spring_pressure`` [Pa gauge] (return spring / piston area: the piston travels out
        at it, :func:`~train_dynamics.physics.kernel.pneumatic.cylinder_pressure`).
        """
        self.spec = spec = spec or PneumaticSpec()
        lengths = np.asarray(lengths, dtype=float)
        self.n = n = lengths.shape[0]
        self.h = float(h)
        per = np.maximum(1, np.round(lengths / spec.cell_length)).astype(np.int64)
        self.start = np.concatenate([[0], np.cumsum(per)])
        nc = int(self.start[-1])
        area = math.pi * spec.pipe_diameter ** 2 / 4.0
        dx = np.repeat(lengths / per, per)
        self.cells = np.zeros((pk.N_CELL_ROWS, nc))
        self.cells[pk.C_VOL] = area * dx
        self.faces = np.zeros((pk.N_FACE_ROWS, nc + 1))
        self.faces[pk.F_OPEN, 1:nc] = 1.0
        self.faces[pk.F_LEN, 1:nc] = 0.5 * (dx[:-1] + dx[1:])
        self.faces[pk.F_LEN, 0] = dx[0]
        self.faces[pk.F_LEN, nc] = dx[-1]
        self.faces[pk.F_K, self.start[1:n]] = spec.hose_loss
        if spec.angle_cock_closed:
            k = int(spec.angle_cock_closed)
            if not 1 <= k <= n - 1:
                raise ValueError(f'angle_cock_closed must be 0 or a coupling 1..{n - 1}')
            self.faces[pk.F_OPEN, self.start[k]] = 0.0
        self.cells[pk.C_LEAK] = spec.leakage / (spec.nominal_pressure)
        self.rt = rt = pk.R_AIR * spec.temperature
        # sub-steps for the pipe's CFL condition c h / dx <= 0.8
        self.substeps = max(1, int(math.ceil(math.sqrt(rt) * self.h / (0.8 * dx.min()))))
        veh = self.veh = np.zeros((pk.N_VEH_ROWS, n))
        veh[pk.V_VCR] = spec.cr_volume
        veh[pk.V_VAUX] = spec.aux_volume
        veh[pk.V_VCYL] = spec.cylinder_volume if dead_volume is None else dead_volume
        veh[pk.V_VSTROKE] = stroke_volume
        veh[pk.V_PSPRING] = spring_pressure
        if np.any(veh[pk.V_VCYL] <= 0.0) or np.any(veh[pk.V_VSTROKE] < 0.0) \
                or np.any(veh[pk.V_PSPRING] < 0.0):
            raise ValueError('cylinder dead volume must be > 0, stroke volume and spring '
                             'pressure >= 0')
        veh[pk.V_VQS] = spec.qs_volume
        veh[pk.V_PMAX] = np.broadcast_to(np.asarray(p_max, dtype=float), (n,))
        regimes = [str(r).upper() for r in np.broadcast_to(np.asarray(regimes), (n,))]
        if any(r not in ('P', 'G') for r in regimes):
            raise ValueError(f'brake regimes must be P or G, got {sorted(set(regimes))}')
        goods = np.array([r == 'G' for r in regimes])
        veh[pk.V_AAPP] = np.where(goods, spec.app_area_g, spec.app_area_p)
        veh[pk.V_AREL] = np.where(goods, spec.rel_area_g, spec.rel_area_p)
        veh[pk.V_CELL] = self.start[:-1] + per // 2
        veh[pk.V_ACC] = np.broadcast_to(np.asarray(accelerators, dtype=bool), (n,))
        veh[pk.V_REMOTE] = np.broadcast_to(np.asarray(remotes, dtype=bool), (n,))
        veh[pk.V_INSHOT] = spec.inshot_pressure if inshot is None else inshot
        if brake_system not in BRAKE_SYSTEMS:
            raise ValueError(f'brake_system must be one of {BRAKE_SYSTEMS}, got {brake_system!r}')
        self.brake_system = brake_system
        sc = self.sc = np.zeros(pk.N_SCALARS)
        sc[[pk.S_H, pk.S_RT, pk.S_AREA, pk.S_DIAM, pk.S_MU, pk.S_PATM, pk.S_PMR, pk.S_ACHG,
            pk.S_AVENT, pk.S_AEM, pk.S_BAND, pk.S_EMTH, pk.S_GCR, pk.S_APPTH, pk.S_RELTH,
            pk.S_SPAN, pk.S_AAUX, pk.S_AQS, pk.S_LAP, pk.S_DBAND]] = [
            self.h, rt, area, spec.pipe_diameter, spec.viscosity, spec.atmospheric_pressure,
            spec.main_reservoir_pressure, spec.charge_area, spec.vent_area,
            spec.emergency_area, spec.relay_band, spec.emergency_threshold,
            1.0 / spec.cr_time_constant, spec.apply_threshold, spec.release_threshold,
            spec.nominal_pressure - spec.full_service_pressure, spec.aux_charge_area,
            spec.qs_area, spec.lap_band, spec.relay_part_band]
        sc[[pk.S_ACCRATE, pk.S_ACCAREA, pk.S_ACCCLOSE, pk.S_ACCTAU, pk.S_EPAPP, pk.S_EPREL,
            pk.S_ECPPIPE, pk.S_AINSHOT, pk.S_ACCDROP]] = [
            spec.accelerator_rate, spec.accelerator_area, spec.accelerator_close,
            spec.accelerator_filter, spec.ep_application_area, spec.ep_release_area,
            spec.ecp_pipe_penalty, spec.inshot_area, spec.accelerator_drop]
        self.iv = np.array([self.substeps, int(external_pipe), 0,
                            BRAKE_SYSTEMS.index(brake_system), 1], dtype=np.int64)
        self._empty = np.zeros((0, n))
        self.reset()

    def reset(self) -> None:
        """Charged train at rest: pipe, CR, AR at nominal, cylinders and bulbs at 0 gauge."""
        spec = self.spec
        patm = spec.atmospheric_pressure
        p0 = spec.nominal_pressure + patm
        self.cells[pk.C_M] = p0 * self.cells[pk.C_VOL] / self.rt
        self.faces[pk.F_W] = 0.0
        veh = self.veh
        veh[pk.V_MCR] = p0 * veh[pk.V_VCR] / self.rt
        veh[pk.V_MAUX] = p0 * veh[pk.V_VAUX] / self.rt
        veh[pk.V_MCYL] = patm * veh[pk.V_VCYL] / self.rt
        veh[pk.V_MQS] = patm * veh[pk.V_VQS] / self.rt
        veh[pk.V_APPLIED] = 0.0
        veh[pk.V_PEXT] = spec.nominal_pressure
        veh[pk.V_ACCOPEN] = 0.0
        veh[pk.V_RATE] = 0.0
        veh[pk.V_PPREV] = p0
        veh[pk.V_RCMD] = spec.nominal_pressure
        veh[pk.V_RLAP] = 0.0
        veh[pk.V_VALVE] = pk.VALVE_LAP
        self.sc[pk.S_CMD] = spec.nominal_pressure
        self.sc[pk.S_EPCMD] = 0.0
        self.iv[pk.I_LAP] = 0
        self.iv[pk.I_LINE] = 1
        self.steps = 0
        #: the head's command [Pa gauge] and lap state, the EP/ECP command at the head
        self._command = spec.nominal_pressure
        self._lap = False
        self.ep_command = 0.0
        #: pending actions: (instant [s], order, action) in time order
        self._events = []
        self._order = 0
        # distributed power: the lead's traction command, what the remotes last received
        self.lead_traction = 0.0
        self.remote_traction = 0.0
        self.radio_sent = 0
        self.radio_lost = 0
        self.radio_received = 0
        self.radio_last = 0.0
        self.radio_ok = True
        self._rng = np.random.default_rng(spec.radio_seed)
        if self.has_remotes:
            self._schedule(spec.radio_period, self._radio_tick)

    # -- inputs -----------------------------------------------------------------------------
    def set_command(self, p: float) -> None:
        """Pressure [Pa gauge] the driver's brake valve regulates the pipe head to."""
        changed = float(p) != self._command or self._lap
        self._command = float(p)
        self._lap = False
        self.iv[pk.I_LAP] = 0
        self._head_command()
        if changed:        # the radio carries changes (and the periodic repeats)
            self._radio_send()

    def set_lap(self, lap: bool = True) -> None:
        """Lap position: the driver's brake valve neither charges nor vents the pipe."""
        changed = bool(lap) != self._lap
        self._lap = bool(lap)
        self.iv[pk.I_LAP] = int(bool(lap))
        if changed:
            self._radio_send()

    def set_ep_command(self, fraction: float) -> None:
        """
        Set the EP / ECP command on the train line.

        A fraction of full service (0 release, 1 full), acting at every vehicle
        ``spec.ep_valve_delay`` seconds later.
        """
        fraction = float(fraction)
        if not (math.isfinite(fraction) and 0.0 <= fraction <= 1.0):
            raise ValueError(f'EP command must be a fraction in [0, 1], got {fraction!r}')
        self.ep_command = fraction
        self._head_command()
        self._schedule(self.t + self.spec.ep_valve_delay,
                       lambda: self.sc.__setitem__(pk.S_EPCMD, fraction))

    def set_train_line(self, healthy: bool) -> None:
        """
        Set the state of the EP / ECP train line.

        Lost: EP vehicles brake pneumatically (the head's
        brake valve then also regulates the pipe to the EP command's service pressure); ECP
        cars make a penalty (full) application.
        """
        self.iv[pk.I_LINE] = int(bool(healthy))
        self._head_command()

    def set_traction(self, command: float) -> None:
        """Set the lead locomotive's traction command, sent to the remotes over the radio."""
        changed = float(command) != self.lead_traction
        self.lead_traction = float(command)
        if changed:
            self._radio_send()

    def _head_command(self) -> None:
        """Set the head's regulated pressure: the command, or the EP fallback if lower."""
        cmd = self._command
        if self.brake_system == 'ep' and not self.iv[pk.I_LINE]:
            spec = self.spec
            cmd = min(cmd, spec.nominal_pressure
                      - self.ep_command * (spec.nominal_pressure - spec.full_service_pressure))
        self.sc[pk.S_CMD] = cmd

    # -- distributed power: radio link ------------------------------------------------------
    @property
    def has_remotes(self) -> bool:
        """Whether the train has distributed-power locomotives."""
        return bool(np.any(self.veh[pk.V_REMOTE] > 0.5))

    def _schedule(self, t: float, action) -> None:
        self._order += 1
        self._events.append((float(t), self._order, action))
        self._events.sort(key=lambda e: (e[0], e[1]))

    def _radio_send(self) -> None:
        """Send the lead's brake and traction state; lost with ``spec.radio_loss``."""
        if not self.has_remotes:
            return
        self.radio_sent += 1
        if self.spec.radio_loss > 0.0 and self._rng.random() < self.spec.radio_loss:
            self.radio_lost += 1
            return
        state = (self._command, self._lap, self.lead_traction)
        self._schedule(self.t + self.spec.radio_delay, lambda: self._radio_receive(*state))

    def _radio_receive(self, command, lap, traction) -> None:
        remote = self.veh[pk.V_REMOTE] > 0.5
        self.veh[pk.V_RCMD, remote] = command
        self.veh[pk.V_RLAP, remote] = float(lap)
        self.remote_traction = traction
        self.radio_received += 1
        self.radio_last = self.t
        self.radio_ok = True

    def _radio_tick(self) -> None:
        """Every radio period: the lead repeats its state; a silent link is declared lost."""
        if self.t - self.radio_last > self.spec.radio_timeout:
            # link lost: the remotes idle (no traction) and hold their pipe (valve lapped)
            self.radio_ok = False
            self.veh[pk.V_RLAP, self.veh[pk.V_REMOTE] > 0.5] = 1.0
            self.remote_traction = 0.0
        self._radio_send()
        self._schedule(self.t + self.spec.radio_period, self._radio_tick)

    def set_pipe_pressure(self, p, index: int | None = None) -> None:
        """Local pipe pressures [Pa gauge] when the pipe is external (``pipe_per_coach``)."""
        if index is None:
            self.veh[pk.V_PEXT] = np.asarray(p, dtype=float)
        else:
            self.veh[pk.V_PEXT, index] = float(p)

    # -- stepping ---------------------------------------------------------------------------
    def advance(self, n_steps: int, trace: np.ndarray | None = None,
                traction: np.ndarray | None = None) -> None:
        """
        Advance ``n_steps`` steps.

        ``trace`` (n_steps, N) receives the cylinder pressures, ``traction`` (n_steps,) the
        remotes' traction command during each step.

        Pending actions (EP valves after their delay, radio messages) take effect at the
        first step boundary at or after their instant.
        """
        n_steps = int(n_steps)
        done = 0
        while True:
            self._fire_due()
            if done >= n_steps:
                return
            k = n_steps - done
            if self._events:
                k = min(k, max(1, int(math.ceil((self._events[0][0] - self.t) / self.h
                                                - 1e-9))))
            if traction is not None:
                traction[done:done + k] = self.remote_traction
            pk.advance(k, self.cells, self.faces, self.veh, self.sc, self.iv,
                       self._empty if trace is None else trace[done:done + k])
            self.steps += k
            done += k

    def _fire_due(self) -> None:
        while self._events and self._events[0][0] <= self.t + 1e-9:
            self._events.pop(0)[2]()

    @property
    def t(self) -> float:
        """Time of the brake system [s]."""
        return self.steps * self.h

    # -- outputs (gauge Pa, per vehicle) ----------------------------------------------------
    def _gauge(self, row: int, vol_row: int) -> np.ndarray:
        return self.veh[row] * self.rt / self.veh[vol_row] - self.spec.atmospheric_pressure

    @property
    def cell_pressure(self) -> np.ndarray:
        """Pressure of every pipe cell, gauge [Pa]."""
        return self.cells[pk.C_M] * self.rt / self.cells[pk.C_VOL] - self.spec.atmospheric_pressure

    @property
    def pipe_pressure(self) -> np.ndarray:
        """Brake-pipe pressure at each vehicle's distributor, gauge [Pa]."""
        if self.iv[pk.I_EXTERNAL]:
            return self.veh[pk.V_PEXT].copy()
        return self.cell_pressure[self.veh[pk.V_CELL].astype(np.int64)]

    @property
    def control_pressure(self) -> np.ndarray:
        """Control-reservoir pressures, gauge [Pa]."""
        return self._gauge(pk.V_MCR, pk.V_VCR)

    @property
    def auxiliary_pressure(self) -> np.ndarray:
        """Auxiliary-reservoir pressures, gauge [Pa]."""
        return self._gauge(pk.V_MAUX, pk.V_VAUX)

    @property
    def cylinder_pressure(self) -> np.ndarray:
        """Brake-cylinder pressures, gauge [Pa] (the kernel's ``cylinder_pressure``)."""
        veh = self.veh
        m, v0, vs = veh[pk.V_MCYL], veh[pk.V_VCYL], veh[pk.V_VSTROKE]
        ps = self.spec.atmospheric_pressure + veh[pk.V_PSPRING]
        p = np.where(m <= ps * v0 / self.rt, m * self.rt / v0,
                     np.where(m < ps * (v0 + vs) / self.rt, ps, m * self.rt / (v0 + vs)))
        return p - self.spec.atmospheric_pressure

    @property
    def valve_state(self) -> np.ndarray:
        """
        Each cylinder's valve in the last step: +1 filling, 0 lapped (holding), -1 venting.

        The distributor's relay part, the EP valves or the ECP car control device.
        """
        return self.veh[pk.V_VALVE].copy()

    @property
    def ep_command_at_vehicles(self) -> float:
        """
        EP / ECP command the vehicles' valves follow now, fraction of full service.

        0 with the train line lost (nothing is received); 0 for ``brake_system`` pneumatic.
        """
        if self.brake_system == 'pneumatic' or not self.iv[pk.I_LINE]:
            return 0.0
        return float(self.sc[pk.S_EPCMD])

    @property
    def radio_age(self) -> float:
        """Time [s] since the remotes last received a radio message (0 before the first)."""
        return max(0.0, self.t - self.radio_last)

    @property
    def ep_command_received(self) -> float:
        """EP / ECP command acting at the vehicles (after the valve delay), fraction."""
        return float(self.sc[pk.S_EPCMD])

    @property
    def train_line(self) -> bool:
        """Whether the EP / ECP train line is healthy."""
        return bool(self.iv[pk.I_LINE])

    @property
    def accelerator_open(self) -> np.ndarray:
        """Emergency accelerators venting the pipe now."""
        return self.veh[pk.V_ACCOPEN] > 0.5

    @property
    def remote_command(self) -> np.ndarray:
        """Pressure each remote's brake valve regulates to, gauge [Pa] (NaN: not a remote)."""
        return np.where(self.veh[pk.V_REMOTE] > 0.5, self.veh[pk.V_RCMD], np.nan)

    @property
    def applied(self) -> np.ndarray:
        """Distributors in the applied position."""
        return self.veh[pk.V_APPLIED] > 0.5

    @property
    def pipe_air_mass(self) -> float:
        """Air in the pipe [kg]."""
        return float(np.sum(self.cells[pk.C_M]))

    @property
    def total_air_mass(self) -> float:
        """Air in the pipe, reservoirs, cylinders and bulbs [kg]."""
        veh = self.veh
        return self.pipe_air_mass + float(np.sum(veh[pk.V_MCR] + veh[pk.V_MAUX] + veh[pk.V_MCYL]
                                                 + veh[pk.V_MQS]))


def propagation_speed(lengths, instants) -> float:
    """
    Return the speed [m/s] at which an event (e.g. a 1 bar pipe drop) travels along a train.

    1 / slope of the least-squares line of the event's instants [s] at the vehicles against
    the positions of their distributors (each vehicle's middle [m], ``lengths`` front to
    rear): the wave's speed along the whole train, not set by one vehicle's lag at either end.
    """
    lengths = np.asarray(lengths, dtype=float)
    middle = np.cumsum(lengths) - 0.5 * lengths
    slope = np.polyfit(middle, np.asarray(instants, dtype=float), 1)[0]
    return float(1.0 / slope)


def from_config(cfg, h: float, external_pipe: bool = False, lengths=None, p_max=None,
                regimes=None, accelerators=None, remotes=None, **cylinders) -> PneumaticBrake:
    """
    Return the pneumatic brake of a simulator configuration (``parameters.SimConfig``).

    ``lengths``, ``p_max``, ``regimes``, ``accelerators``, ``remotes``: per-vehicle data of
    a consist; by default the uniform train's ``coach_length``, ``max_cylinder_pressure`` and
    ``brake_regime``, ``emergency_accelerator`` on every vehicle, no remote locomotives.
    ``cylinders``: the per-vehicle
    cylinder keywords of :class:`PneumaticBrake` (``inshot``, ``dead_volume``,
    ``stroke_volume``, ``spring_pressure``).
    """
    n = cfg.n_coaches
    spec = PneumaticSpec(
        pipe_diameter=float(cfg.brake_pipe_diameter),
        atmospheric_pressure=float(cfg.atmospheric_pressure),
        nominal_pressure=float(cfg.pipe_nominal_pressure),
        full_service_pressure=float(cfg.full_service_pressure),
        leakage=float(cfg.brake_pipe_leakage),
        angle_cock_closed=int(cfg.angle_cock_closed),
        main_reservoir_pressure=float(cfg.main_reservoir_pressure),
        radio_delay=float(cfg.radio_delay),
        radio_loss=float(cfg.radio_loss))
    return PneumaticBrake(
        np.full(n, float(cfg.coach_length)) if lengths is None else lengths,
        float(cfg.max_cylinder_pressure) if p_max is None else p_max,
        str(cfg.brake_regime) if regimes is None else regimes, h, spec, external_pipe,
        accelerators=bool(cfg.emergency_accelerator) if accelerators is None else accelerators,
        remotes=False if remotes is None else remotes, brake_system=str(cfg.brake_system),
        **cylinders)
