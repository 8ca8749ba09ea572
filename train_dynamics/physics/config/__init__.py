"""
The configuration: parameters, their one validator, parameter and consist files, budgets.

One concern per module, no rclpy:

- :mod:`.spec`: the description of a parameter (:class:`ParamSpec`) and its validator;
- :mod:`.table`: the simulator's parameters (:data:`PARAMETERS`, the per-vehicle fields among
  them) and ``sim_node``'s own;
- :mod:`.simconfig`: :class:`SimConfig`, the typed configuration checked as a whole, which
  keeps its parsed consist;
- :mod:`.files`: ROS 2 parameter files (node and offline alike) and the rule for relative
  paths;
- :mod:`.consist`: consist files, the vehicle library and the connection rules;
- :mod:`.budgets`: the memory a run needs; :mod:`.docs`: the documentation's parameter table
  (not imported here: ``python -m train_dynamics.physics.config.docs`` prints it). The rules
  refusing an input message are the input table's (:mod:`train_dynamics.input_kinds`).

The modules import each other in that order upwards (spec, table, files, consist, budgets,
simconfig); this package re-exports their public names.
"""
from train_dynamics.physics.config.budgets import fmt_bytes, MAX_SIMULATOR_MEMORY, simulator_memory
from train_dynamics.physics.config.consist import Consist, CONSIST_PARAMETERS
from train_dynamics.physics.config.files import (KNOWN_NODE_NAMES, node_sections, read_param_file,
                                                 read_param_sections, resolve_path,
                                                 ROS_BUILTIN_PARAMETERS, simulator_params,
                                                 unknown_sections, unknown_sections_message)
from train_dynamics.physics.config.node_table import SIM_NODE_PARAMETERS
from train_dynamics.physics.config.simconfig import load_param_file, SimConfig
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
    'INTEGRATION_TOLERANCE', 'KNOWN_NODE_NAMES', 'load_param_file',
    'MAX_SIMULATOR_MEMORY', 'node_sections', 'P_FILL_FRACTION', 'P_FILL_TIME',
    'P_RELEASE_FRACTION', 'P_RELEASE_TIME', 'PARAMETERS', 'ParamSpec', 'PIPE_NOMINAL_PRESSURE',
    'read_param_file', 'read_param_sections', 'resolve_path', 'ROS_BUILTIN_PARAMETERS',
    'SIM_NODE_PARAMETERS', 'SimConfig', 'simulator_memory', 'simulator_params', 'STRING',
    'STRING_ARRAY', 'unknown_sections',
    'unknown_sections_message', 'validate_value', 'VEHICLE_PARAMETERS']
