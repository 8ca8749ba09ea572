"""
Parameters: one description format (:class:`ParamSpec`) and one validator for every parameter.

The simulator's table :data:`PARAMETERS` (every parameter of the product contract, declared
once with its default, type, unit, range and whether it may change while the simulation runs)
is shared by ``sim_node`` and the offline command; :data:`SIM_NODE_PARAMETERS` are the
node's own (not part of the simulator configuration). The brake valve describes its
parameters in the same format (:mod:`train_dynamics.physics.brake_valve`). The nodes build
their ROS parameter descriptors from these tables (``train_dynamics.ros.parameters``) and
check every value with :func:`validate_value`; the offline command reads the same ROS 2
parameter file with :func:`load_param_file`. Pressures in parameters are GAUGE pressures [Pa],
except :data:`ATMOSPHERIC_PRESSURE`.

This module never imports rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math
import os
import re
from typing import Any, Callable, Mapping

from train_dynamics import topics
# consist uses this module's table at call time only (a circular import that is safe)
from train_dynamics.physics import consist, track
from train_dynamics.physics.kernel import layout
import yaml

# Kinds of value, named after the ROS 2 parameter types they map to.
DOUBLE = 'double'
INTEGER = 'integer'
STRING = 'string'
BOOL = 'bool'
DOUBLE_ARRAY = 'double_array'
STRING_ARRAY = 'string_array'
ARRAY_KINDS = (DOUBLE_ARRAY, STRING_ARRAY)

# Pressure defaults, written once (used by the simulator and the brake valve).
ATMOSPHERIC_PRESSURE = 101325.0    # [Pa absolute]: FluidPressure (absolute) = gauge + this
PIPE_NOMINAL_PRESSURE = 500000.0   # [Pa gauge] brake-pipe running pressure (UIC: 5 bar)
FULL_SERVICE_PRESSURE = 350000.0   # [Pa gauge] brake pipe at full service (UIC: 3.5 bar)


@dataclass(frozen=True)
class ParamSpec:
    """
    Declaration of one parameter: what ``ros2 param describe`` shows.

    ``dynamic``: the value may change while the node runs and acts at once; otherwise it is
    structural (``sim_node`` keeps it pending until the ``reset`` service).
    """

    name: str
    default: Any
    kind: str
    description: str
    low: float | None = None          # lower bound, inclusive unless low_exclusive
    high: float | None = None         # upper bound, inclusive
    low_exclusive: bool = False
    choices: tuple[str, ...] = ()
    dynamic: bool = False


# Quick-acting passenger (UIC "P") brake: cylinder filling and release characteristics,
# as fractions of the maximum cylinder pressure against time [s]. Filling reaches 95 % in
# 4.0 s (UIC 540: 3-5 s); release from maximum to 0.4 bar (10.5 % of 3.8 bar) in 17 s
# (UIC: 15-20 s). The filling curve has the shape of the paper's measured Fig. 4: a fast
# first stage, then an exponential approach.
P_FILL_TIME = [0.0, 0.3, 0.6, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0]
P_FILL_FRACTION = [0.0, 0.16, 0.28, 0.41, 0.55, 0.66, 0.75, 0.83, 0.90, 0.95, 0.99, 1.0]
P_RELEASE_TIME = [0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 14.0, 17.0, 20.0, 24.0, 28.0]
P_RELEASE_FRACTION = [1.0, 0.768, 0.589, 0.452, 0.347, 0.267, 0.205, 0.157, 0.105, 0.07, 0.03,
                      0.0]
# Goods (UIC "G") brake: the same shapes stretched to 95 % filling in 24 s (UIC: 18-30 s)
# and release to 0.4 bar in 52 s (UIC: 45-60 s).
G_FILL_TIME = [round(t * 6.0, 3) for t in P_FILL_TIME]
G_RELEASE_TIME = [round(t * 52.0 / 17.0, 3) for t in P_RELEASE_TIME]

#: default integration_tolerance (issue 14)
INTEGRATION_TOLERANCE = 0.0

_PARAMS = [
    ParamSpec('model_type', 'tanh', STRING,
              'Coupler friction law: "tanh" uses tanh(u*ydot) (paper eqs. 14-16), '
              '"sign" uses sgn(ydot) (paper eqs. 2-3).',
              choices=('tanh', 'sign'), dynamic=True),
    ParamSpec('scale_factor', 1000.0, DOUBLE,
              'u in tanh(u*ydot) [s/m], > 0 (paper eq. 14).',
              low=0.0, high=1.0e7, low_exclusive=True, dynamic=True),
    ParamSpec('num_coaches', 3, INTEGER, 'Number of coaches N >= 2 (ignored when masses is set).',
              low=2, high=100000),
    ParamSpec('coach_mass', 45000.0, DOUBLE,
              'Mass of every coach m_i [kg], unless masses is set. Bounds: a track trolley '
              '(~0.5 t) to a loaded heavy-load wagon (~800 t).', low=500.0, high=1.0e6),
    ParamSpec('masses', [], DOUBLE_ARRAY,
              'Per-coach masses [kg], front to rear; non-empty overrides num_coaches and '
              'coach_mass. Bounds as coach_mass.', low=500.0, high=1.0e6),
    ParamSpec('coach_length', 25.0, DOUBLE,
              'Coach length [m]: brake-pipe length per coach. Bounds: a trolley (1 m) to '
              'twice the longest rail vehicles (~50 m).', low=1.0, high=100.0),
    ParamSpec('buffer_stiffness', 2.8e6, DOUBLE,
              'Buffer stiffness k_e [N/m] (paper eq. 2). Real buffers: 0.5-50 MN/m; the '
              'bounds allow two decades either side.', low=1.0e4, high=1.0e10),
    ParamSpec('buffer_friction', 1.4e6, DOUBLE,
              'Buffer friction constant k_f [N/m] (paper eq. 2), 0 <= k_f < k_e.',
              low=0.0, high=1.0e10),
    ParamSpec('draw_gear_stiffness', 5.46e6, DOUBLE,
              'Draw-gear stiffness k_ec [N/m] (paper eq. 3). Bounds as buffer_stiffness.',
              low=1.0e4, high=1.0e10),
    ParamSpec('draw_gear_friction', 2.43e6, DOUBLE,
              'Draw-gear friction constant k_fc [N/m] (paper eq. 3), 0 <= k_fc < k_ec.',
              low=0.0, high=1.0e10),
    ParamSpec('adhesion_coefficient', 0.1, DOUBLE,
              'Wheel-rail adhesion coefficient mu_a (paper eqs. 12-13): full braking force '
              'is mu_a*m*g per coach.', low=0.0, high=1.0, low_exclusive=True),
    ParamSpec('gravity', 9.81, DOUBLE,
              'Gravitational acceleration g [m/s^2]. Bounds: the Moon (1.6) to Jupiter '
              '(24.8), rounded.', low=1.0, high=30.0),
    ParamSpec('max_cylinder_pressure', 380000.0, DOUBLE,
              'Maximum brake-cylinder pressure p_max, gauge [Pa] (paper eq. 13). Bounds: '
              '0.1 bar to the 20 bar input limit.', low=1.0e4, high=2.0e6),
    ParamSpec('initial_speed', 44.444, DOUBLE, 'Initial speed of every coach v_i(0) [m/s].',
              low=0.0, high=200.0),
    ParamSpec('brake_input', 'pipe_head', STRING,
              'Which input drives the brakes: pipe_head, pipe_per_coach or cylinder_per_coach.',
              choices=('pipe_head', 'pipe_per_coach', 'cylinder_per_coach')),
    ParamSpec('brake_propagation_speed', 250.0, DOUBLE,
              'Brake-wave propagation speed along the pipe [m/s]. Bounds: the slowest '
              'pneumatic brakes (~50 m/s; UIC asks >= 250) to an electro-pneumatic signal '
              '(1e5: all coaches at once). Sizes the delay line (see the memory limit).',
              low=50.0, high=1.0e5),
    ParamSpec('integration_step', 2.0e-3, DOUBLE,
              'Fixed integrator step [s] (ROS2, L-stable Rosenbrock): 2 ms keeps the peak '
              'coupler force within 0.35 % of a tight reference at u = 1e3 for 3 to 1000 '
              "coaches (0.07 % on the paper's 3); 5 ms is ~2x faster, within 0.7 %.",
              low=1.0e-6, high=0.05),
    ParamSpec('publish_rate', 100.0, DOUBLE,
              'Output rate [Hz] in simulation time; 1 / publish_rate must be a whole number '
              'of integration steps (outputs on an exact grid).',
              low=0.0, high=10000.0, low_exclusive=True),
    ParamSpec('real_time_factor', 1.0, DOUBLE,
              'Simulation seconds per wall second; 0 = as fast as possible.',
              low=0.0, high=1000.0, dynamic=True),
    ParamSpec('publish_clock', False, BOOL, 'Publish /clock with the simulation time.',
              dynamic=True),
    ParamSpec('record_bag', '', STRING,
              'When set, a path: record inputs and outputs to a rosbag2 (MCAP).'),
    ParamSpec('atmospheric_pressure', ATMOSPHERIC_PRESSURE, DOUBLE,
              'Atmospheric pressure [Pa]: converts the absolute pressures of FluidPressure '
              'messages to gauge.', low=50000.0, high=150000.0),
    # Brake system (beyond the contract; documented in the README).
    ParamSpec('brake_regime', 'P', STRING,
              'Brake regime for the default cylinder characteristics: "P" passenger '
              '(fill 95 % in 4 s, release in 17 s) or "G" goods (24 s, 52 s).',
              choices=('P', 'G')),
    ParamSpec('cylinder_fill_time', [], DOUBLE_ARRAY,
              'Filling characteristic, times [s] (increasing, from 0); empty = regime default.',
              low=0.0, high=1000.0),
    ParamSpec('cylinder_fill_fraction', [], DOUBLE_ARRAY,
              'Filling characteristic, p/p_max at cylinder_fill_time (increasing 0 -> 1).',
              low=0.0, high=1.0),
    ParamSpec('cylinder_release_time', [], DOUBLE_ARRAY,
              'Release characteristic, times [s] (increasing, from 0); empty = regime default.',
              low=0.0, high=1000.0),
    ParamSpec('cylinder_release_fraction', [], DOUBLE_ARRAY,
              'Release characteristic, p/p_max at cylinder_release_time (decreasing 1 -> 0).',
              low=0.0, high=1.0),
    ParamSpec('pipe_nominal_pressure', PIPE_NOMINAL_PRESSURE, DOUBLE,
              'Brake-pipe running pressure, gauge [Pa] (UIC: 5 bar).', low=1.0e5, high=1.0e6),
    ParamSpec('full_service_pressure', FULL_SERVICE_PRESSURE, DOUBLE,
              'Brake-pipe pressure at full service, gauge [Pa] (UIC: 3.5 bar).',
              low=0.0, high=1.0e6),
    ParamSpec('distributor_sensitivity', 30000.0, DOUBLE,
              'Pipe-pressure drop below nominal [Pa] that a distributor ignores; a larger '
              'drop applies the brake (first stage).', low=0.0, high=5.0e5),
    ParamSpec('max_coupler_displacement', 5.0, DOUBLE,
              'Numerical-fault bound on |y| [m]: beyond it the coaches would overlap or part '
              '(a real buffer strokes ~0.1 m); the integration stops with a fault.',
              low=0.0, high=1000.0, low_exclusive=True),
    # Node behaviour (issue 6).
    ParamSpec('input_timeout', 0.0, DOUBLE,
              'Seconds (wall) without any brake input before it is reported stale; 0 = never.',
              low=0.0, high=3600.0, dynamic=True),
    ParamSpec('on_input_timeout', 'hold', STRING,
              'On a stale input: "hold" the last value or apply an "emergency" brake.',
              choices=('hold', 'emergency'), dynamic=True),
    # Pneumatic brake (issue 12; physics/pneumatic.py, README "Pneumatic brake").
    ParamSpec('brake_model', 'empirical', STRING,
              'Brake system model: "empirical" (propagation delay, distributor map, filling '
              'tables) or "pneumatic" (brake-pipe gas dynamics, relay valve, UIC '
              'distributors with reservoirs). In pneumatic, brake_pipe/pressure is the '
              'pressure the brake valve of the driver regulates the pipe head to.',
              choices=('empirical', 'pneumatic')),
    ParamSpec('brake_pipe_leakage', 0.0, DOUBLE,
              'Pneumatic: leakage of the brake pipe, as the pressure drop rate [Pa/s] of '
              'the lapped pipe at the running pressure, spread evenly along the train.',
              low=0.0, high=1.0e5),
    ParamSpec('angle_cock_closed', 0, INTEGER,
              'Pneumatic: coupling k (between vehicles k and k+1) whose angle cocks are '
              'closed, cutting the brake pipe; 0 = all open.', low=0, high=100000),
    ParamSpec('brake_pipe_diameter', 0.032, DOUBLE,
              'Pneumatic: inner diameter of the brake pipe [m] (EN 15355: 25-32 mm).',
              low=0.01, high=0.1),
    ParamSpec('main_reservoir_pressure', 900000.0, DOUBLE,
              'Pneumatic: main-reservoir pressure feeding the brake valve of the driver, gauge '
              '[Pa].', low=1.0e5, high=2.0e6),
    # Run metrics (issue 13, physics/metrics.py): a crossing is a WARN in /diagnostics.
    ParamSpec('coupler_force_limit', 0.0, DOUBLE,
              'Coupler force limit on abs(F) [N]: each excursion beyond it is a limit crossing '
              '(coupler, value, time) in the run metrics; 0 = off.',
              low=0.0, high=1.0e9, dynamic=True),
    ParamSpec('jerk_limit', 0.0, DOUBLE,
              'Jerk limit [m/s^3] on abs(jerk) of each vehicle, evaluated over 1 s windows '
              '(EN 12299 practice): each excursion is a limit crossing; 0 = off.',
              low=0.0, high=1000.0, dynamic=True),
    # Real trains (issue 11): consist, coupler travel, resistance, track, traction. Each
    # vehicle field of a consist (physics/consist.py) is also a parameter of the same name
    # (mass -> coach_mass, length -> coach_length): the value of the uniform train and the
    # default of a vehicle type that leaves it out. Defaults are the paper's idealisation.
    ParamSpec('consist_file', '', STRING,
              'YAML consist (vehicle_types, vehicles front to rear); empty = the uniform train '
              'of num_coaches/masses. Relative: to the parameter file, then config/.'),
    ParamSpec('rotating_mass_factor', 0.0, DOUBLE,
              'Rotating-mass allowance: the inertia of a vehicle is m (1 + factor).',
              low=0.0, high=2.0),
    ParamSpec('davis_a', 0.0, DOUBLE, 'Running resistance (Davis) constant term A [N].',
              low=0.0, high=1.0e6),
    ParamSpec('davis_b', 0.0, DOUBLE, 'Running resistance (Davis) B |v| term [N s/m].',
              low=0.0, high=1.0e6),
    ParamSpec('davis_c', 0.0, DOUBLE, 'Running resistance (Davis) C v^2 term [N s^2/m^2].',
              low=0.0, high=1.0e5),
    ParamSpec('buffer_stroke', 0.105, DOUBLE,
              'Buffer stroke S_c [m] before blocking (UIC 526-1: 105 mm).',
              low=0.0, high=10.0, low_exclusive=True),
    ParamSpec('draw_gear_stroke', 0.06, DOUBLE,
              'Draw-gear spring travel S_t [m] before blocking (UIC 520 draw gear, typical).',
              low=0.0, high=10.0, low_exclusive=True),
    ParamSpec('buffer_slack', 0.0, DOUBLE,
              'Free play g_c [m] before the buffers take load (0: tight screw coupling).',
              low=0.0, high=1.0),
    ParamSpec('draw_gear_slack', 0.0, DOUBLE,
              'Free play g_t [m] before the draw gear takes load (0: tight coupling).',
              low=0.0, high=1.0),
    ParamSpec('blocked_stiffness', 1.0e8, DOUBLE,
              'Stiffness K_b [N/m] once a buffer or draw gear is at the end of its stroke '
              '(vehicle underframe, ~1e8 N/m).', low=0.0, high=1.0e12, low_exclusive=True),
    ParamSpec('max_tractive_force', 0.0, DOUBLE,
              'Locomotive: starting tractive effort [N] (0: not a traction unit).',
              low=0.0, high=1.0e7),
    ParamSpec('max_power', 0.0, DOUBLE, 'Locomotive: power at the wheel rim in traction [W].',
              low=0.0, high=1.0e8),
    ParamSpec('max_dynamic_brake_force', 0.0, DOUBLE,
              'Locomotive: maximum dynamic (electric) braking force [N].', low=0.0, high=1.0e7),
    ParamSpec('max_dynamic_brake_power', 0.0, DOUBLE,
              'Locomotive: maximum dynamic braking power [W].', low=0.0, high=1.0e8),
    ParamSpec('traction_build_up_time', 4.0, DOUBLE,
              'Locomotive: time [s] for the tractive/dynamic-brake force to go from 0 to the '
              'full command (rate limit); 0 = immediate.', low=0.0, high=600.0),
    ParamSpec('traction_adhesion', 0.33, DOUBLE,
              'Locomotive: wheel-rail adhesion at standstill for traction and dynamic braking; '
              'falls with speed as Curtius-Kniffler.', low=0.0, high=1.0, low_exclusive=True),
    ParamSpec('dynamic_brake_fade_speed', 1.4, DOUBLE,
              'Locomotive: below this speed [m/s] the dynamic braking force fades linearly '
              'to 0.', low=0.0, high=50.0, low_exclusive=True),
    ParamSpec('initial_position', 0.0, DOUBLE,
              'Position along the track [m] of the front of vehicle 1 at t = 0.',
              low=-1.0e7, high=1.0e7),
    ParamSpec('track_gradient_positions', [], DOUBLE_ARRAY,
              'Track positions [m] (increasing) where a gradient starts; 0 before the first.',
              low=-1.0e7, high=1.0e7),
    ParamSpec('track_gradients', [], DOUBLE_ARRAY,
              'Gradient [per mille, > 0 uphill] from each track_gradient_positions entry on.',
              low=-100.0, high=100.0),
    ParamSpec('track_curve_starts', [], DOUBLE_ARRAY, 'Track positions [m] where curves start.',
              low=-1.0e7, high=1.0e7),
    ParamSpec('track_curve_ends', [], DOUBLE_ARRAY, 'Track positions [m] where curves end.',
              low=-1.0e7, high=1.0e7),
    ParamSpec('track_curve_radii', [], DOUBLE_ARRAY,
              'Curve radii [m]; Roeckl resistance 650/(R-55) per mille (R >= 300 m), '
              '500/(R-30) below.', low=100.0, high=1.0e6),
    ParamSpec('traction_schedule_times', [], DOUBLE_ARRAY,
              'Offline runs without a traction bag: times [s] (increasing) from which every '
              'locomotive holds the matching traction_schedule_commands entry.',
              low=0.0, high=1.0e7),
    ParamSpec('traction_schedule_commands', [], DOUBLE_ARRAY,
              'Traction command in [-1, 1] (> 0 traction, < 0 dynamic brake) from each '
              'traction_schedule_times entry on.', low=-1.0, high=1.0),
    # error-controlled stepping (issue 14)
    ParamSpec('integration_tolerance', INTEGRATION_TOLERANCE, DOUBLE,
              'Error-controlled integration: the local error of every coupler force per step, '
              'relative to the largest coupler force in the train (at least 1e-3 of a '
              "vehicle's weight) [-]; ROS2 with its embedded first-order estimate, PI step "
              'control, landing on every output instant. 0 = fixed step integration_step.',
              low=0.0, high=0.1),
    ParamSpec('integration_max_steps', 100, INTEGER,
              'Work budget of the error-controlled integration: steps per output period; '
              'beyond it the rest of the period runs at the fixed integration_step (counted '
              'in /diagnostics fallback_periods).', low=1, high=1000000),
]

PARAMETERS: dict[str, ParamSpec] = {p.name: p for p in _PARAMS}

#: ``sim_node``'s own parameters (not part of the simulator configuration; all live).
SIM_NODE_PARAMETERS: dict[str, ParamSpec] = {p.name: p for p in [
    ParamSpec('duration', 0.0, DOUBLE,
              'Simulation time [s] after which the node stops by itself (outputs up to and '
              'including t = duration); 0 = run until shut down.',
              low=0.0, high=1.0e9, dynamic=True),
    ParamSpec('wait_for_input', 0.0, DOUBLE,
              'Before the simulation clock starts (and after each reset), wait up to this many '
              'wall seconds until a publisher is connected to every brake-input topic of '
              'brake_input (the state stays at t = 0 meanwhile); 0 = start at once.',
              low=0.0, high=3600.0, dynamic=True),
    ParamSpec('record_flush_period', 10.0, DOUBLE,
              'Wall-clock period [s] at which the record_bag MCAP file is finished and a new '
              'one started: a SIGKILL loses at most this much of the recording.',
              low=0.1, high=3600.0, dynamic=True),
]}


class ConfigError(ValueError):
    """A parameter value or a parameter file that cannot be used; the message says why."""


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def validate_value(name: str, value: Any,
                   table: Mapping[str, ParamSpec] = PARAMETERS) -> Any:
    """
    Check one value of parameter ``name`` of ``table``; return it normalised.

    Integers become floats for doubles, arrays become lists. Raises :class:`ConfigError`
    with a one-line reason.
    """
    spec = table.get(name)
    if spec is None:
        raise ConfigError(f'unknown parameter {name!r}')
    kind = spec.kind
    if kind in (DOUBLE, INTEGER):
        return _check_number(spec, value, name)
    if kind == BOOL:
        if not isinstance(value, bool):
            raise ConfigError(f'{name}: expected true or false, got {value!r}')
        return value
    if kind == STRING:
        if not isinstance(value, str):
            raise ConfigError(f'{name}: expected a string, got {type(value).__name__} {value!r}')
        if spec.choices and value not in spec.choices:
            raise ConfigError(f'{name}: {value!r} is not one of {", ".join(spec.choices)}')
        return value
    if kind in ARRAY_KINDS:
        if isinstance(value, (str, bytes)) or not hasattr(value, '__iter__'):
            what = 'numbers' if kind == DOUBLE_ARRAY else 'strings'
            raise ConfigError(f'{name}: expected a list of {what}, got {value!r}')
        if kind == STRING_ARRAY:
            return [_check_string(item, f'{name}[{k}]') for k, item in enumerate(value)]
        return [_check_number(spec, item, f'{name}[{k}]') for k, item in enumerate(value)]
    raise AssertionError(kind)


def _check_string(value: Any, label: str) -> str:
    if not isinstance(value, str):
        raise ConfigError(f'{label}: expected a string, got {value!r}')
    return value


def _check_number(spec: ParamSpec, value: Any, label: str) -> float | int:
    """Check a number of ``spec`` (an element for a double array), range included."""
    if spec.kind == INTEGER:
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigError(f'{label}: expected an integer, got {type(value).__name__} '
                              f'{value!r}')
        value = int(value)
    elif not _is_number(value):
        if spec.kind == DOUBLE_ARRAY:
            raise ConfigError(f'{label}: expected a number, got {value!r}')
        raise ConfigError(f'{label}: expected a number, got {type(value).__name__} {value!r}')
    else:
        value = float(value)
    _check_range(spec, value, label)
    return value


def _check_range(spec: ParamSpec, value: float, label: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f'{label}: must be finite, got {value}')
    if spec.low is not None:
        if spec.low_exclusive and not value > spec.low:
            raise ConfigError(f'{label}: must be > {spec.low:g}, got {value:g}')
        if not spec.low_exclusive and not value >= spec.low:
            raise ConfigError(f'{label}: must be >= {spec.low:g}, got {value:g}')
    if spec.high is not None and not value <= spec.high:
        raise ConfigError(f'{label}: must be <= {spec.high:g}, got {value:g}')


# -- brake-input messages: the rejection rules of sim_node and of the offline replay ------------

#: why a brake-input pressure is not used (``sim_node`` counts them per reason)
INPUT_VALUE_REASONS = ('non_finite', 'negative', 'too_high')


def input_rejection(absolute: float) -> tuple[str, str] | None:
    """
    Return (reason, detail) if a brake-input ABSOLUTE pressure [Pa] is rejected, else None.

    The one rule for ``sim_node`` and the offline replay: ``non_finite`` (NaN, +-inf),
    ``negative`` (< 0), ``too_high`` (> :data:`train_dynamics.topics.MAX_ABSOLUTE_PRESSURE`).
    """
    p = float(absolute)
    if not math.isfinite(p):
        return 'non_finite', f'pressure {p}'
    if p < 0.0:
        return 'negative', f'absolute pressure {p:g} Pa < 0'
    if p > topics.MAX_ABSOLUTE_PRESSURE:
        return 'too_high', (f'absolute pressure {p:g} Pa > '
                            f'{topics.MAX_ABSOLUTE_PRESSURE:g} Pa')
    return None


#: why a traction command is not used (``sim_node`` counts them per reason)
TRACTION_VALUE_REASONS = ('non_finite', 'out_of_range')


def traction_rejection(command: float) -> tuple[str, str] | None:
    """
    Return (reason, detail) if a traction command is rejected, else None.

    The one rule for ``sim_node`` and the offline replay of ``coach_<i>/traction/command``
    (a fraction of the available force, > 0 traction, < 0 dynamic brake): ``non_finite``
    (NaN, +-inf), ``out_of_range`` (outside [-1, 1]).
    """
    c = float(command)
    if not math.isfinite(c):
        return 'non_finite', f'command {c}'
    if not -1.0 <= c <= 1.0:
        return 'out_of_range', f'command {c:g} outside [-1, 1]'
    return None


# -- what a run costs: memory of the simulator, disk of its outputs ---------------------------

#: [bytes] largest simulator state a configuration may need (delay line + per-coach arrays)
MAX_SIMULATOR_MEMORY = 1 << 30
#: [bytes] upper estimate of the simulator's arrays per coach: the kernel's packed rows
#: (state, coupler constants, workspace; from the layout) and 32 more float rows for the
#: per-vehicle vectors and the error-controlled stepping's tick buffers
SIMULATOR_BYTES_PER_COACH = 8 * (len(layout.COACH) + len(layout.COUPLER) + len(layout.WORK) + 32)
#: [bytes] the simulator's arrays whatever the train (cylinder tables, scalars)
SIMULATOR_FIXED_BYTES = 1 << 16
#: [bytes] MCAP record and index overhead per message (opcode, length, channel, sequence,
#: two times; message-index entry)
BAG_BYTES_PER_MESSAGE = 48
#: relative tolerance of ``1 / (publish_rate * integration_step)`` being a whole number
GRID_TOLERANCE = 1e-9
#: [bytes] a recorded head brake-pipe pressure (FluidPressure) per output instant
HEAD_INPUT_BYTES = 40 + BAG_BYTES_PER_MESSAGE


def delay_line_length(n_coaches: int, coach_length: float, speed: float, h: float) -> int:
    """Return the samples of the brake-pipe delay line: (N-1) L / c / h + 2 (train.py)."""
    return int(math.floor((n_coaches - 1) * coach_length / speed / h)) + 2


def simulator_memory(n_coaches: int, coach_length: float, speed: float, h: float) -> int:
    """Return an upper estimate [bytes] of the simulator's arrays."""
    return (8 * delay_line_length(n_coaches, coach_length, speed, h)
            + SIMULATOR_BYTES_PER_COACH * n_coaches + SIMULATOR_FIXED_BYTES)


def _joint_state_bytes(joints: int, name_len: int) -> int:
    """Return the CDR size [bytes] of a JointState of ``joints`` names of ~``name_len``."""
    name = 4 + (name_len + 1 + 3) // 4 * 4
    return 32 + joints * name + 3 * (8 + 8 * joints)


def output_bytes_per_sample(n_coaches: int) -> int:
    """Return the bag bytes of one output instant: couplers, coaches, brake_cylinders."""
    digits = len(str(n_coaches))
    msgs = (_joint_state_bytes(n_coaches - 1, 8 + digits)
            + 2 * _joint_state_bytes(n_coaches, 6 + digits))
    return msgs + 3 * BAG_BYTES_PER_MESSAGE


def output_disk(cfg: 'SimConfig', duration: float) -> int:
    """Return an estimate [bytes] of the bag of the outputs of ``duration`` [s] of ``cfg``."""
    samples = math.floor(duration * float(cfg.publish_rate) + 1e-9) + 1
    return int(samples * (output_bytes_per_sample(cfg.n_coaches) + HEAD_INPUT_BYTES))


def fmt_bytes(n: float) -> str:
    """Return ``n`` bytes in words: '3.8 MB', '64 TB'."""
    for unit in ('B', 'kB', 'MB', 'GB', 'TB', 'PB'):
        if abs(n) < 1000.0 or unit == 'PB':
            return f'{n:.3g} {unit}'
        n /= 1000.0
    raise AssertionError


def _check_output_grid(rate: float, h: float) -> None:
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


@dataclass
class SimConfig:
    """All parameters, validated as a whole. Build with :meth:`from_dict`."""

    values: dict[str, Any] = field(default_factory=lambda: {
        n: (list(s.default) if isinstance(s.default, list) else s.default)
        for n, s in PARAMETERS.items()})

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__['values'][name]
        except KeyError:
            raise AttributeError(name) from None

    @classmethod
    def from_dict(cls, overrides: dict[str, Any] | None = None, *,
                  ignore_unknown: bool = False) -> 'SimConfig':
        cfg = cls()
        for name, value in (overrides or {}).items():
            if name not in PARAMETERS:
                if ignore_unknown:
                    continue
                raise ConfigError(f'unknown parameter {name!r}')
            cfg.values[name] = validate_value(name, value)
        cfg.check()
        return cfg

    def replace(self, **changes: Any) -> 'SimConfig':
        merged = dict(self.values)
        merged.update(changes)
        return SimConfig.from_dict(merged)

    # -- derived quantities -------------------------------------------------------------
    @property
    def n_coaches(self) -> int:
        if self.consist_file:
            return self.consist.n
        return len(self.masses) if self.masses else int(self.num_coaches)

    @property
    def mass_array(self) -> list[float]:
        if self.consist_file:
            return [float(m) for m in self.consist['mass']]
        if self.masses:
            return list(self.masses)
        return [float(self.coach_mass)] * int(self.num_coaches)

    @property
    def consist(self):
        """Return the train's :class:`~train_dynamics.physics.consist.Consist` (cached)."""
        cached = self.__dict__.get('_consist')
        if cached is None or cached[0] != self.values:
            cached = (dict(self.values), consist.consist_of(self.values))
            self.__dict__['_consist'] = cached
        return cached[1]

    @property
    def external_forces(self) -> bool:
        """Return True when the train has resistance, gradients, curves or traction."""
        v = self.values
        if v['consist_file'] or v['davis_a'] or v['davis_b'] or v['davis_c']:
            return True
        return bool(v['track_gradients'] or v['track_curve_starts']
                    or v['max_tractive_force'] or v['max_dynamic_brake_force'])

    @property
    def track(self):
        """Return the line (:class:`~train_dynamics.physics.track.Track`) of the parameters."""
        v = self.values
        return track.Track.from_lists(v['initial_position'], v['track_gradient_positions'],
                                      v['track_gradients'], v['track_curve_starts'],
                                      v['track_curve_ends'], v['track_curve_radii'])

    def fill_table(self) -> tuple[list[float], list[float]]:
        if self.cylinder_fill_time:
            return list(self.cylinder_fill_time), list(self.cylinder_fill_fraction)
        times = P_FILL_TIME if self.brake_regime == 'P' else G_FILL_TIME
        return list(times), list(P_FILL_FRACTION)

    def release_table(self) -> tuple[list[float], list[float]]:
        if self.cylinder_release_time:
            return list(self.cylinder_release_time), list(self.cylinder_release_fraction)
        times = P_RELEASE_TIME if self.brake_regime == 'P' else G_RELEASE_TIME
        return list(times), list(P_RELEASE_FRACTION)

    def check(self) -> None:
        """Cross-parameter checks; raises :class:`ConfigError`."""
        v = self.values
        self._check_real_train()
        if self.masses and len(self.masses) < 2:
            raise ConfigError(f'masses: a train needs at least 2 coaches, got {len(self.masses)}')
        _check_output_grid(float(v['publish_rate']), float(v['integration_step']))
        memory = simulator_memory(self.n_coaches, float(v['coach_length']),
                                  float(v['brake_propagation_speed']),
                                  float(v['integration_step']))
        if memory > MAX_SIMULATOR_MEMORY:
            raise ConfigError(
                f'the simulator would need {fmt_bytes(memory)} (limit '
                f'{fmt_bytes(MAX_SIMULATOR_MEMORY)}): the brake-pipe delay line holds '
                '(num_coaches - 1) * coach_length / brake_propagation_speed / integration_step '
                'samples; raise brake_propagation_speed or integration_step, or shorten the train')
        if not v['buffer_friction'] < v['buffer_stiffness']:
            raise ConfigError('buffer_friction must be < buffer_stiffness (k_f < k_e), or the '
                              'buffer force would change sign on unloading')
        if not v['draw_gear_friction'] < v['draw_gear_stiffness']:
            raise ConfigError('draw_gear_friction must be < draw_gear_stiffness (k_fc < k_ec)')
        if not (v['full_service_pressure'] + v['distributor_sensitivity']
                < v['pipe_nominal_pressure']):
            raise ConfigError('full_service_pressure + distributor_sensitivity must be below '
                              'pipe_nominal_pressure')
        if v['angle_cock_closed'] > self.n_coaches - 1:
            raise ConfigError(f'angle_cock_closed: the couplings are 1..{self.n_coaches - 1} '
                              f'(0 = none), got {v["angle_cock_closed"]}')
        if (v['brake_model'] == 'pneumatic'
                and v['main_reservoir_pressure'] <= v['pipe_nominal_pressure']):
            raise ConfigError('main_reservoir_pressure must be above pipe_nominal_pressure')
        for kind in ('fill', 'release'):
            t_name, f_name = f'cylinder_{kind}_time', f'cylinder_{kind}_fraction'
            times, fracs = v[t_name], v[f_name]
            if len(times) != len(fracs):
                raise ConfigError(f'{t_name} and {f_name} must have the same length '
                                  f'({len(times)} != {len(fracs)})')
            if not times:
                continue
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
        """Check the track, the traction schedule and the consist file (issue 11)."""
        v = self.values
        try:
            self.track
        except ValueError as exc:
            raise ConfigError(str(exc)) from None
        times, cmds = v['traction_schedule_times'], v['traction_schedule_commands']
        if len(times) != len(cmds):
            raise ConfigError('traction_schedule_times and traction_schedule_commands must have '
                              f'the same length ({len(times)} != {len(cmds)})')
        if any(b <= a for a, b in zip(times, times[1:])):
            raise ConfigError('traction_schedule_times: must strictly increase')
        if v['consist_file']:
            self.consist


class _RosParamLoader(yaml.SafeLoader):
    """
    A safe YAML loader that reads 2.8e6 and 1e-3 as floats, as ROS 2's parser does.

    PyYAML's YAML 1.1 rules would read them as strings.
    """


_RosParamLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$'),
    list('-+0123456789'))


#: parameters every ROS 2 node has; a parameter file may set them, the model ignores them
ROS_BUILTIN_PARAMETERS = ('use_sim_time', 'start_type_description_service')


#: node names whose sections a parameter file of this package may hold ('/**': every node)
KNOWN_NODE_NAMES = (topics.NODE_NAME, topics.VALVE_NODE_NAME)
WILDCARD = '/**'


def section_node(key: str) -> str:
    """Return the node name of a parameter-file section: '/ns/node' -> 'node'."""
    return key.rstrip('/').split('/')[-1]


def read_param_sections(path: str) -> dict[str, dict[str, Any]]:
    """
    Return ``{section: ros__parameters}`` of a ROS 2 parameter file, in file order.

    Raises :class:`ConfigError` (one line) for a missing, unreadable or malformed file: what
    rclpy would refuse with an ``RCLError``.
    """
    try:
        with open(path, encoding='utf-8') as fh:
            doc = yaml.load(fh, Loader=_RosParamLoader)
    except FileNotFoundError:
        raise ConfigError(f'parameter file not found: {path}') from None
    except IsADirectoryError:
        raise ConfigError(f'parameter file {path} is a directory') from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ConfigError(' '.join(f'cannot read parameter file {path}: {exc}'.split())
                          ) from None
    if doc is None:
        return {}
    if not isinstance(doc, dict):
        raise ConfigError(f'{path}: not a ROS 2 parameter file (top level is not a mapping)')
    sections: dict[str, dict[str, Any]] = {}
    for key, section in doc.items():
        if not isinstance(key, str):
            raise ConfigError(f'{path}: section name {key!r} is not a node name')
        if not isinstance(section, dict) or 'ros__parameters' not in section:
            raise ConfigError(f'{path}: section {key!r} has no ros__parameters')
        params = section['ros__parameters'] or {}
        if not isinstance(params, dict):
            raise ConfigError(f'{path}: {key}.ros__parameters is not a mapping')
        sections[key] = params
    return sections


def unknown_sections(sections: Mapping[str, Any],
                     known: tuple[str, ...] = KNOWN_NODE_NAMES) -> list[str]:
    """Return the sections that apply to none of the ``known`` nodes (e.g. a typo)."""
    return [k for k in sections if k != WILDCARD and section_node(k) not in known]


def unknown_sections_message(path: str, unknown: list[str]) -> str:
    """Return the one-line warning about sections for no node of this package."""
    return (f'{path}: section(s) {", ".join(repr(k) for k in unknown)} match no node of this '
            f'package and are ignored (known: {", ".join(KNOWN_NODE_NAMES)}, {WILDCARD})')


def node_sections(sections: Mapping[str, dict[str, Any]], node_name: str
                  ) -> tuple[dict[str, Any], dict[str, Any]]:
    """
    Return (the ``/**`` parameters, the node's own) of ``sections`` for ``node_name``.

    Own: the sections ``node``, ``/node`` and ``/ns/node``, later ones winning.
    """
    own: dict[str, Any] = {}
    for key, params in sections.items():
        if key != WILDCARD and section_node(key) == node_name:
            own.update(params)
    return dict(sections.get(WILDCARD, {})), own


def read_param_file(path: str, node_name: str = 'train_dynamics') -> dict[str, Any]:
    """
    Read the ``ros__parameters`` of ``node_name`` from a ROS 2 parameter file.

    Accepts the node's own key, ``/node``, a namespaced ``/ns/node`` and the ``/**``
    wildcard (more specific sections win). Returns ``{}`` when the node has no section.
    Raises :class:`ConfigError` for a missing or malformed file.
    """
    wildcard, own = node_sections(read_param_sections(path), node_name)
    return {**wildcard, **own}


def load_param_file(path: str, warn: Callable[[str], None] | None = None) -> SimConfig:
    """
    Read the simulator configuration from a ROS 2 parameter file (``train_dynamics``).

    As rclpy does for the node: keys of the ``/**`` section that the simulator does not
    declare are ignored (they may be the brake valve's). Unlike rclpy, an unknown key of the
    node's own section is an error, and so is a file whose only sections match no node of
    this package (a typo such as ``train_dynamic:``); other unknown sections are reported
    through ``warn``.
    """
    sections = read_param_sections(path)
    unknown = unknown_sections(sections)
    wildcard, own = node_sections(sections, topics.NODE_NAME)
    if unknown:
        if len(unknown) == len(sections):
            raise ConfigError(
                f'{path}: no section for {topics.NODE_NAME}, only '
                f'{", ".join(repr(k) for k in unknown)} (known: {", ".join(KNOWN_NODE_NAMES)}, '
                f'{WILDCARD}); a typo?')
        if warn is not None:
            warn(unknown_sections_message(path, unknown))
    params = {k: v for k, v in wildcard.items() if k in PARAMETERS}
    params.update({k: v for k, v in own.items() if k not in ROS_BUILTIN_PARAMETERS})
    name = params.get('consist_file')
    if isinstance(name, str) and name and not os.path.isabs(os.path.expanduser(name)):
        local = os.path.join(os.path.dirname(os.path.abspath(path)), name)
        if os.path.isfile(local):        # relative to the parameter file, then config/
            params['consist_file'] = local
    try:
        return SimConfig.from_dict(params)
    except ConfigError as exc:
        raise ConfigError(f'{path}: {exc}') from None


def _fmt_default(v: Any) -> str:
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, str):
        return '`""`' if v == '' else f'`{v}`'
    if isinstance(v, list):
        return '`[]`' if not v else f'`{v!r}`'
    if isinstance(v, float):
        return f'{v:g}'
    return str(v)


def _fmt_range(s: ParamSpec) -> str:
    if s.choices:
        return ', '.join(f'`{c}`' for c in s.choices)
    parts = []
    if s.low is not None:
        parts.append(('> ' if s.low_exclusive else '>= ') + f'{s.low:g}')
    if s.high is not None:
        parts.append(f'<= {s.high:g}')
    return ', '.join(parts)


def markdown_table() -> str:
    """Return the README's parameter table, generated from :data:`PARAMETERS`."""
    lines = ['| name | type | default | range | when | meaning |',
             '| --- | --- | --- | --- | --- | --- |']
    for s in PARAMETERS.values():
        when = 'live' if s.dynamic else 'reset'
        meaning = s.description.replace('|', '/')
        lines.append(f'| `{s.name}` | {s.kind} | {_fmt_default(s.default)} | {_fmt_range(s)} '
                     f'| {when} | {meaning} |')
    return '\n'.join(lines)


if __name__ == '__main__':   # python -m train_dynamics.physics.parameters: the README table
    print(markdown_table())
