"""
``sim_node``'s own parameters: how the node runs, not what it simulates.

Scheduling, pacing, lock-step with a controller, recording and the clock: every one is live
(``ros2 param set``), none is part of :class:`~train_dynamics.physics.config.SimConfig` nor
known to the offline command. The simulator's parameters are the table of
:mod:`train_dynamics.physics.config.table`; the node declares both with the same descriptors
(:mod:`train_dynamics.ros.parameters`) and checks both with the same validator.

Adding one: its :class:`ParamSpec` here, its effect in ``sim_node`` (at start and in
``_apply_parameters``), the table of docs/ros_interface.md regenerated (``python -m
train_dynamics.ros.node_parameters`` prints it; ``test/ros/test_node_parameters.py`` fails
while the page falls behind). Never imports rclpy: the controller-test harness reads this
table without ROS.
"""
from __future__ import annotations

from train_dynamics.physics.config.docs import parameter_table
from train_dynamics.physics.config.spec import (BOOL, DOUBLE, INTEGER, ParamSpec, STRING,
                                                STRING_ARRAY)

#: ``sim_node``'s own parameters (not part of the simulator configuration; all live).
SIM_NODE_PARAMETERS: dict[str, ParamSpec] = {p.name: p for p in [
    ParamSpec('namespaced_clock', False, BOOL,
              "With publish_clock: publish the simulation time on clock in the node's "
              'namespace (/<namespace>/clock) instead of the global /clock, so that several '
              'simulated trains in one ROS graph each have their own clock; their nodes on '
              'use_sim_time read it with --ros-args -r /clock:=/<namespace>/clock.',
              dynamic=True),
    ParamSpec('duration', 0.0, DOUBLE,
              'Simulation time [s] after which the node stops by itself (outputs up to and '
              'including t = duration); 0 = run until shut down.',
              low=0.0, high=1.0e9, dynamic=True),
    ParamSpec('wait_for_input', 0.0, DOUBLE,
              'Before the simulation clock starts (and after each reset), wait up to this many '
              'wall seconds until a publisher is connected to every brake-input topic of '
              'brake_input (the state stays at t = 0 meanwhile); 0 = start at once.',
              low=0.0, high=3600.0, dynamic=True),
    ParamSpec('sync_mode', 'free', STRING,
              'free: the simulation runs at real_time_factor whatever the controller does; '
              'lockstep: after each output the node waits until every input that '
              'lockstep_inputs declares has answered it, then advances one output period '
              '(and starts only when the controller is connected both ways).',
              choices=('free', 'lockstep'), dynamic=True),
    ParamSpec('lockstep_inputs', ['brake'], STRING_ARRAY,
              'lockstep: the controller inputs each output period waits for. brake: every '
              'active brake-input topic of brake_input, answered by a message stamped with '
              "the output's stamp; traction: the command topic of every locomotive that "
              'takes one, ep: brake_ep/command (brake_system ep or ecp), wsp: every '
              "vehicle's coach_<i>/wsp/valve (wsp external), blending: brake_demand, "
              'brake_emergency and ed_brake/trip, each of the three (blending builtin), or '
              "every motor car's coach_<i>/ed_brake/force (blending external), each "
              'answered by one command received after the output was published '
              '(std_msgs/Float64 and Int8 have no stamp). A listed input the train does not '
              'have is a configuration error in lockstep.',
              choices=('brake', 'traction', 'ep', 'wsp', 'blending'), dynamic=True,
              min_items=1),
    ParamSpec('lockstep_answer', 'echo', STRING,
              "lockstep: what answers a period. echo: a brake input stamped with the output's "
              'stamp; clock: the node publishes /clock at every output (whatever publish_clock '
              'says) and a period waits for inputs stamped at or after its time, from a '
              'controller on use_sim_time with its own timer (no wait at t = 0).',
              choices=('echo', 'clock'), dynamic=True),
    ParamSpec('lockstep_period', 0.0, DOUBLE,
              'lockstep_answer clock: simulation seconds between two waits for the controller '
              '(its timer period), rounded to whole output periods; 0 = every output period.',
              low=0.0, high=3600.0, dynamic=True),
    ParamSpec('input_timing', 'arrival', STRING,
              'arrival: a brake input takes effect at the next integration step after it '
              'arrives; stamp: at its header stamp (simulation time), exactly with '
              'cylinder_per_coach and pipe_per_coach (the step spanning it is split there), '
              'else at the first integration step at or after it; one the simulation has '
              'passed takes effect at once and is counted late.',
              choices=('arrival', 'stamp'), dynamic=True),
    ParamSpec('lockstep_timeout', 5.0, DOUBLE,
              'lockstep: wall seconds without the answer to an output after which the node '
              'reports it (log, /diagnostics) and then does what lockstep_on_timeout says; '
              '0 = wait silently.',
              low=0.0, high=3600.0, dynamic=True),
    ParamSpec('lockstep_on_timeout', 'wait', STRING,
              'lockstep, after lockstep_timeout: wait (keep waiting for the answer) or stop '
              '(end the run; sim_node exits with status 4).',
              choices=('wait', 'stop'), dynamic=True),
    ParamSpec('step_periods', 1, INTEGER,
              'Output periods the ~/step service advances a paused simulation by.',
              low=1, high=1000000000, dynamic=True),
    ParamSpec('realtime_priority', 20, INTEGER,
              'SCHED_FIFO priority (1-99) of the simulation thread while it keeps up with '
              'real_time_factor, so that the load of other processes does not delay its '
              'outputs; 0 = normal scheduling. Needs CAP_SYS_NICE or an rtprio limit (ulimit '
              '-r); without either the thread runs at normal priority (logged).',
              low=0, high=99, dynamic=True),
    # off by default: a machine-wide effect (every CPU of the host), so opt-in
    ParamSpec('cpu_wake_latency', -1, INTEGER,
              'Longest CPU wake-up latency [us] the node asks the kernel for while it runs '
              '(Linux PM QoS, /dev/cpu_dma_latency): idle CPUs stay in idle states that wake '
              'within it (in a VM: poll instead of halting), at the cost of their power; '
              'machine-wide, so opt-in: -1 (default) = no request, 0 = the lowest latency. '
              'Needs write access to /dev/cpu_dma_latency (root by default); without it '
              'nothing is asked (logged).',
              low=-1, high=100000, dynamic=True),
    # 1 s: the usual rate of ROS diagnostics (diagnostic_updater's default period)
    ParamSpec('diagnostics_period', 1.0, DOUBLE,
              'Wall-clock period [s] of the /diagnostics statuses (and of their copy in '
              'record_bag outside lock-step): shorter to watch a run closely, longer to '
              'spare a loaded machine. Each status takes the simulation lock briefly.',
              low=0.1, high=3600.0, dynamic=True),
    ParamSpec('record_flush_period', 10.0, DOUBLE,
              'Wall-clock period [s] at which the record_bag MCAP file is finished and a new '
              'one started: a SIGKILL loses at most this much of the recording.',
              low=0.1, high=3600.0, dynamic=True),
]}


def markdown_table() -> str:
    """Return the table of :data:`SIM_NODE_PARAMETERS` as docs/ros_interface.md shows it."""
    return parameter_table(SIM_NODE_PARAMETERS)


if __name__ == '__main__':   # python -m train_dynamics.ros.node_parameters: the docs' table
    print(markdown_table())
