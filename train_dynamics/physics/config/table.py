"""
The simulator's parameter table :data:`PARAMETERS`, and ``sim_node``'s own parameters.

Every parameter of the product contract is declared once here, with its default, type, unit,
range and whether it may change while the simulation runs; ``sim_node`` and the offline
command share the table, the docs' parameter table is generated from it
(:mod:`~train_dynamics.physics.config.docs`). The per-vehicle fields of a consist are the
entries with ``vehicle`` set (:data:`VEHICLE_PARAMETERS`): name in a consist file, unit, range,
default, connection rule and kernel row (:data:`KERNEL_ROWS`) in one place. Pressures in
parameters are GAUGE pressures [Pa], except :data:`ATMOSPHERIC_PRESSURE`.
"""
from __future__ import annotations

from typing import Any, Mapping

from train_dynamics.physics.config.blending_params import BLENDING_PARAMS
from train_dynamics.physics.config.integrator import (ADAPTIVE_TOLERANCE, DEFAULT_INTEGRATOR,
                                                      INTEGRATORS)
from train_dynamics.physics.config.spec import (ADDED, BOOL, check_value, ConfigError, DOUBLE,
                                                DOUBLE_ARRAY, EQUAL_FORCE, INTEGER, ParamSpec,
                                                SERIES, STRING)
from train_dynamics.physics.config.table_ends import END_AND_RESISTANCE_PARAMS
from train_dynamics.physics.pneumatic import INSHOT_PRESSURE
from train_dynamics.quoting import quote

# Pressure defaults, written once (used by the simulator and the brake valve).
ATMOSPHERIC_PRESSURE = 101325.0    # [Pa absolute]: FluidPressure (absolute) = gauge + this
PIPE_NOMINAL_PRESSURE = 500000.0   # [Pa gauge] brake-pipe running pressure (UIC: 5 bar)
FULL_SERVICE_PRESSURE = 350000.0   # [Pa gauge] brake pipe at full service (UIC: 3.5 bar)


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

#: default integration_tolerance: 0 = unset (no error control unless integrator adaptive)
INTEGRATION_TOLERANCE = 0.0
#: default multirate_tolerance and multirate_reversal_weight: every coupler-force and
#: displacement sample within 2 % of the independent reference's peak on the four accuracy
#: cases and on 1000 of the paper's coaches, within 0.1 % on the paper's scenario
#: (bench/results/accuracy_results.md: force 0.090 / 0.303 / 0.253 / 0.88 %, displacement 0.053 /
#: 0.031 / 0.039 / 0.11 % on paper / khz_unequal / mixed_freeplay / paper30; 1000 coaches
#: 0.086 %; the fixed 2 ms step alone 0.256 / 50.1 / 14.8 / 6.57 %), but not on 100 coaches
#: (11.6 %, a few late friction reversals). 3e-4 meets that too (1.49 %) at about twice the
#: cost, which put sim_node's p99 output jitter with 300 vehicles at 100 Hz over 2 ms
#: (1.84-2.05 ms in three runs; 0.48 ms at 1e-3): the real-time node keeps 1e-3.
MULTIRATE_TOLERANCE = 1.0e-3
MULTIRATE_REVERSAL_WEIGHT = 1.0

#: the most vehicles of a train, however given (num_coaches, masses, a consist file's counts)
MAX_VEHICLES = 100_000

_PARAMS = [
    ParamSpec('model_type', 'tanh', STRING,
              'Coupler friction law: "tanh" uses tanh(u*ydot) (paper eqs. 14-16), '
              '"sign" uses sgn(ydot) (paper eqs. 2-3).',
              choices=('tanh', 'sign'), dynamic=True),
    ParamSpec('scale_factor', 1000.0, DOUBLE,
              'u in tanh(u*ydot) [s/m], > 0 (paper eq. 14).',
              low=0.0, high=1.0e7, low_exclusive=True, dynamic=True),
    ParamSpec('num_coaches', 3, INTEGER, 'Number of coaches N >= 2 (ignored when masses is set).',
              low=2, high=MAX_VEHICLES),
    ParamSpec('coach_mass', 45000.0, DOUBLE,
              'Mass of every coach m_i [kg], unless masses is set. Bounds: a track trolley '
              '(~0.5 t) to a loaded heavy-load wagon (~800 t).', low=500.0, high=1.0e6,
              vehicle='mass'),
    ParamSpec('masses', [], DOUBLE_ARRAY,
              'Per-coach masses [kg], front to rear; non-empty overrides num_coaches and '
              'coach_mass. Bounds as coach_mass; at most as many values as num_coaches allows.',
              low=500.0, high=1.0e6, max_items=MAX_VEHICLES),
    ParamSpec('coach_length', 25.0, DOUBLE,
              'Coach length [m]: brake-pipe length per coach. Bounds: a trolley (1 m) to '
              'twice the longest rail vehicles (~50 m).', low=1.0, high=100.0, vehicle='length',
              row='LENGTH'),
    ParamSpec('buffer_stiffness', 2.8e6, DOUBLE,
              'Buffer stiffness k_e [N/m] (paper eq. 2). Real buffers: 0.5-50 MN/m; the '
              'bounds allow two decades either side.', low=1.0e4, high=1.0e10,
              vehicle='buffer_stiffness', connection=SERIES),
    ParamSpec('buffer_friction', 1.4e6, DOUBLE,
              'Buffer friction constant k_f [N/m] (paper eq. 2), 0 <= k_f < k_e.',
              low=0.0, high=1.0e10, vehicle='buffer_friction', connection=SERIES),
    ParamSpec('draw_gear_stiffness', 5.46e6, DOUBLE,
              'Draw-gear stiffness k_ec [N/m] (paper eq. 3). Bounds as buffer_stiffness.',
              low=1.0e4, high=1.0e10, vehicle='draw_gear_stiffness', connection=SERIES),
    ParamSpec('draw_gear_friction', 2.43e6, DOUBLE,
              'Draw-gear friction constant k_fc [N/m] (paper eq. 3), 0 <= k_fc < k_ec.',
              low=0.0, high=1.0e10, vehicle='draw_gear_friction', connection=SERIES),
    ParamSpec('adhesion_coefficient', 0.1, DOUBLE,
              'Wheel-rail adhesion coefficient mu_a (paper eqs. 12-13): full braking force '
              'is mu_a*m*g per coach.', low=0.0, high=1.0, low_exclusive=True,
              vehicle='adhesion_coefficient'),
    ParamSpec('gravity', 9.81, DOUBLE,
              'Gravitational acceleration g [m/s^2]. Bounds: the Moon (1.6) to Jupiter '
              '(24.8), rounded.', low=1.0, high=30.0),
    ParamSpec('max_cylinder_pressure', 380000.0, DOUBLE,
              'Maximum brake-cylinder pressure p_max, gauge [Pa] (paper eq. 13). Bounds: '
              '0.1 bar to the 20 bar input limit.', low=1.0e4, high=2.0e6,
              vehicle='max_cylinder_pressure'),
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
              choices=('P', 'G'), vehicle='brake_regime'),
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
    # Node behaviour on stale inputs.
    ParamSpec('input_timeout', 0.0, DOUBLE,
              'Seconds (wall) without any brake input before it is reported stale; 0 = never.',
              low=0.0, high=3600.0, dynamic=True),
    ParamSpec('on_input_timeout', 'hold', STRING,
              'On a stale input: "hold" the last value or apply an "emergency" brake.',
              choices=('hold', 'emergency'), dynamic=True),
    # Pneumatic brake (physics/pneumatic.py, README "Pneumatic brake").
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
              'closed, cutting the brake pipe; 0 = all open.', low=0, high=MAX_VEHICLES),
    ParamSpec('brake_pipe_diameter', 0.032, DOUBLE,
              'Pneumatic: inner diameter of the brake pipe [m] (EN 15355: 25-32 mm).',
              low=0.01, high=0.1),
    ParamSpec('main_reservoir_pressure', 900000.0, DOUBLE,
              'Pneumatic: main-reservoir pressure feeding the brake valve of the driver, gauge '
              '[Pa].', low=1.0e5, high=2.0e6),
    ParamSpec('brake_system', 'pneumatic', STRING,
              'Pneumatic: "pneumatic" (UIC distributors), "ep" (EP valves at every vehicle '
              'follow brake_ep/command after 0.2 s, pipe kept charged; a lost train line '
              'brakes through the pipe) or "ecp" (car control devices fill each cylinder to '
              'brake_ep/command x p_max; a lost train line or pipe is a full penalty '
              'application).', choices=('pneumatic', 'ep', 'ecp')),
    ParamSpec('emergency_accelerator', True, BOOL,
              'Pneumatic: the vehicle has an emergency accelerator (a pipe falling more than '
              '1 bar below its control reservoir at over 1 bar/s opens a 25 mm local vent: '
              'the emergency carries along the train at >= 250 m/s, as UIC 540 asks). On by '
              'default: UIC passenger and freight distributors carry one in service; false '
              'for a vehicle without.', vehicle='emergency_accelerator'),
    # Cylinders and distributor first stage of the pneumatic brake (physics/pneumatic.py).
    ParamSpec('inshot_pressure', INSHOT_PRESSURE, DOUBLE,
              'Pneumatic: distributor first stage (inshot; UIC 540 / EN 15355 "first stage" of '
              'the cylinder pressure): an applied distributor fills its cylinder through an '
              'extra port up to this gauge pressure [Pa] (rigging slack taken up quickly, '
              'typically 0.4-0.7 bar; the UIC fill times are calibrated with 0.4 bar); 0 = '
              'none.',
              low=0.0, high=2.0e5, vehicle='inshot_pressure'),
    ParamSpec('cylinder_dead_volume', 0.008, DOUBLE,
              'Pneumatic: volume of the brake cylinders of the vehicle with the pistons '
              'released [m^3] (clearance and pipes; with piston_stroke 0 the whole, fixed, '
              'cylinder volume the UIC fill times were calibrated with).',
              low=1.0e-4, high=0.2, vehicle='cylinder_dead_volume'),
    ParamSpec('piston_stroke', 0.0, DOUBLE,
              'Pneumatic: piston stroke [m]: the pistons (brake_cylinders x '
              'brake_cylinder_area) travel out at the return-spring pressure '
              'brake_spring_force / brake_cylinder_area, adding brake_cylinders x '
              'brake_cylinder_area x piston_stroke to the dead volume; needs '
              'brake_cylinder_area > 0. 0 = a fixed volume.',
              low=0.0, high=0.5, vehicle='piston_stroke'),
    ParamSpec('remote', False, BOOL,
              'Pneumatic, consist field: a distributed-power locomotive, its brake valve on the '
              'pipe at its position and its traction following the lead over the radio; the '
              'uniform train (no consist_file) has none.', vehicle='remote'),
    ParamSpec('radio_delay', 0.5, DOUBLE,
              "Pneumatic, distributed power: radio delay [s] of the lead's brake and traction "
              'commands to the remote locomotives (consist field remote).', low=0.0, high=60.0),
    ParamSpec('radio_loss', 0.0, DOUBLE,
              'Pneumatic, distributed power: probability that a radio message is lost; the '
              'lead repeats its state every 0.5 s, a remote without a message for 2 s idles '
              'its traction and laps its brake valve.', low=0.0, high=1.0),
    # Run metrics (physics/metrics.py): a crossing is a WARN in /diagnostics.
    ParamSpec('coupler_force_limit', 0.0, DOUBLE,
              'Coupler force limit on abs(F) [N]: each excursion beyond it is a limit crossing '
              '(coupler, value, time) in the run metrics; 0 = off.',
              low=0.0, high=1.0e9, dynamic=True),
    ParamSpec('jerk_limit', 0.0, DOUBLE,
              'Jerk limit [m/s^3] on abs(jerk) of each vehicle, evaluated over 1 s windows '
              '(EN 12299 practice): each excursion is a limit crossing; 0 = off.',
              low=0.0, high=1000.0, dynamic=True),
    # Real trains: consist, coupler travel, resistance, track, traction. A parameter with
    # ``vehicle`` set is also a field of a consist's vehicles (config/consist.py; mass is
    # coach_mass, length is coach_length): the value of the uniform train and the default of a
    # vehicle type that leaves it out. Defaults are the paper's idealisation.
    ParamSpec('consist_file', '', STRING,
              'YAML consist (vehicle_types, vehicles front to rear); empty = the uniform train '
              'of num_coaches/masses. Relative: to the folder of the parameter file that sets '
              'it, else to the current directory; then config/.',
              file_input=True),
    ParamSpec('rotating_mass_factor', 0.0, DOUBLE,
              'Rotating-mass allowance: the inertia of a vehicle is m (1 + factor).',
              low=0.0, high=2.0, vehicle='rotating_mass_factor'),
    ParamSpec('davis_a', 0.0, DOUBLE, 'Running resistance (Davis) constant term A [N].',
              low=0.0, high=1.0e6, vehicle='davis_a', row='DAVIS_A'),
    ParamSpec('davis_b', 0.0, DOUBLE, 'Running resistance (Davis) B |v| term [N s/m].',
              low=0.0, high=1.0e6, vehicle='davis_b', row='DAVIS_B'),
    ParamSpec('davis_c', 0.0, DOUBLE, 'Running resistance (Davis) C v^2 term [N s^2/m^2].',
              low=0.0, high=1.0e5, vehicle='davis_c', row='DAVIS_C'),
    ParamSpec('buffer_stroke', 0.105, DOUBLE,
              'Buffer stroke S_c [m] before blocking (UIC 526-1: 105 mm).',
              low=0.0, high=10.0, low_exclusive=True,
              vehicle='buffer_stroke', connection=ADDED),
    ParamSpec('draw_gear_stroke', 0.06, DOUBLE,
              'Draw-gear spring travel S_t [m] before blocking (UIC 520 draw gear, typical).',
              low=0.0, high=10.0, low_exclusive=True,
              vehicle='draw_gear_stroke', connection=ADDED),
    ParamSpec('buffer_slack', 0.0, DOUBLE,
              'Free play g_c [m] before the buffers take load (0: tight screw coupling).',
              low=0.0, high=1.0, vehicle='buffer_slack', connection=ADDED),
    ParamSpec('draw_gear_slack', 0.0, DOUBLE,
              'Free play g_t [m] before the draw gear takes load (0: tight coupling).',
              low=0.0, high=1.0, vehicle='draw_gear_slack', connection=ADDED),
    ParamSpec('blocked_stiffness', 1.0e8, DOUBLE,
              'Stiffness K_b [N/m] once a buffer or draw gear is at the end of its stroke '
              '(vehicle underframe, ~1e8 N/m).', low=0.0, high=1.0e12, low_exclusive=True,
              vehicle='blocked_stiffness', connection=SERIES),
    # Preloaded and progressive ends (physics/characteristics.py end_loading): the datasheet
    # figures of a buffer (EN 15551) or draw gear; all 0: the paper's linear law.
    ParamSpec('buffer_preload', 0.0, DOUBLE,
              'Buffer preload P [N]: the force below which the buffer does not move (its '
              'spring is pre-compressed); 0 = none.', low=0.0, high=1.0e7,
              vehicle='buffer_preload', connection=EQUAL_FORCE),
    ParamSpec('draw_gear_preload', 0.0, DOUBLE,
              'Draw-gear preload [N] (as buffer_preload).', low=0.0, high=1.0e7,
              vehicle='draw_gear_preload', connection=EQUAL_FORCE),
    ParamSpec('buffer_final_force', 0.0, DOUBLE,
              'Buffer final force F_f [N] at the end of the stroke on the loading branch '
              '(datasheet); 0 = the linear law of buffer_stiffness and buffer_friction.',
              low=0.0, high=1.0e8, vehicle='buffer_final_force', connection=EQUAL_FORCE),
    ParamSpec('draw_gear_final_force', 0.0, DOUBLE,
              'Draw-gear final force [N] (as buffer_final_force).', low=0.0, high=1.0e8,
              vehicle='draw_gear_final_force', connection=EQUAL_FORCE),
    ParamSpec('buffer_energy', 0.0, DOUBLE,
              'Energy W [J] the buffer absorbs on loading to its stroke (datasheet, EN 15551 '
              'category); with buffer_final_force it sets the progression, L = P + (F_f - P) '
              'x^q; 0 = linear from the preload to the final force.', low=0.0, high=1.0e7,
              vehicle='buffer_energy', connection=ADDED),
    ParamSpec('draw_gear_energy', 0.0, DOUBLE,
              'Energy [J] the draw gear absorbs to its stroke (as buffer_energy).', low=0.0,
              high=1.0e7, vehicle='draw_gear_energy', connection=ADDED),
    ParamSpec('max_tractive_force', 0.0, DOUBLE,
              'Locomotive: starting tractive effort [N] (0: not a traction unit).',
              low=0.0, high=1.0e7, vehicle='max_tractive_force', row='T_FORCE'),
    ParamSpec('max_power', 0.0, DOUBLE, 'Locomotive: power at the wheel rim in traction [W].',
              low=0.0, high=1.0e8, vehicle='max_power', row='T_POWER'),
    ParamSpec('max_dynamic_brake_force', 0.0, DOUBLE,
              'Locomotive: maximum dynamic (electric) braking force [N].', low=0.0, high=1.0e7,
              vehicle='max_dynamic_brake_force', row='DB_FORCE'),
    ParamSpec('max_dynamic_brake_power', 0.0, DOUBLE,
              'Locomotive: maximum dynamic braking power [W].', low=0.0, high=1.0e8,
              vehicle='max_dynamic_brake_power', row='DB_POWER'),
    ParamSpec('traction_build_up_time', 4.0, DOUBLE,
              'Locomotive: time [s] for the tractive/dynamic-brake force to go from 0 to the '
              'full command (rate limit); 0 = immediate.', low=0.0, high=600.0,
              vehicle='traction_build_up_time', row='T_BUILD'),
    ParamSpec('traction_adhesion', 0.33, DOUBLE,
              'Locomotive: wheel-rail adhesion at standstill for traction and dynamic braking; '
              'falls with speed as Curtius-Kniffler.', low=0.0, high=1.0, low_exclusive=True,
              vehicle='traction_adhesion', row='T_ADH'),
    ParamSpec('dynamic_brake_fade_speed', 1.4, DOUBLE,
              'Locomotive: below this speed [m/s] the dynamic braking force fades linearly '
              'to 0.', low=0.0, high=50.0, low_exclusive=True,
              vehicle='dynamic_brake_fade_speed', row='DB_FADE'),
    ParamSpec('initial_state', 'equilibrium', STRING,
              'The couplers at t = 0: "equilibrium" (the quasi-static deflections that balance '
              'gradient, curve, resistance and traction at t = 0, free play included: a steady '
              'run stays steady) or "unstressed" (every coupler at y = 0, the paper\'s start).',
              choices=('equilibrium', 'unstressed')),
    # Friction brakes (physics/friction.py): the material and one of two routes to the force
    # level, the EN 14531-1 force chain (cylinder area and rigging ratio) or the braked mass
    # of the vehicle's regime (UIC 544-1). Ignored for paper (eq. 13).
    ParamSpec('friction_material', 'paper', STRING,
              'Friction material of the brakes: paper (eq. 13 with the adhesion coefficient, '
              'as in the paper) or a friction law of the friction_materials: of the vehicle '
              'library or a consist file (physics/friction_laws.py): shipped cast_iron '
              '(Karwatzki: falls with speed and block force), composite_k, composite_ll '
              '(composition blocks), disc (pads on discs).',
              vehicle='friction_material', row='MATERIAL'),
    ParamSpec('brake_cylinder_area', 0.0, DOUBLE,
              'Force chain: piston area of one brake cylinder [m^2] (a 10 inch cylinder: '
              '0.0507); 0 = no force chain (braked mass instead).', low=0.0, high=1.0,
              vehicle='brake_cylinder_area'),
    ParamSpec('brake_cylinders', 1.0, DOUBLE,
              'Force chain: number of brake cylinders of the vehicle.', low=1.0, high=64.0,
              vehicle='brake_cylinders'),
    ParamSpec('brake_cylinder_efficiency', 0.95, DOUBLE,
              'Force chain: cylinder efficiency eta_c [-] (EN 14531-1; seals: ~0.95).',
              low=0.0, high=1.0, low_exclusive=True, vehicle='brake_cylinder_efficiency'),
    ParamSpec('brake_spring_force', 0.0, DOUBLE,
              'Force chain: return-spring force of one cylinder [N] (subtracted from the '
              'piston force).', low=0.0, high=1.0e5, vehicle='brake_spring_force'),
    ParamSpec('rigging_ratio', 0.0, DOUBLE,
              'Force chain: brake rigging (lever) ratio i [-] from piston to all blocks or '
              'pads of one cylinder; 0 = no force chain.', low=0.0, high=100.0,
              vehicle='rigging_ratio'),
    ParamSpec('rigging_efficiency', 0.83, DOUBLE,
              'Force chain: rigging efficiency eta_r [-] (EN 14531-1 tread rigging: '
              '~0.83; disc units ~0.95).', low=0.0, high=1.0, low_exclusive=True,
              vehicle='rigging_efficiency'),
    ParamSpec('brake_blocks', 8.0, DOUBLE,
              'Number of blocks (tread) or pads (disc) sharing the normal force: the block '
              'force of the cast-iron law.', low=1.0, high=256.0, vehicle='brake_blocks',
              row='BLOCKS'),
    ParamSpec('brake_radius_ratio', 1.0, DOUBLE,
              'Radius ratio rho [-]: 1 for tread brakes; disc: effective friction radius '
              'over wheel radius (~0.25 / 0.46).', low=0.0, high=2.0, low_exclusive=True,
              vehicle='brake_radius_ratio', row='RHO'),
    ParamSpec('braked_mass_p', 0.0, DOUBLE,
              'Braked mass [kg] in regime P (the braked weight on the vehicle label, UIC '
              '544-1); sets the force level when there is no force chain; 0 = not given.',
              low=0.0, high=1.0e6, vehicle='braked_mass_p'),
    ParamSpec('braked_mass_g', 0.0, DOUBLE,
              'Braked mass [kg] in regime G (as braked_mass_p).', low=0.0, high=1.0e6,
              vehicle='braked_mass_g'),
    ParamSpec('load_empty_mass', 0.0, DOUBLE,
              'Load-weighing: mass of the empty vehicle [kg]; 0 = no load-weighing (the '
              'force level is the loaded one). The actual mass is the mass of the vehicle.',
              low=0.0, high=1.0e6, vehicle='load_empty_mass'),
    ParamSpec('load_full_mass', 0.0, DOUBLE,
              'Load-weighing: mass [kg] from which the loaded force level applies (the '
              'force chain or braked mass give the loaded level).', low=0.0, high=1.0e6,
              vehicle='load_full_mass'),
    ParamSpec('load_changeover_mass', 0.0, DOUBLE,
              'Load-weighing: empty/loaded changeover at this mass [kg]; 0 = a continuous '
              'load-proportional valve between load_empty_mass and load_full_mass.',
              low=0.0, high=1.0e6, vehicle='load_changeover_mass'),
    ParamSpec('load_empty_ratio', 1.0, DOUBLE,
              'Load-weighing: cylinder pressure of the empty setting over the loaded one [-] '
              '(the load valve scales the pressure that acts on the piston).', low=0.0,
              high=1.0, low_exclusive=True, vehicle='load_empty_ratio'),
    ParamSpec('initial_position', 0.0, DOUBLE,
              'Position along the track [m] of the front of vehicle 1 at t = 0.',
              low=-1.0e7, high=1.0e7),
    ParamSpec('target_stop_position', [], DOUBLE_ARRAY,
              'Target stopping point [m, track position] of the front of vehicle 1: [] none, '
              'or [x]. Sets the distance_to_go output and the stop_error metric; the '
              'target_stop_position topic (std_msgs/Float64) moves it while running.',
              low=-1.0e7, high=1.0e7, max_items=1),
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
    ParamSpec('track_adhesion_positions', [], DOUBLE_ARRAY,
              'Track positions [m] (increasing) where a rail condition starts; dry '
              '(Curtius-Kniffler, 0.33 at rest) before the first. Changeable while running '
              '(with track_adhesion, in one batch).', low=-1.0e7, high=1.0e7, dynamic=True),
    ParamSpec('track_adhesion', [], DOUBLE_ARRAY,
              'Available wheel-rail adhesion at low speed [-] from each '
              'track_adhesion_positions entry on (UIC 541-05 low adhesion: 0.02-0.10); falls '
              'with speed as Curtius-Kniffler; averaged over each vehicle; limits the '
              'wheelsets, traction and dynamic braking. Changeable while running.',
              low=0.0, high=1.0, low_exclusive=True, dynamic=True),
    # Wheel slide and slide protection (physics/wheelset.py).
    ParamSpec('wheelsets', False, BOOL,
              'Rotating wheelsets with a creep-force law per vehicle: the brake acts on the '
              'wheel, the rail on the vehicle through the creep force, wheels can slide and '
              'lock. Implied by wsp other than none and by any track_adhesion below dry. '
              'Fixed-step integration only.'),
    ParamSpec('wsp', 'none', STRING,
              'Wheel-slide protection, per vehicle a hold and a vent valve on the brake '
              'cylinder: none, builtin (the reference controller on slip and deceleration '
              'thresholds) or external (input coach_<i>/wsp/valve).',
              choices=('none', 'builtin', 'external')),
    ParamSpec('adhesion_limit', True, BOOL,
              'Braking force at most what the wheel-rail adhesion carries: on a train '
              'without wheelsets each vehicle brakes with at most mu(v) m g (mu the available '
              'adhesion: track_adhesion, dry otherwise, falling with speed as '
              'Curtius-Kniffler), the demand beyond it counted as sliding (sliding time and '
              'distance); with wheelsets the creep law limits it. false: unlimited (eq. 13 '
              'and the friction brakes as computed, whatever the adhesion).'),
    ParamSpec('wheelset_inertia', 440.0, DOUBLE,
              'Wheelsets: rotational inertia of all the wheelsets of the vehicle [kg m^2] '
              '(about 110 per passenger wheelset with brake discs, a representative figure; '
              'four wheelsets).', low=1.0, high=1.0e5, vehicle='wheelset_inertia'),
    ParamSpec('wheel_radius', 0.46, DOUBLE,
              'Wheelsets: wheel radius [m] (920 mm new passenger wheels).', low=0.2, high=1.0,
              vehicle='wheel_radius'),
    ParamSpec('wheel_speed_resolution', 0.0, DOUBLE,
              'Wheelsets: the speed sensor of the wheelsets output, its quantisation step '
              '[m/s] (the speed rounded to the nearest multiple; e.g. 0.05 for a 100-tooth '
              'wheel counted over 0.6 s at r = 0.46 m); 0 = the exact speed. The builtin WSP '
              'reads the exact speed.', low=0.0, high=1.0),
    ParamSpec('wheel_speed_noise', 0.0, DOUBLE,
              "Wheelsets: standard deviation [m/s] of the speed sensor's Gaussian noise in "
              'the wheelsets output (added before the quantisation, the result held >= 0); '
              'the same for a given wheel_speed_seed and output time, node and offline.',
              low=0.0, high=1.0),
    ParamSpec('wheel_speed_seed', 0, INTEGER,
              'Wheelsets: seed of the speed-sensor noise (with the output time stamp [ns] it '
              "seeds each sample's draws: reproducible).", low=0, high=2 ** 31 - 1),
    # Per-bogie wheelsets (kernel/bogie.py).
    ParamSpec('bogie_wheelsets', False, BOOL,
              'Wheelsets: two lumped wheelsets per vehicle, one per bogie (bogie 1 the front '
              'one), each with half the axle load, inertia and friction brake, its own brake '
              'cylinder fed by the vehicle brake and its own slide-protection valves (wsp '
              'external: coach_<i>/bogie_<j>/wsp/valve); the wheelsets output then names '
              'coach_<i>/bogie_<j>. Implies wheelsets. false: one wheelset per vehicle.'),
    ParamSpec('rail_conditioning', 0.0, DOUBLE,
              'Per-bogie wheelsets: fraction c [-] of the gap to dry rail that the leading '
              "bogie's passage restores for the trailing one (its low-speed adhesion mu + c "
              '(0.331 - mu); the cleaning effect, Voltr and Lata 2015); 0 = none; the size is '
              'a model figure, not a measured one.', low=0.0, high=1.0),
    ParamSpec('traction_schedule_times', [], DOUBLE_ARRAY,
              'Offline runs without a traction bag: times [s] (increasing) from which every '
              'locomotive holds the matching traction_schedule_commands entry; refused for a '
              'train without a locomotive.',
              low=0.0, high=1.0e7),
    ParamSpec('traction_schedule_commands', [], DOUBLE_ARRAY,
              'Traction command in [-1, 1] (> 0 traction, < 0 dynamic brake) from each '
              'traction_schedule_times entry on.', low=-1.0, high=1.0),
    ParamSpec('ep_schedule_times', [], DOUBLE_ARRAY,
              'Offline runs without brake_ep/command in an input bag: times [s] (increasing) '
              'from which the EP / ECP train line carries the matching ep_schedule_commands '
              'entry; needs brake_system ep or ecp.', low=0.0, high=1.0e7),
    ParamSpec('ep_schedule_commands', [], DOUBLE_ARRAY,
              'EP / ECP command in [0, 1] (fraction of full service, 0 = release) from each '
              'ep_schedule_times entry on.', low=0.0, high=1.0),
    # The integration method (config/integrator.py: the rules, older files' settings).
    ParamSpec('integrator', DEFAULT_INTEGRATOR, STRING,
              'Integration method: "fixed" (every coupler at the fixed integration_step), '
              '"multirate" (the fixed step, couplers above multirate_tolerance re-integrated '
              'in error-controlled sub-steps) or "adaptive" (error control of every step at '
              f'integration_tolerance; {ADAPTIVE_TOLERANCE:g} when that is 0). With multirate '
              '(the default), integration_tolerance > 0 means adaptive and multirate_tolerance '
              '0 means fixed, as in older files; fixed with integration_tolerance > 0 is '
              'refused.', choices=INTEGRATORS),
    ParamSpec('integration_tolerance', INTEGRATION_TOLERANCE, DOUBLE,
              'Error-controlled integration (integrator adaptive): the local error of every '
              'coupler force per step, relative to the largest coupler force in the train (at '
              "least 1e-3 of a vehicle's weight) [-]; ROS2 with its embedded first-order "
              'estimate, PI step control, landing on every output instant. 0 = unset (fixed '
              'step integration_step, or the adaptive default).',
              low=0.0, high=0.1),
    ParamSpec('integration_max_steps', 100, INTEGER,
              'Work budget of the error-controlled integration: steps per output period; '
              'beyond it the rest of the period takes at most as many equal steps without '
              'error control (counted in /diagnostics fallback_periods). At most ~0.25 s of '
              'work per period: 25000 / (1 + N / 20) steps for N vehicles.', low=1,
              high=1000000),
    ParamSpec('multirate_tolerance', MULTIRATE_TOLERANCE, DOUBLE,
              'Multirate fixed step (integrator multirate, the default): after each '
              'integration_step, a coupler whose local force error (ROS2 embedded estimate) '
              'exceeds this fraction of the largest coupler force in the train (at least 1e-3 '
              "of a vehicle's weight) [-] is re-integrated with its two neighbouring "
              'vehicles on either side in error-controlled sub-steps, the rest of the train '
              'keeping the step (momentum exact). 0 = every coupler at the plain fixed step '
              '(the fastest, least accurate setting). Acts with the tanh law only (the sign '
              'law, discontinuous at zero relative speed, keeps the plain fixed step) and not '
              'under error control (integrator adaptive controls every step already).',
              low=0.0, high=0.1),
    ParamSpec('multirate_reversal_weight', MULTIRATE_REVERSAL_WEIGHT, DOUBLE,
              "Multirate: a coupler's local error is at least this weight times its relative "
              'velocity error times k_f |y| u, the slope of the tanh law at its next friction '
              'reversal [-] (outside the friction band the estimate does not see velocity '
              'errors that shift the reversal). 0 = off.', low=0.0, high=100.0),
    *BLENDING_PARAMS,       # multiple units: brake control unit, blending (blending_params.py)
]
# side buffers, screw-coupling pretension, tabulated curves, resistance laws: table_ends.py
_PARAMS += END_AND_RESISTANCE_PARAMS

PARAMETERS: dict[str, ParamSpec] = {p.name: p for p in _PARAMS}

#: per-vehicle field name (as in a consist file) -> its parameter, in table order
VEHICLE_PARAMETERS: dict[str, ParamSpec] = {p.vehicle: p for p in _PARAMS if p.vehicle}
#: per-vehicle field -> the kernel row (``layout.VEHICLE``) that holds it as is, in table order
KERNEL_ROWS: dict[str, str] = {f: p.row for f, p in VEHICLE_PARAMETERS.items() if p.row}


def validate_value(name: str, value: Any,
                   table: Mapping[str, ParamSpec] = PARAMETERS) -> Any:
    """
    Check one value of parameter ``name`` of ``table``; return it normalised (:func:`check_value`).

    Raises :class:`ConfigError` with a one-line reason (an unknown name too).
    """
    spec = table.get(name)
    if spec is None:
        raise ConfigError(f'unknown parameter {quote(name)}')
    return check_value(spec, value)
