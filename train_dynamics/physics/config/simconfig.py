"""
The simulator's configuration: :class:`SimConfig`, each parameter a typed attribute.

Build one with :meth:`SimConfig.from_dict` (values checked one by one with the table's
validator, then as a whole by :meth:`SimConfig.check`) or :meth:`SimConfig.replace` (a ROS 2
parameter file: :func:`train_dynamics.param_files.load_param_file`). A configuration never
changes afterwards: a change, live (``ros2 param set``) or not, makes a new one with
:meth:`SimConfig.replace`, checked as a whole.

The consist (:class:`~train_dynamics.physics.config.consist.Consist`) is built when the
configuration is: a consist file is read once and kept. :meth:`SimConfig.replace` keeps the
parent's consist unless a value it is built from (:data:`CONSIST_PARAMETERS`) changes, so a
consist file that changes or disappears later never affects a configuration already built, nor
one derived from it by a change of other values. Never imports rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
from typing import Any, Mapping

import numpy as np

from train_dynamics.physics import track
from train_dynamics.physics.config.blending_params import check_blending
from train_dynamics.physics.config.budgets import (config_memory, fmt_bytes, MAX_PERIOD_SECONDS,
                                                   max_period_steps, MAX_SIMULATOR_MEMORY)
from train_dynamics.physics.config.consist import (check_friction_below_stiffness,
                                                   check_traction_power, Consist, consist_of,
                                                   CONSIST_PARAMETERS)
from train_dynamics.physics.config.integrator import DEFAULT_INTEGRATOR, Integration, resolve
from train_dynamics.physics.config.spec import ConfigError
from train_dynamics.physics.config.table import (ATMOSPHERIC_PRESSURE, FULL_SERVICE_PRESSURE,
                                                 G_FILL_TIME, G_RELEASE_TIME, INSHOT_PRESSURE,
                                                 INTEGRATION_TOLERANCE, MULTIRATE_REVERSAL_WEIGHT,
                                                 MULTIRATE_TOLERANCE,
                                                 P_FILL_FRACTION,
                                                 P_FILL_TIME, P_RELEASE_FRACTION, P_RELEASE_TIME,
                                                 PARAMETERS, PIPE_NOMINAL_PRESSURE, validate_value)
from train_dynamics.quoting import quote

#: relative tolerance of ``1 / (publish_rate * integration_step)`` being a whole number
GRID_TOLERANCE = 1e-9


@dataclass(frozen=True)
class SimConfig:
    """
    All parameters of the simulator (:data:`~train_dynamics.physics.config.table.PARAMETERS`).

    One attribute per parameter, declared here with its type and default (a test checks them
    against the table, which holds the description, unit and range of each).
    """

    # coupler model (paper eqs. 2-4, 14-16)
    model_type: str = 'tanh'                          # friction law: 'tanh' or 'sign' (live)
    scale_factor: float = 1000.0                      # u in tanh(u ydot) [s/m] (live)
    # the uniform train (no consist_file)
    num_coaches: int = 3                              # N >= 2, unless masses is set
    coach_mass: float = 45000.0                       # m_i [kg]; vehicle field 'mass'
    masses: list[float] = field(default_factory=list)  # per coach [kg], front to rear
    coach_length: float = 25.0                        # [m]; vehicle field 'length'
    buffer_stiffness: float = 2.8e6                   # k_e [N/m] (eq. 2)
    buffer_friction: float = 1.4e6                    # k_f [N/m] (eq. 2), < k_e
    draw_gear_stiffness: float = 5.46e6               # k_ec [N/m] (eq. 3)
    draw_gear_friction: float = 2.43e6                # k_fc [N/m] (eq. 3), < k_ec
    adhesion_coefficient: float = 0.1                 # mu_a [-] (eqs. 12-13)
    gravity: float = 9.81                             # g [m/s^2]
    max_cylinder_pressure: float = 380000.0           # p_max, gauge [Pa] (eq. 13)
    initial_speed: float = 44.444                     # v_i(0) [m/s]
    # brake inputs and the empirical brake
    brake_input: str = 'pipe_head'                    # pipe_head, pipe_per_coach, cylinder_...
    brake_propagation_speed: float = 250.0            # brake wave along the pipe [m/s]
    # integration and outputs
    integration_step: float = 2.0e-3                  # fixed step h [s]
    publish_rate: float = 100.0                       # outputs [Hz] (simulation time)
    real_time_factor: float = 1.0                     # sim s per wall s; 0 = fast (live)
    publish_clock: bool = False                       # publish /clock (live)
    record_bag: str = ''                              # rosbag2 path; '' = no recording
    atmospheric_pressure: float = ATMOSPHERIC_PRESSURE  # absolute -> gauge [Pa]
    # brake cylinders and the distributors
    brake_regime: str = 'P'                           # default characteristics: 'P' or 'G'
    cylinder_fill_time: list[float] = field(default_factory=list)         # [s]; [] = regime
    cylinder_fill_fraction: list[float] = field(default_factory=list)     # p / p_max [-]
    cylinder_release_time: list[float] = field(default_factory=list)      # [s]; [] = regime
    cylinder_release_fraction: list[float] = field(default_factory=list)  # p / p_max [-]
    pipe_nominal_pressure: float = PIPE_NOMINAL_PRESSURE  # running pressure, gauge [Pa]
    full_service_pressure: float = FULL_SERVICE_PRESSURE  # full service, gauge [Pa]
    distributor_sensitivity: float = 30000.0          # pipe drop a distributor ignores [Pa]
    max_coupler_displacement: float = 5.0             # |y| fault bound [m]
    # stale brake inputs (live)
    input_timeout: float = 0.0                        # [s wall]; 0 = never stale
    on_input_timeout: str = 'hold'                    # 'hold' or 'emergency'
    # pneumatic brake (physics/pneumatic.py)
    brake_model: str = 'empirical'                    # 'empirical' or 'pneumatic'
    brake_pipe_leakage: float = 0.0                   # lapped pipe's drop rate [Pa/s]
    angle_cock_closed: int = 0                        # coupling cut off; 0 = all open
    brake_pipe_diameter: float = 0.032                # inner diameter [m]
    main_reservoir_pressure: float = 900000.0         # gauge [Pa]
    brake_system: str = 'pneumatic'                   # 'pneumatic', 'ep' or 'ecp'
    emergency_accelerator: bool = True                # vehicle field: accelerator fitted
    inshot_pressure: float = INSHOT_PRESSURE          # vehicle field: first stage [Pa]
    cylinder_dead_volume: float = 0.008               # vehicle field: pistons in [m^3]
    piston_stroke: float = 0.0                        # vehicle field: [m]; 0 = fixed volume
    remote: bool = False                              # vehicle field: DP remote locomotive
    radio_delay: float = 0.5                          # distributed power: lead -> remote [s]
    radio_loss: float = 0.0                           # probability a radio message is lost
    # run metrics (live)
    coupler_force_limit: float = 0.0                  # |F| limit [N]; 0 = off
    jerk_limit: float = 0.0                           # |jerk| limit [m/s^3]; 0 = off
    # real trains: consist, coupler travel, resistance, traction (vehicle fields)
    consist_file: str = ''                            # YAML consist; '' = uniform train
    rotating_mass_factor: float = 0.0                 # inertia m (1 + factor) [-]
    davis_a: float = 0.0                              # Davis A [N]
    davis_b: float = 0.0                              # Davis B [N s/m]
    davis_c: float = 0.0                              # Davis C [N s^2/m^2]
    buffer_stroke: float = 0.105                      # S_c [m]
    draw_gear_stroke: float = 0.06                    # S_t [m]
    buffer_slack: float = 0.0                         # g_c [m]
    draw_gear_slack: float = 0.0                      # g_t [m]
    blocked_stiffness: float = 1.0e8                  # K_b [N/m]
    buffer_preload: float = 0.0                       # [N]; 0 = none
    draw_gear_preload: float = 0.0                    # [N]; 0 = none
    buffer_final_force: float = 0.0                   # [N] at the stroke; 0 = linear law
    draw_gear_final_force: float = 0.0                # [N] at the stroke; 0 = linear law
    buffer_energy: float = 0.0                        # [J] to the stroke; 0 = linear
    draw_gear_energy: float = 0.0                     # [J] to the stroke; 0 = linear
    max_tractive_force: float = 0.0                   # [N]; 0 = no traction
    max_power: float = 0.0                            # traction power at the rim [W]
    max_dynamic_brake_force: float = 0.0              # [N]
    max_dynamic_brake_power: float = 0.0              # [W]
    traction_build_up_time: float = 4.0               # 0 -> full command [s]
    traction_adhesion: float = 0.33                   # at standstill [-]
    dynamic_brake_fade_speed: float = 1.4             # [m/s]
    initial_state: str = 'equilibrium'                # couplers at t = 0, or 'unstressed'
    friction_material: str = 'paper'                  # paper (eq. 13) or a material
    brake_cylinder_area: float = 0.0                  # force chain: piston area [m^2]
    brake_cylinders: float = 1.0                      # force chain: cylinders per vehicle
    brake_cylinder_efficiency: float = 0.95           # force chain: eta_c [-]
    brake_spring_force: float = 0.0                   # force chain: return spring [N]
    rigging_ratio: float = 0.0                        # force chain: lever ratio i [-]
    rigging_efficiency: float = 0.83                  # force chain: eta_r [-]
    brake_blocks: float = 8.0                         # blocks or pads per vehicle
    brake_radius_ratio: float = 1.0                   # disc: r_eff / r_wheel [-]
    braked_mass_p: float = 0.0                        # braked mass, regime P [kg]
    braked_mass_g: float = 0.0                        # braked mass, regime G [kg]
    load_empty_mass: float = 0.0                      # load-weighing: empty [kg]; 0 = none
    load_full_mass: float = 0.0                       # load-weighing: loaded from [kg]
    load_changeover_mass: float = 0.0                 # 0 = continuous valve [kg]
    load_empty_ratio: float = 1.0                     # empty / loaded pressure [-]
    # the line
    initial_position: float = 0.0                     # front of vehicle 1 at t = 0 [m]
    target_stop_position: list[float] = field(default_factory=list)   # [] or [x] [m]
    track_gradient_positions: list[float] = field(default_factory=list)   # [m], increasing
    track_gradients: list[float] = field(default_factory=list)            # [per mille]
    track_curve_starts: list[float] = field(default_factory=list)         # [m]
    track_curve_ends: list[float] = field(default_factory=list)           # [m]
    track_curve_radii: list[float] = field(default_factory=list)          # [m]
    track_adhesion_positions: list[float] = field(default_factory=list)   # [m] (live)
    track_adhesion: list[float] = field(default_factory=list)             # mu_low [-] (live)
    # wheel slide (physics/wheelset.py)
    wheelsets: bool = False                           # rotating wheelsets, creep law
    wsp: str = 'none'                                 # slide protection: none/builtin/external
    adhesion_limit: bool = True                       # braking force <= mu(v) m g
    wheelset_inertia: float = 440.0                   # vehicle field: J [kg m^2]
    wheel_radius: float = 0.46                        # vehicle field: r [m]
    wheel_speed_resolution: float = 0.0               # speed sensor: quantisation [m/s]
    wheel_speed_noise: float = 0.0                    # speed sensor: noise std [m/s]
    wheel_speed_seed: int = 0                         # speed sensor: seed of the noise
    traction_schedule_times: list[float] = field(default_factory=list)    # [s], increasing
    traction_schedule_commands: list[float] = field(default_factory=list)  # [-1, 1]
    ep_schedule_times: list[float] = field(default_factory=list)          # [s], increasing
    ep_schedule_commands: list[float] = field(default_factory=list)       # [0, 1]
    # the integration method (config/integrator.py)
    integrator: str = DEFAULT_INTEGRATOR              # 'fixed', 'multirate' or 'adaptive'
    integration_tolerance: float = INTEGRATION_TOLERANCE  # [-]; 0 = unset
    integration_max_steps: int = 100                  # steps per output period
    multirate_tolerance: float = MULTIRATE_TOLERANCE  # [-]; 0 = plain fixed step
    multirate_reversal_weight: float = MULTIRATE_REVERSAL_WEIGHT  # [-]; 0 = off
    # multiple units: brake control unit and blending (config/blending_params.py)
    blending: str = 'none'                            # 'none' or 'builtin'
    blending_scope: str = 'train'                     # 'train' or 'car'
    brake_demand_mode: str = 'fraction'               # 'fraction' or 'deceleration'
    full_service_deceleration: float = 1.0            # [m/s^2]
    blending_jerk_limit: float = 1.0                  # [m/s^3]
    blending_period: float = 0.01                     # BCU cycle [s]
    friction_response_time: float = 0.3               # EP cylinder time constant [s]
    demand_schedule_times: list[float] = field(default_factory=list)   # [s]
    demand_schedule_values: list[float] = field(default_factory=list)  # as brake_demand_mode
    emergency_schedule_time: float = -1.0             # [s]; < 0 none
    ed_trip_schedule_time: float = -1.0               # [s]; < 0 never
    track_brake_force: float = 0.0                    # vehicle field: at rest [N]; 0 none
    track_brake_half_speed: float = 30.0              # vehicle field: [m/s]
    eddy_brake_force: float = 0.0                     # vehicle field: at v_c [N]; 0 none
    eddy_brake_critical_speed: float = 15.0           # vehicle field: [m/s]
    eddy_brake_air_gap: float = 0.007                 # vehicle field: [m]
    track_brake_delay: float = 0.5                    # switching delay [s]
    # vehicle ends and resistance laws (config/table_ends.py)
    buffers_per_end: int = 1                          # side buffers per end, in parallel
    coupling_pretension: float = 0.0                  # screw coupling at rest [N]; 0 = none
    buffer_characteristic: str = ''                   # tabulated buffer curve; '' = none
    draw_gear_characteristic: str = ''                # tabulated draw-gear curve; '' = none
    resistance_law: str = 'davis'                     # davis, strahl or sauthoff
    strahl_k: float = 0.05                            # Strahl speed factor k [-]
    sauthoff_c: float = 0.0024                        # Sauthoff c [per mille per km/h]
    sauthoff_area: float = 1.45                       # Sauthoff area f [m^2]
    resistance_wind: float = 15.0                     # wind allowance dV [km/h]

    #: the parsed consist (built by :meth:`from_dict` or on first use, then kept)
    _consist = None

    @classmethod
    def from_dict(cls, overrides: Mapping[str, Any] | None = None, *,
                  ignore_unknown: bool = False) -> SimConfig:
        """Return the configuration of the defaults and ``overrides``; raises ConfigError."""
        values = {}
        for name, value in (overrides or {}).items():
            if name not in PARAMETERS:
                if ignore_unknown:
                    continue
                raise ConfigError(f'unknown parameter {quote(name)}')
            values[name] = validate_value(name, value)
        return cls._checked(values, None)

    @classmethod
    def _checked(cls, values: dict[str, Any], consist: Consist | None) -> SimConfig:
        cfg = cls(**values)
        object.__setattr__(cfg, '_consist', consist)
        cfg.check()
        return cfg

    def replace(self, **changes: Any) -> SimConfig:
        """
        Return a configuration with ``changes``, checked as a whole.

        The consist is kept (no file read) unless a value of :data:`CONSIST_PARAMETERS`
        changes.
        """
        old = self.values
        new = dict(old)
        for name, value in changes.items():
            if name not in PARAMETERS:
                raise ConfigError(f'unknown parameter {quote(name)}')
            new[name] = validate_value(name, value)
        same = all(new[n] == old[n] for n in CONSIST_PARAMETERS)
        return SimConfig._checked(new, self.consist if same else None)

    @property
    def values(self) -> dict[str, Any]:
        """Return ``{name: value}`` of every parameter, in table order (a new dict)."""
        return {name: getattr(self, name) for name in PARAMETERS}

    # -- derived quantities -------------------------------------------------------------
    @property
    def consist(self) -> Consist:
        """Return the vehicles of the train (built once, then kept)."""
        if self._consist is None:
            object.__setattr__(self, '_consist', consist_of(self.values))
        return self._consist

    @property
    def n_coaches(self) -> int:
        """Return the number of vehicles."""
        if self.consist_file:
            return self.consist.n
        return len(self.masses) if self.masses else int(self.num_coaches)

    @property
    def mass_array(self) -> list[float]:
        """Return the mass [kg] of every vehicle, front to rear."""
        if self.consist_file:
            return [float(m) for m in self.consist['mass']]
        if self.masses:
            return list(self.masses)
        return [float(self.coach_mass)] * int(self.num_coaches)

    @property
    def external_forces(self) -> bool:
        """Return True when the train has resistance, gradients, curves or traction."""
        if (self.consist_file or self.davis_a or self.davis_b or self.davis_c
                or self.resistance_law != 'davis'):
            return True
        return bool(self.track_gradients or self.track_curve_starts
                    or self.max_tractive_force or self.max_dynamic_brake_force)

    @property
    def track(self) -> track.Track:
        """Return the line (:class:`~train_dynamics.physics.track.Track`) of the parameters."""
        return track.Track.from_lists(self.initial_position, self.track_gradient_positions,
                                      self.track_gradients, self.track_curve_starts,
                                      self.track_curve_ends, self.track_curve_radii,
                                      self.track_adhesion_positions, self.track_adhesion)

    @property
    def integration(self) -> Integration:
        """Return the integration method and the tolerances it uses (config/integrator.py)."""
        return resolve(self.integrator, self.integration_tolerance, self.multirate_tolerance)

    @property
    def has_wheelsets(self) -> bool:
        """Return True when the vehicles run on rotating wheelsets (``wheelsets``, implied)."""
        return bool(self.wheelsets or self.wsp != 'none'
                    or any(a < track.DRY_ADHESION for a in self.track_adhesion))

    def fill_table(self, regime: str = '') -> tuple[list[float], list[float]]:
        """Return the filling characteristic of ``regime`` (brake_regime): times [s], p/p_max."""
        if self.cylinder_fill_time:
            return list(self.cylinder_fill_time), list(self.cylinder_fill_fraction)
        times = P_FILL_TIME if (regime or self.brake_regime) == 'P' else G_FILL_TIME
        return list(times), list(P_FILL_FRACTION)

    def release_table(self, regime: str = '') -> tuple[list[float], list[float]]:
        """Return the release characteristic of ``regime`` (brake_regime): times [s], p/p_max."""
        if self.cylinder_release_time:
            return list(self.cylinder_release_time), list(self.cylinder_release_fraction)
        times = P_RELEASE_TIME if (regime or self.brake_regime) == 'P' else G_RELEASE_TIME
        return list(times), list(P_RELEASE_FRACTION)

    @property
    def ep_commanded(self) -> bool:
        """Return True if the train takes ``brake_ep/command`` (an EP or ECP brake system)."""
        return self.brake_model == 'pneumatic' and self.brake_system != 'pneumatic'

    # -- the checks as a whole ------------------------------------------------------------
    def check(self) -> None:
        """Cross-parameter checks; raises :class:`ConfigError`."""
        self.integration                 # the method: refuses a contradiction
        self._check_real_train()
        check_blending(self)
        if self.masses and len(self.masses) < 2:
            raise ConfigError(f'masses: a train needs at least 2 coaches, got {len(self.masses)}')
        check_output_grid(float(self.publish_rate), float(self.integration_step))
        memory = config_memory(self)
        if memory > MAX_SIMULATOR_MEMORY:
            steps = 1.0 / (float(self.publish_rate) * float(self.integration_step))
            raise ConfigError(
                f'the simulator would need {fmt_bytes(memory)} (limit '
                f'{fmt_bytes(MAX_SIMULATOR_MEMORY)}) for {self.n_coaches} vehicles: the '
                'brake-pipe delay line holds (pipe length) / brake_propagation_speed / '
                f'integration_step samples, each output period {steps:.3g} steps (1 / '
                'publish_rate / integration_step) per vehicle; raise brake_propagation_speed, '
                'integration_step or publish_rate, or shorten the train')
        self._check_work()
        if self.has_wheelsets and self.integration.method == 'adaptive':
            raise ConfigError('wheelsets (wheelsets, wsp or a track_adhesion below dry) need '
                              'the fixed step: set integration_tolerance 0 and integrator '
                              'fixed or multirate')
        # the uniform train's vehicles (and the defaults of a consist's)
        check_friction_below_stiffness(self.values)
        check_traction_power(self.values)
        if not (self.full_service_pressure + self.distributor_sensitivity
                < self.pipe_nominal_pressure):
            raise ConfigError('full_service_pressure + distributor_sensitivity must be below '
                              'pipe_nominal_pressure')
        if self.angle_cock_closed > self.n_coaches - 1:
            raise ConfigError(f'angle_cock_closed: the couplings are 1..{self.n_coaches - 1} '
                              f'(0 = none), got {self.angle_cock_closed}')
        if self.remote:
            raise ConfigError("remote is a field of a consist's locomotives (consist_file); "
                              'the uniform train has no remote locomotive')
        if self.brake_system != 'pneumatic' and self.brake_model != 'pneumatic':
            raise ConfigError(f'brake_system {self.brake_system} needs brake_model pneumatic')
        if (self.brake_model == 'pneumatic'
                and self.main_reservoir_pressure <= self.pipe_nominal_pressure):
            raise ConfigError('main_reservoir_pressure must be above pipe_nominal_pressure')
        for kind in ('fill', 'release'):
            self._check_cylinder_table(kind)

    def _check_cylinder_table(self, kind: str) -> None:
        t_name, f_name = f'cylinder_{kind}_time', f'cylinder_{kind}_fraction'
        times, fracs = getattr(self, t_name), getattr(self, f_name)
        if len(times) != len(fracs):
            raise ConfigError(f'{t_name} and {f_name} must have the same length '
                              f'({len(times)} != {len(fracs)})')
        if not times:
            return
        if len(times) < 2:
            raise ConfigError(f'{t_name}: a characteristic needs at least 2 points')
        if times[0] != 0.0 or any(b <= a for a, b in zip(times, times[1:])):
            raise ConfigError(f'{t_name}: must start at 0 and strictly increase')
        if kind == 'fill':
            ok = fracs[0] == 0.0 and fracs[-1] == 1.0 and all(
                b > a for a, b in zip(fracs, fracs[1:]))
            if not ok:
                raise ConfigError(f'{f_name}: must rise strictly from 0 to 1')
        else:
            ok = fracs[0] == 1.0 and fracs[-1] == 0.0 and all(
                b < a for a, b in zip(fracs, fracs[1:]))
            if not ok:
                raise ConfigError(f'{f_name}: must fall strictly from 1 to 0')

    def _check_real_train(self) -> None:
        """Check the track, the traction schedule and the consist file (read it once)."""
        try:
            self.track
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        for kind in ('traction', 'ep'):
            t_name, c_name = f'{kind}_schedule_times', f'{kind}_schedule_commands'
            times, cmds = getattr(self, t_name), getattr(self, c_name)
            if len(times) != len(cmds):
                raise ConfigError(f'{t_name} and {c_name} must have the same length '
                                  f'({len(times)} != {len(cmds)})')
            if any(b <= a for a, b in zip(times, times[1:])):
                raise ConfigError(f'{t_name}: must strictly increase')
        if self.ep_schedule_times and not self.ep_commanded:
            raise ConfigError('ep_schedule_times: needs brake_model pneumatic and brake_system '
                              'ep or ecp')
        times = self.traction_schedule_times
        if self.consist_file:
            remotes = self.consist.remotes
            if remotes and self.brake_model != 'pneumatic':
                raise ConfigError(f'{self.consist_file}: remote locomotives (vehicles '
                                  f'{[i + 1 for i in remotes]}) need brake_model pneumatic')
        consist = self.consist
        bad = np.flatnonzero((consist['piston_stroke'] > 0.0)
                             & (consist['brake_cylinder_area'] <= 0.0))
        if bad.size:
            raise ConfigError(f'piston_stroke needs brake_cylinder_area > 0 (vehicles '
                              f'{[int(i) + 1 for i in bad[:10]]})')
        if times and not self.consist.locomotives:
            raise ConfigError('traction_schedule_times: the train has no locomotive (no vehicle '
                              'with max_tractive_force or max_dynamic_brake_force > 0), so the '
                              'traction schedule would command nothing; remove it or add a '
                              'locomotive')

    def _check_work(self) -> None:
        """Refuse an error-control work budget that could keep one output period busy."""
        limit = max_period_steps(self.n_coaches)
        if self.integration.method == 'adaptive' and self.integration_max_steps > limit:
            raise ConfigError(
                f'integration_max_steps {self.integration_max_steps}: more than the limit of '
                f'{limit} error-controlled steps per output period for {self.n_coaches} '
                f'vehicles (about {MAX_PERIOD_SECONDS:g} s of work per period: signals and '
                'callbacks are served between periods); lower integration_max_steps '
                '(the rest of a period runs at the fixed integration_step)')


def check_output_grid(rate: float, h: float) -> None:
    """Raise unless 1 / ``rate`` [Hz] is a whole number of steps ``h`` [s] (exact grid)."""
    ratio = 1.0 / (rate * h)
    steps = round(ratio)
    if steps >= 1 and abs(ratio - steps) <= GRID_TOLERANCE * steps:
        return
    up = max(1, math.ceil(ratio - GRID_TOLERANCE * ratio))
    rates = sorted({1.0 / (k * h) for k in (max(1, math.floor(ratio)), up)
                    if 1.0 / (k * h) <= PARAMETERS['publish_rate'].high})
    hint = ' or '.join(f'{r:.9g}' for r in rates)
    raise ConfigError(
        f'publish_rate {rate:g} Hz and integration_step {h:g} s: an output period of '
        f'{ratio:.6g} steps; outputs must land on whole steps, so 1 / publish_rate must be a '
        f'whole number of integration steps: use publish_rate {hint or "<= 1 / step"} Hz, or '
        f'integration_step {1.0 / (rate * up):.9g} s')
