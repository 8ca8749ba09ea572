"""
Names and types on the wire: the topics of the product contract, written once.

Every layer takes its topic names, message type strings and joint names from here: the node
(``ros/``), the bag reader, writer and plots (``recording/``) and the offline command
(``cli/``). Relative names, so that namespaces and remapping work. No imports beyond the
standard library: the physics layer may use it too. What each controller input is (its
message field, rule, setter, who takes it, lock-step family): the input table
:data:`train_dynamics.input_kinds.INPUT_KINDS` (here only the names).
"""
from __future__ import annotations

NODE_NAME = 'train_dynamics'
VALVE_NODE_NAME = 'brake_valve'

# -- message types (rosbag2 / rosbags spelling) --------------------------------------------------
FLUID_PRESSURE = 'sensor_msgs/msg/FluidPressure'
JOINT_STATE = 'sensor_msgs/msg/JointState'
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
FLOAT64 = 'std_msgs/msg/Float64'
ODOMETRY = 'nav_msgs/msg/Odometry'

# -- brake inputs (sensor_msgs/FluidPressure, ABSOLUTE Pa) ---------------------------------------
PIPE_HEAD = 'pipe_head'
PIPE_PER_COACH = 'pipe_per_coach'
CYLINDER_PER_COACH = 'cylinder_per_coach'

HEAD_PIPE_TOPIC = 'brake_pipe/pressure'
#: per-coach input topic of each per-coach mode, ``.format(i=<1-based coach>)``
COACH_INPUT_TOPIC = {PIPE_PER_COACH: 'coach_{i}/brake_pipe/pressure',
                     CYLINDER_PER_COACH: 'coach_{i}/brake_cylinder/pressure'}
#: Inputs above this ABSOLUTE pressure [Pa] (20 bar) are rejected as implausible.
MAX_ABSOLUTE_PRESSURE = 2.0e6

# -- traction inputs (std_msgs/Float64, a fraction in [-1, 1]) ------------------------------------
#: traction / dynamic-brake command of locomotive i, ``.format(i=<1-based vehicle>)``
TRACTION_TOPIC = 'coach_{i}/traction/command'

# -- EP / ECP train-line command (std_msgs/Float64, a fraction of full service in [0, 1]) ---------
#: brake_system ep / ecp: the command every vehicle's EP valves / car control device follows
EP_COMMAND_TOPIC = 'brake_ep/command'

# -- slide protection (std_msgs/Int8: 0 normal, 1 hold, 2 vent) -----------------------------------
#: ``wsp: external``: the hold and vent valves on vehicle i's brake cylinder
WSP_VALVE_TOPIC = 'coach_{i}/wsp/valve'
INT8 = 'std_msgs/msg/Int8'

# -- the stopping target (std_msgs/Float64, a track position [m]) -------------------------------
#: moves the target stopping point (parameter ``target_stop_position``) while the node runs
TARGET_STOP_TOPIC = 'target_stop_position'

# -- outputs (header.stamp = simulation time) ----------------------------------------------------
# What each output carries, when a run has it and how it is read off the simulator: the
# table train_dynamics.recording.output_specs.OUTPUTS (here only the names).
COUPLERS_TOPIC = 'couplers'
COACHES_TOPIC = 'coaches'
BRAKE_CYLINDERS_TOPIC = 'brake_cylinders'
BRAKE_RESERVOIRS_TOPIC = 'brake_reservoirs'
VEHICLE_FORCES_TOPIC = 'vehicle_forces'
VEHICLE_MOTION_TOPIC = 'vehicle_motion'
#: nav_msgs/Odometry of the lead vehicle (``coach_1``) along the track line
LEAD_ODOMETRY_TOPIC = 'odom'
#: ``target_stop_position`` set: the distance from the lead vehicle's front to the target
DISTANCE_TO_GO_TOPIC = 'distance_to_go'
#: ``header.frame_id`` of every output (the JointStates and ``odom``): the track, one axis
#: along it, forward (towards ``coach_1``'s end) positive; displacements, speeds,
#: accelerations and forces are along it, pressures are scalars of the vehicles on it
TRACK_FRAME = 'track'
WHEELSETS_TOPIC = 'wheelsets'
BRAKE_EP_STATE_TOPIC = 'brake_ep/state'
RADIO_STATE_TOPIC = 'distributed_power/state'
CLOCK_TOPIC = '/clock'
#: ``namespaced_clock``: the clock relative to the node's namespace instead of ``/clock``
NAMESPACED_CLOCK_TOPIC = 'clock'

# -- multiple units, blending builtin (std_msgs/Float64 inputs; physics/blending.py) -------------
#: the train-wide brake demand: a fraction of full service in [0, 1] or a deceleration
#: [m/s^2] (``brake_demand_mode``)
BRAKE_DEMAND_TOPIC = 'brake_demand'
#: the emergency brake, bypassing the blending: >= 0.5 applied, < 0.5 released
BRAKE_EMERGENCY_TOPIC = 'brake_emergency'
#: the ED brake of every motor car lost (line breaker trip): >= 0.5 tripped, < 0.5 restored
ED_TRIP_TOPIC = 'ed_brake/trip'
#: ``blending: external``: the ED brake force [N, >= 0] commanded of motor car i
#: (physics/ed_force.py), ``.format(i=<1-based vehicle>)``
ED_FORCE_TOPIC = 'coach_{i}/ed_brake/force'
#: the brake control unit's outputs (fields: recording/output_specs.py)
BRAKE_BLENDING_TOPIC = 'brake_blending'
BRAKE_DEMAND_STATE_TOPIC = 'brake_demand/state'
DIAGNOSTICS_TOPIC = '/diagnostics'


def input_topic(mode: str, coach: int | None = None) -> str:
    """Return the input topic of ``mode``; ``coach`` (1-based) for the per-coach modes."""
    if mode == PIPE_HEAD:
        return HEAD_PIPE_TOPIC
    return COACH_INPUT_TOPIC[mode].format(i=coach)


def coupler_names(n_coaches: int) -> list[str]:
    """Return the joint names of ``couplers``: ``coupler_1`` .. ``coupler_{N-1}``."""
    return [f'coupler_{i}' for i in range(1, n_coaches)]


def vehicle_names(indices) -> list[str]:
    """Return the joint names ``coach_<i>`` of some vehicles given by 0-based ``indices``."""
    return [f'coach_{int(i) + 1}' for i in indices]


def coach_names(n_coaches: int) -> list[str]:
    """Return the joint names of ``coaches``, ``brake_cylinders``: ``coach_1`` .. ``coach_N``."""
    return [f'coach_{i}' for i in range(1, n_coaches + 1)]
