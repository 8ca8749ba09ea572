"""
Rows of the parameter table for vehicle ends and running resistance laws (:mod:`.table`).

Side buffers per end, the screw coupling's pretension, tabulated force-stroke curves of
buffers and draw gear (physics/characteristics.py) and the running resistance law of a vehicle
(physics/resistance.py). :mod:`.table` appends :data:`END_AND_RESISTANCE_PARAMS` to its list:
each row is declared once, here, and is a parameter and (``vehicle``) a consist field like the
rows there. Defaults keep the paper's law and Davis: every row at its default changes nothing.
"""
from __future__ import annotations

from train_dynamics.physics.config.spec import DOUBLE, EQUAL_FORCE, INTEGER, ParamSpec, STRING
from train_dynamics.physics.resistance import RESISTANCE_LAWS

END_AND_RESISTANCE_PARAMS = [
    # Two side buffers per end (physics/config/consist.py, parallel_buffers)
    ParamSpec('buffers_per_end', 1, INTEGER,
              'Side buffers of one vehicle end, in parallel (UIC: 2). With n > 1 the buffer '
              'figures a vehicle type gives (buffer_stiffness, buffer_friction, '
              'buffer_preload, buffer_final_force, buffer_energy, buffer_characteristic) are '
              "each buffer's and the end's are n times them (stroke and free play are each "
              "buffer's). 1: the figures are the whole end's, as in files before this field. "
              "The uniform train's buffer parameters are whole-coupling constants: not "
              'scaled.', low=1, high=4, vehicle='buffers_per_end'),
    # Screw coupling tightened against the buffers (physics/characteristics.py)
    ParamSpec('coupling_pretension', 0.0, DOUBLE,
              'Screw-coupling pretension [N]: the coupling is tightened until the buffers '
              'and the draw gear carry this elastic force at rest, buffers in contact; both '
              'then work in parallel until one unloads. A coupling takes the larger of its '
              "two ends; needs no free play. 0 = none (the paper's law).", low=0.0,
              high=1.0e6, vehicle='coupling_pretension', connection=EQUAL_FORCE),
    ParamSpec('buffer_characteristic', '', STRING,
              'Name of a tabulated force-stroke curve (characteristics: mapping of the '
              'vehicle library or the consist file: stroke [m], loading and unloading force '
              '[N]) for the buffers: replaces buffer_stiffness, buffer_friction, '
              'buffer_preload, buffer_final_force and buffer_energy; its last stroke is the '
              "buffer's stroke. '' = none.", vehicle='buffer_characteristic',
              connection=EQUAL_FORCE),
    ParamSpec('draw_gear_characteristic', '', STRING,
              'Name of a tabulated force-stroke curve for the draw gear (as '
              "buffer_characteristic). '' = none.", vehicle='draw_gear_characteristic',
              connection=EQUAL_FORCE),
    # Running resistance laws (physics/resistance.py)
    ParamSpec('resistance_law', 'davis', STRING,
              'Running resistance law: davis (davis_a, davis_b, davis_c), strahl (freight: '
              'm g (2.5 + strahl_k ((V + dV) / 10)^2) / 1000, V km/h) or sauthoff '
              '(passenger: m g (1.9 + sauthoff_c V) / 1000 + 0.0048 g (1 + 2.7 / n) '
              'sauthoff_area (V + dV)^2, n the vehicles of the train on this law); dV is '
              'resistance_wind. Sources: physics/resistance.py.',
              choices=RESISTANCE_LAWS, vehicle='resistance_law'),
    ParamSpec('strahl_k', 0.05, DOUBLE,
              'Strahl: speed factor k [-] (0.025 loaded, 0.05 mixed, 0.1 empty freight).',
              low=0.0, high=1.0, vehicle='strahl_k'),
    ParamSpec('sauthoff_c', 0.0024, DOUBLE,
              'Sauthoff: running-resistance factor c [per mille per km/h] (0.0024 for a '
              'four-axle coach).', low=0.0, high=0.1, vehicle='sauthoff_c'),
    ParamSpec('sauthoff_area', 1.45, DOUBLE,
              'Sauthoff: equivalent air-resistance area f of one vehicle [m^2] (1.45 for '
              'a passenger coach).', low=0.0, high=50.0, vehicle='sauthoff_area'),
    ParamSpec('resistance_wind', 15.0, DOUBLE,
              'Strahl and Sauthoff: wind allowance dV [km/h] added to the speed in the air '
              'term (15: head wind of the published formulas).', low=0.0, high=100.0,
              vehicle='resistance_wind'),
]
