"""
Parameters of multiple units: the brake control unit and its blending (physics/blending.py).

Declared here, one :class:`~train_dynamics.physics.config.spec.ParamSpec` each, and added to
the simulator's table (:data:`~train_dynamics.physics.config.table.PARAMETERS`); the rules
between them and the other parameters are :func:`check_blending`. Motor cars are vehicles
with ``max_dynamic_brake_force`` > 0: their electro-dynamic (ED) brake is the locomotive's
dynamic brake (``kernel/traction.py``: force and power limits, adhesion, fade-out below
``dynamic_brake_fade_speed``, build-up over ``traction_build_up_time``).
"""
from __future__ import annotations

from typing import Any

from train_dynamics.physics.config.spec import ConfigError, DOUBLE, DOUBLE_ARRAY, ParamSpec, STRING

#: the blending modes: none (friction only, the brake inputs of brake_input as before),
#: builtin (the reference brake control unit of physics/blending.py), external (the
#: controller under test is the brake control unit)
BLENDING_MODES = ('none', 'builtin', 'external')

BLENDING_PARAMS = [
    ParamSpec('blending', 'none', STRING,
              'Brake blending of a multiple unit: none (friction brakes only, driven by '
              'brake_input as before) or builtin (a brake control unit takes the train-wide '
              'brake_demand: the electro-dynamic brake of the motor cars first, up to its '
              'limit at the present speed, the friction brake of every car makes up the rest; '
              'needs brake_input cylinder_per_coach and brake_model empirical: the unit sets '
              'the cylinder pressures itself) or external (the controller under test is the '
              'brake control unit: it commands the cylinder of each car on '
              'coach_<i>/brake_cylinder/pressure and the ED brake of each motor car on '
              'coach_<i>/traction/command < 0, a fraction of the ED available at the present '
              'speed; needs brake_input cylinder_per_coach; brake_blending shows the '
              'achieved forces).', choices=BLENDING_MODES),
    ParamSpec('blending_scope', 'train', STRING,
              'builtin blending: train (the ED force of the motor cars relieves every car: '
              'the friction make-up is shared by all cars in proportion to their mass) or '
              'car (each car brakes its own mass: a motor car its ED force, then friction; a '
              'trailer friction only).', choices=('train', 'car')),
    ParamSpec('brake_demand_mode', 'fraction', STRING,
              'Meaning of brake_demand: fraction (of full service, in [0, 1]: '
              'fraction x full_service_deceleration) or deceleration [m/s^2].',
              choices=('fraction', 'deceleration')),
    ParamSpec('full_service_deceleration', 1.0, DOUBLE,
              'Deceleration demanded by a full-service brake_demand [m/s^2] (EN 13452-1 '
              'expects about 1 m/s^2 for EMUs and high-speed units; the unit files set their '
              "operators' figure).", low=0.05, high=5.0),
    ParamSpec('blending_jerk_limit', 1.0, DOUBLE,
              'builtin blending: largest rate of change of the demanded deceleration [m/s^3] '
              '(the comfort limit of brake control units, typically 0.75-1.5 m/s^3; a guess '
              'within that range). Emergency is not limited.', low=0.01, high=100.0),
    ParamSpec('blending_period', 0.01, DOUBLE,
              'builtin blending: cycle time of the brake control unit [s] (it reads the speeds '
              'and achieved ED forces and sets ED commands and cylinder pressures once per '
              'period; 10 ms: a guess, BCUs run at 10-50 ms).', low=1.0e-4, high=1.0),
    ParamSpec('friction_response_time', 0.3, DOUBLE,
              'builtin blending: time constant [s] of the EP-controlled cylinder pressure '
              '(first-order lag from the pressure the unit commands to the cylinder; a guess '
              'for an analogue EP valve feeding a disc-brake cylinder, 95 % in 3 time '
              'constants).', low=1.0e-3, high=10.0),
    ParamSpec('demand_schedule_times', [], DOUBLE_ARRAY,
              'Offline runs without brake_demand in an input bag: times [s] (increasing) '
              'from which the brake demand is the matching demand_schedule_values entry; '
              'needs blending builtin.', low=0.0, high=1.0e7),
    ParamSpec('demand_schedule_values', [], DOUBLE_ARRAY,
              'Brake demand (as brake_demand_mode) from each demand_schedule_times entry on.',
              low=0.0, high=10.0),
    ParamSpec('emergency_schedule_time', -1.0, DOUBLE,
              'Offline runs without brake_emergency in an input bag: time [s] of an emergency '
              'brake application (bypasses the blending); < 0: none. Needs blending builtin.',
              low=-1.0, high=1.0e7),
    ParamSpec('ed_trip_schedule_time', -1.0, DOUBLE,
              'Offline runs without ed_brake/trip in an input bag: time [s] at which the '
              'electro-dynamic brake of every motor car is lost (line breaker trip); < 0: '
              'never. Needs blending builtin.', low=-1.0, high=1.0e7),
    ParamSpec('track_brake_force', 0.0, DOUBLE,
              'Magnetic track brakes of the vehicle: braking force at rest [N], all magnets '
              'together (a force on the rail, not limited by adhesion; applied with the '
              'emergency brake of blending builtin; physics/track_brake.py); 0 = none.',
              low=0.0, high=1.0e6, vehicle='track_brake_force'),
    ParamSpec('track_brake_half_speed', 30.0, DOUBLE,
              'Magnetic track brakes: speed [m/s] at which the force has fallen to half, '
              'F = F_0 / (1 + |v| / v_h) (a guess after the manufacturers curves: about half '
              'the standstill force near 100 km/h).', low=0.01, high=1.0e9,
              vehicle='track_brake_half_speed'),
    ParamSpec('eddy_brake_force', 0.0, DOUBLE,
              'Linear eddy-current brake of the vehicle: force [N] at the critical speed and '
              'the nominal air gap of 7 mm, F = F_e (g_0 / g)^2 2 (v / v_c) / (1 + (v / '
              'v_c)^2) (physics/track_brake.py: a force on the rail, 0 at rest; applied with '
              'the track brakes); 0 = none.', low=0.0, high=1.0e6, vehicle='eddy_brake_force'),
    ParamSpec('eddy_brake_critical_speed', 15.0, DOUBLE,
              'Linear eddy-current brake: speed [m/s] of its largest force (a guess).',
              low=0.1, high=200.0, vehicle='eddy_brake_critical_speed'),
    ParamSpec('eddy_brake_air_gap', 0.007, DOUBLE,
              'Linear eddy-current brake: air gap between magnets and rail [m]; the force '
              'scales as (0.007 / gap)^2.', low=0.001, high=0.05,
              vehicle='eddy_brake_air_gap'),
    ParamSpec('track_brake_delay', 0.5, DOUBLE,
              'Magnetic track brakes: time [s] from the emergency application to the force '
              '(lowering the magnets, building the field; a guess); released at once.',
              low=0.0, high=10.0),
]


def check_blending(cfg: Any) -> None:
    """Refuse a blending configuration that cannot run; raises :class:`ConfigError`."""
    times, values = cfg.demand_schedule_times, cfg.demand_schedule_values
    if len(times) != len(values):
        raise ConfigError(f'demand_schedule_times and demand_schedule_values must have the '
                          f'same length ({len(times)} != {len(values)})')
    if any(b <= a for a, b in zip(times, times[1:])):
        raise ConfigError('demand_schedule_times: must strictly increase')
    if cfg.blending == 'none':
        if times or cfg.emergency_schedule_time >= 0.0 or cfg.ed_trip_schedule_time >= 0.0:
            raise ConfigError('demand_schedule_times, emergency_schedule_time and '
                              'ed_trip_schedule_time need blending builtin')
        return
    if cfg.blending == 'external':
        if cfg.brake_input != 'cylinder_per_coach' or times or \
                cfg.emergency_schedule_time >= 0.0 or cfg.ed_trip_schedule_time >= 0.0:
            raise ConfigError('blending external: needs brake_input cylinder_per_coach (the '
                              'controller commands the cylinders) and no demand, emergency or '
                              'ED trip schedule (those are inputs of the builtin unit)')
        return
    if cfg.brake_input != 'cylinder_per_coach' or cfg.brake_model != 'empirical':
        raise ConfigError(f'blending {cfg.blending}: needs brake_input cylinder_per_coach and '
                          f'brake_model empirical (the brake control unit sets the cylinder '
                          f'pressures), got {cfg.brake_input} / {cfg.brake_model}')
    if cfg.brake_demand_mode == 'fraction' and any(v > 1.0 for v in values):
        raise ConfigError('demand_schedule_values: a fraction of full service is at most 1')
