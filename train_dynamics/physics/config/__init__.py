"""
The configuration: parameters, their one validator, consist files, budgets.

One concern per module, no rclpy:

- :mod:`.spec`: the description of a parameter (:class:`ParamSpec`) and its validator;
- :mod:`.table`: the simulator's parameters (:data:`PARAMETERS`, the per-vehicle fields among
  them; ``sim_node``'s own are :mod:`train_dynamics.ros.node_parameters`);
- :mod:`.simconfig`: :class:`SimConfig`, the typed configuration checked as a whole, which
  keeps its parsed consist;
- :mod:`.files`: the YAML dialect of the configuration's files and the rule for relative
  paths (the ROS 2 parameter-file form is :mod:`train_dynamics.param_files`'s);
- :mod:`.consist`: consist files, the vehicle library and the connection rules;
- :mod:`.budgets`: the memory a run needs; :mod:`.docs`: the documentation's parameter table
  (not imported here: ``python -m train_dynamics.physics.config.docs`` prints it). The rules
  refusing an input message are the input table's (:mod:`train_dynamics.input_kinds`).

The modules import each other in that order upwards (spec, table, files, consist, budgets,
simconfig); this package re-exports their public names.
"""
from train_dynamics.physics.config.budgets import fmt_bytes, MAX_SIMULATOR_MEMORY, simulator_memory
from train_dynamics.physics.config.consist import Consist, CONSIST_PARAMETERS
from train_dynamics.physics.config.files import resolve_path
from train_dynamics.physics.config.simconfig import SimConfig
from train_dynamics.physics.config.spec import (ARRAY_KINDS, BOOL, check_value, ConfigError,
                                                DOUBLE, DOUBLE_ARRAY, INTEGER, ParamSpec, STRING,
                                                STRING_ARRAY)
from train_dynamics.physics.config.table import (ATMOSPHERIC_PRESSURE, FULL_SERVICE_PRESSURE,
                                                 G_FILL_TIME, G_RELEASE_TIME,
                                                 INTEGRATION_TOLERANCE, P_FILL_FRACTION,
                                                 P_FILL_TIME, P_RELEASE_FRACTION, P_RELEASE_TIME,
                                                 PARAMETERS, PIPE_NOMINAL_PRESSURE,
                                                 validate_value, VEHICLE_PARAMETERS)

__all__ = [
    'ARRAY_KINDS', 'ATMOSPHERIC_PRESSURE', 'BOOL', 'check_value', 'ConfigError', 'Consist',
    'CONSIST_PARAMETERS', 'DOUBLE', 'DOUBLE_ARRAY',
    'fmt_bytes', 'FULL_SERVICE_PRESSURE',
    'G_FILL_TIME', 'G_RELEASE_TIME', 'INTEGER',
    'INTEGRATION_TOLERANCE', 'MAX_SIMULATOR_MEMORY', 'P_FILL_FRACTION', 'P_FILL_TIME',
    'P_RELEASE_FRACTION', 'P_RELEASE_TIME', 'PARAMETERS', 'ParamSpec', 'PIPE_NOMINAL_PRESSURE',
    'resolve_path', 'SimConfig', 'simulator_memory', 'STRING', 'STRING_ARRAY',
    'validate_value', 'VEHICLE_PARAMETERS']
