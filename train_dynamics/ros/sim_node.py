"""
``sim_node``: the real-time ROS 2 node (node name ``train_dynamics``) around the physics core.

The model is :class:`train_dynamics.physics.train.TrainSimulator`, the same class the offline
command runs. This module declares the node and wires its parts, each of which documents its
behaviour and owns its state:

- :mod:`train_dynamics.ros.controller_inputs`: the controller inputs, one channel per kind of
  the input table (:mod:`train_dynamics.input_kinds`): validation and rejection counts,
  staleness and the fail-safes, the graph scan, ``wait_for_input``;
- :mod:`train_dynamics.ros.pacing`: the simulation thread (pacing at ``real_time_factor``,
  the lag policy, chunking), ``duration``, numerical faults;
- :mod:`train_dynamics.ros.publishers`: the output topics of the run (the table
  :data:`train_dynamics.recording.output_specs.OUTPUTS`) and ``/clock`` at ``publish_rate``
  in simulation time; :mod:`train_dynamics.ros.stop_target`: the stopping target's input;
- :mod:`train_dynamics.ros.recorder`: ``record_bag`` (inputs and outputs, a rosbag2 MCAP
  written on its own thread);
- :mod:`train_dynamics.ros.diagnostics`: ``/diagnostics`` (~1 Hz wall);
- :mod:`train_dynamics.ros.parameters`: descriptors and the set callbacks;
- :mod:`train_dynamics.ros.run_control`: the ``~/pause``, ``~/resume`` and ``~/step``
  services and the lock-step with a controller (``sync_mode``, ``lockstep_inputs``,
  ``lockstep_answer``, ``lockstep_timeout``; what answers and what is refused:
  :mod:`train_dynamics.ros.lockstep_inputs`); ``input_timing`` is the brake inputs'.

Threads and locks: the executor thread runs the subscription callbacks, the timers, the
parameter callbacks and the ``reset`` service; the simulation thread (:class:`Pacer`) runs the
simulator; the bag writer thread writes the bag. The :class:`SimulationLock` guards the run
(the simulator and every part's run state); the brake inputs' own lock guards the latest input
values between their callbacks and the simulation thread. The node holds one configuration,
``_cfg``: that of its current parameter values, live and pending alike (an immutable
:class:`SimConfig`; every accepted set replaces it by ``_cfg.replace(...)``, checked as a whole,
on the executor thread under the simulation lock; the simulation thread never reads it: each
part holds the values it uses). What the running simulation was built from is the
simulator's own configuration (``simulator.cfg``, never changed: live values reach the run
through the parts' setters); the structural values where the two differ are the pending
changes.

Parameters: every parameter of :data:`train_dynamics.physics.config.PARAMETERS` plus the node's
own (:data:`~train_dynamics.ros.node_parameters.SIM_NODE_PARAMETERS`): ``duration`` (simulation
seconds after which the node stops by itself, 0 = forever), ``wait_for_input`` (hold t = 0
until the brake-input topics have publishers, at most that many wall seconds),
``realtime_priority`` (the simulation thread's SCHED_FIFO priority,
:mod:`~train_dynamics.ros.pacing`), ``cpu_wake_latency`` (a PM QoS request held while the node
runs, :class:`~train_dynamics.ros.scheduling.CpuWakeLatency`) and ``record_flush_period``.
Invalid values are rejected with a reason and change nothing. The live ones (``dynamic``:
``model_type``, ``scale_factor``, ``real_time_factor``, ``publish_clock``, ``input_timeout``,
``on_input_timeout``, and the node's own) act at once (the state is untouched). Every other
(structural) parameter is accepted as PENDING: it is stored, logged as pending and applied by
the ``reset`` service (``~/reset``, i.e. ``/train_dynamics/reset``, ``std_srvs/srv/Trigger``),
which restarts the scenario from t = 0 with the current parameter values and says in its
response (and the log) what changed; a recording continues in a new bag
``<record_bag>_reset<k>``.

Exit status of ``main``: 0; 2 invalid parameters; 3 numerical fault (with ``duration``);
4 lock-step timeout (``lockstep_on_timeout`` stop) or refused (a second or best-effort
publisher on a lock-step input);
1 other errors (e.g. the bag cannot be created, or writing it failed: a full disk).
"""
from __future__ import annotations

import sys
import threading
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import ParameterException
import rclpy.logging
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from rclpy.serialization import serialize_message
from std_srvs.srv import Trigger

from train_dynamics import topics
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.quoting import quote
from train_dynamics.recording.bags import BagError, offered_qos
from train_dynamics.recording.output_specs import OUTPUTS, target_of
from train_dynamics.recording.outputs import OutputEncoder, time_ns
from train_dynamics.ros import parameters as ros_parameters
from train_dynamics.ros.controller_inputs import (ControllerInputs, GRAPH_SCAN_PERIOD,
                                                  INPUT_QOS, MAX_ABSOLUTE_PRESSURE,
                                                  REJECT_REASONS)
from train_dynamics.ros.diagnostics import (BrakeSystemReport, diagnostic_array, InputReport,
                                            SimulationReport)
from train_dynamics.ros.executor import ExitOn, make_executor, run_node, shutdown_safe
from train_dynamics.ros.lockstep_inputs import lockstep_input_error
from train_dynamics.ros.node_parameters import SIM_NODE_PARAMETERS
from train_dynamics.ros.pacing import BEHIND_WARN, Pacer, SimulationLock
from train_dynamics.ros.publishers import OUTPUT_QOS, Outputs
from train_dynamics.ros.recorder import (BagWriter, check_bag_path, MAX_RECORD_BACKLOG,
                                         open_bag, reset_bag_path)
from train_dynamics.ros.run_control import RunControl
from train_dynamics.ros.scheduling import CpuWakeLatency, freeze_startup_heap, normal_priority
from train_dynamics.ros.stop_target import StopTargetInput

__all__ = ['SimNode', 'main', 'make_executor', 'INPUT_QOS', 'OUTPUT_QOS',
           'MAX_ABSOLUTE_PRESSURE', 'MAX_RECORD_BACKLOG', 'REJECT_REASONS']

NODE_NAME = topics.NODE_NAME
#: exit status after a recording that failed (a full disk): the bag holds less than the run
EXIT_RECORD_FAILED = 1
#: every parameter the node declares: the simulator's and its own
SPECS = {**PARAMETERS, **SIM_NODE_PARAMETERS}
#: the node parameters of the run control (pause/step, lock-step, input timing)
CONTROL_PARAMETERS = frozenset({'sync_mode', 'input_timing', 'lockstep_timeout',
                                'lockstep_on_timeout', 'step_periods', 'lockstep_inputs',
                                'lockstep_answer', 'lockstep_period'})


#: the most values of an array a log line, the reset reply or /diagnostics shows
FMT_ITEMS = 6


def _fmt(value: Any) -> str:
    """Return a value for a log line: floats as %g, arrays cut to :data:`FMT_ITEMS` values."""
    if isinstance(value, float):
        return f'{value:g}'
    if isinstance(value, (list, tuple)):
        shown = [_fmt(v) for v in value[:FMT_ITEMS]]
        if len(value) > FMT_ITEMS:
            shown.append(f'... ({len(value)} values)')
        return '[' + ', '.join(shown) + ']'
    return quote(value) if isinstance(value, str) else str(value)


class SimNode(Node):
    """The simulator node (``train_dynamics``); see the module documentation."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._destroyed = False
        self._record_failed = False      # a bag closed after a write failure (exit 1)
        self._resets = 0                 # executor thread only
        #: parameter files with no section for this node (``main`` fills it; /diagnostics)
        self.parameter_file_warnings: list[str] = []
        ros_parameters.declare_parameters(self, SPECS)
        cfg = SimConfig.from_dict(self._parameter_values())   # raises ConfigError (main: 2)
        self._check_lockstep(cfg)
        #: the configuration of the node's current parameter values (``_start`` sets it):
        #: sets derive it from the last one (a consist is read only when a value it is built
        #: from changes), the reset service builds it anew
        self._cfg: SimConfig | None = None
        self._checked: tuple[SimConfig, dict[str, Any], SimConfig] | None = None
        self._flush_period = float(self.get_parameter('record_flush_period').value)
        if cfg.record_bag:
            check_bag_path(cfg.record_bag)

        self._lock = SimulationLock()
        self._inputs = ControllerInputs(self)
        self._outputs = Outputs(self)
        self._outputs.on_output = self._inputs.output_published    # lock-step: Float64 answers
        self._stop_target = StopTargetInput(self, INPUT_QOS, self._lock, self._target_run,
                                            self._outputs.record)
        self._pacer = Pacer(self._lock, self.get_logger(), self.context, self._inputs,
                            self._outputs)
        self._pacer.duration = float(self.get_parameter('duration').value)
        self._pacer.set_realtime_priority(self.get_parameter('realtime_priority').value)
        self._wake_latency: CpuWakeLatency | None = None
        self._request_wake_latency(self.get_parameter('cpu_wake_latency').value)
        self._control = RunControl(self, self._lock, self._inputs, self._outputs,
                                   self._pacer.wake)
        self._pacer.control = self._control
        self._configure_control()
        self._inputs.wait_for_input = float(self.get_parameter('wait_for_input').value)
        self._pub_diag = self.create_publisher(DiagnosticArray, topics.DIAGNOSTICS_TOPIC,
                                               OUTPUT_QOS)
        self._reset_srv = self.create_service(Trigger, '~/reset', self._on_reset)
        writer = self._open_bag(cfg, first=True)
        try:
            with self._lock.held():
                self._start(cfg, writer, first=True)
            ros_parameters.watch_parameters(self, SPECS, self._check_parameters,
                                            self._apply_parameters)
            # on a steady clock: with use_sim_time and no /clock they would never fire
            steady = Clock(clock_type=ClockType.STEADY_TIME)
            self._diag_timer = self._diagnostics_timer(
                self.get_parameter('diagnostics_period').value)
            self._scan_timer = self.create_timer(
                GRAPH_SCAN_PERIOD, shutdown_safe(self, self._inputs.scan_graph), clock=steady)
            self._clock_timer = self.create_timer(   # a second /clock publisher: a warning
                GRAPH_SCAN_PERIOD, shutdown_safe(self, self._check_clock), clock=steady)
        except BaseException:
            if writer is not None:       # a failed start leaves no bag behind
                self._outputs.take_writer()
                writer.discard()
            raise
        self._pacer.start_thread()

    # -- parameters ------------------------------------------------------------------------
    def _configure_control(self) -> None:
        """Hand the run-control parameters to their parts (simulation lock held or unstarted)."""
        value = self.get_parameter
        sync_mode = value('sync_mode').value
        self._control.configure(sync_mode, value('lockstep_timeout').value,
                                value('lockstep_on_timeout').value, value('step_periods').value,
                                tuple(value('lockstep_inputs').value),
                                value('lockstep_answer').value, value('lockstep_period').value)
        self._outputs.publish_clock = self._publish_clock()
        self._inputs.by_stamp = value('input_timing').value == 'stamp'
        # wake the simulation thread on each input only where it waits for them
        self._inputs.on_input = (self._pacer.wake if sync_mode == 'lockstep'
                                 or self._inputs.by_stamp else None)

    def _check_clock(self) -> None:
        """Warn when another node publishes on our clock topic (``ros/clock.py``)."""
        with self._lock.held():
            self._outputs.clock.check_publishers()

    def _publish_clock(self) -> bool:
        """Return True if /clock goes out: publish_clock, or lock-step on the clock."""
        cfg = self._cfg
        return bool(cfg is not None and cfg.publish_clock) or (
            self.get_parameter('sync_mode').value == 'lockstep'
            and self.get_parameter('lockstep_answer').value == 'clock')

    def _check_lockstep(self, cfg: SimConfig, changes: dict[str, Any] | None = None) -> None:
        """Raise ConfigError if the lock-step declares an input the train of ``cfg`` lacks."""
        changes = changes or {}
        value = {name: changes.get(name, self.get_parameter(name).value)
                 for name in ('sync_mode', 'lockstep_inputs')}
        why = (lockstep_input_error(cfg, tuple(value['lockstep_inputs']))
               if value['sync_mode'] == 'lockstep' else None)
        if why is not None:
            raise ConfigError(why)

    def _request_wake_latency(self, limit_us: int) -> None:
        """Hold a CPU wake-up latency request of ``limit_us`` (-1: none) instead of the last."""
        if self._wake_latency is not None:
            self._wake_latency.release()
        self._wake_latency = CpuWakeLatency(limit_us)
        if limit_us >= 0 and not self._wake_latency.held:
            self.get_logger().info(
                f'cpu_wake_latency {limit_us} us: {self._wake_latency.status}; idle CPUs may '
                'wake the simulation thread late (needs write access to /dev/cpu_dma_latency)')
        self._pacer.cpu_wake_latency = self._wake_latency.status

    def _parameter_values(self) -> dict[str, Any]:
        return ros_parameters.parameter_values(self, PARAMETERS)

    def _check_parameters(self, changes: dict[str, Any]) -> None:
        """Set callback: raise if the batch is not acceptable as a whole (changes nothing)."""
        sim_changes = {k: v for k, v in changes.items() if k in PARAMETERS}
        cfg = self._cfg.replace(**sim_changes)
        bag = changes.get('record_bag')
        if bag and bag != self._running.record_bag:
            check_bag_path(bag)
        if {'sync_mode', 'lockstep_inputs'} & set(changes):
            self._check_lockstep(self._running, changes)
        self._checked = (self._cfg, sim_changes, cfg)   # what post-set adopts

    def _apply_parameters(self, changes: dict[str, Any]) -> None:
        """Post-set callback: apply live changes at once; report structural ones pending."""
        sim_changes = {k: v for k, v in changes.items() if k in PARAMETERS}
        checked, self._checked = self._checked, None
        if checked is not None and checked[0] is self._cfg and checked[1] == sim_changes:
            cfg = checked[2]
        else:
            cfg = self._cfg.replace(**sim_changes)
        with self._lock.held():
            self._cfg = cfg
            if 'model_type' in changes or 'scale_factor' in changes:
                self._pacer.sim.set_model(cfg.model_type, cfg.scale_factor)
                self.get_logger().info(
                    f't = {self._pacer.sim.t:.3f} s: coupler model {cfg.model_type}, '
                    f'scale_factor {cfg.scale_factor:g} s/m')
            self._outputs.metrics.set_limits(cfg.coupler_force_limit, cfg.jerk_limit)
            if {'track_adhesion_positions', 'track_adhesion'} & set(changes):
                self._pacer.sim.set_track_adhesion(cfg.track_adhesion_positions,
                                                   cfg.track_adhesion)
            if 'real_time_factor' in changes:
                self._pacer.set_real_time_factor(cfg.real_time_factor)
            self._outputs.publish_clock = self._publish_clock()
            self._inputs.set_policy(cfg.input_timeout, cfg.on_input_timeout)
            if 'duration' in changes:
                self._pacer.set_duration(changes['duration'])
            if 'realtime_priority' in changes:
                self._pacer.set_realtime_priority(changes['realtime_priority'])
            if 'wait_for_input' in changes:
                self._inputs.wait_for_input = changes['wait_for_input']
            if CONTROL_PARAMETERS & set(changes):
                self._configure_control()
        if 'cpu_wake_latency' in changes:
            self._request_wake_latency(changes['cpu_wake_latency'])
        if 'record_flush_period' in changes:
            self._flush_period = changes['record_flush_period']
        if 'diagnostics_period' in changes:
            self.destroy_timer(self._diag_timer)
            self._diag_timer = self._diagnostics_timer(changes['diagnostics_period'])
        structural = [n for n in changes if not SPECS[n].dynamic]
        if structural:
            self.get_logger().info(
                'parameter change accepted, pending until the reset service is called: '
                + ', '.join(f'{n} = {_fmt(changes[n])}' for n in structural)
                + f' (all pending: {self.pending_changes() or "none"})')

    @property
    def _running(self) -> SimConfig:
        """Return the configuration the running simulation was built from (never changed)."""
        return self._pacer.sim.cfg

    def pending_changes(self) -> str:
        """Return 'name: old -> new, ...' of the values the running simulation does not use."""
        return self._pending_changes(self._cfg)

    def _pending_changes(self, cfg: SimConfig) -> str:
        running = self._running.values
        diffs = [f'{n}: {_fmt(running[n])} -> {_fmt(v)}' for n, v in cfg.values.items()
                 if not PARAMETERS[n].dynamic and running.get(n) != v]
        return ', '.join(diffs)

    @property
    def config(self) -> SimConfig:
        """Return the configuration of the node's current parameter values (immutable)."""
        return self._cfg

    # -- start / reset ---------------------------------------------------------------------
    def _start(self, cfg: SimConfig, writer: BagWriter | None, first: bool = False) -> None:
        """(Re)build the run for ``cfg`` at t = 0; the caller holds the simulation lock."""
        # Warm-up on a throw-away copy: loads the compiled kernels (numba cache) now, not in
        # the first real-time step; what cannot run fails here, before anything changed.
        TrainSimulator(cfg).advance(1)
        sim = TrainSimulator(cfg)
        self._cfg = cfg
        self._outputs.start(OutputEncoder.for_config(cfg), cfg.publish_rate, sim.h,
                            self._publish_clock(), writer, metrics=RunMetrics.for_run(cfg, sim))
        self._inputs.start(cfg, sim.n, recording=writer is not None)
        self._stop_target.start(target_of(cfg) is not None)
        self._control.start(sim)
        self._pacer.start(sim, cfg.real_time_factor)
        rtf, duration = cfg.real_time_factor, self._pacer.duration
        where = f'; recording to {writer.path.resolve()}' if writer else ''
        self.get_logger().info(
            f'{"started" if first else "reset"}: {sim.n} coaches, brake_input '
            f'{cfg.brake_input}, {cfg.model_type} model (scale_factor {cfg.scale_factor:g} '
            f's/m), step {sim.h:g} s, outputs at {self._outputs.rate:g} Hz, real_time_factor '
            f'{rtf:g}{" (as fast as possible)" if rtf == 0 else ""}'
            f'{f", duration {duration:g} s" if duration > 0 else ""}{where}')

    def _target_run(self) -> tuple[Any, float] | None:
        """Return the outputs' run state and the time [s] (simulation lock held)."""
        run = self._outputs.run
        return None if run is None else (run, self._pacer.sim.t)

    def _open_bag(self, cfg: SimConfig, first: bool) -> BagWriter | None:
        """
        Return a recorder for ``cfg.record_bag``; None when not recording.

        After a reset: the first free ``<record_bag>_reset<k>``. Raises if the bag cannot be
        created.
        """
        if not cfg.record_bag:
            return None
        path = cfg.record_bag if first else reset_bag_path(cfg.record_bag, self._resets)
        return open_bag(path, cfg, self.get_fully_qualified_name(), self.get_logger(),
                        self._flush_period, self.resolve_topic_name, self._offered(),
                        sim_time_split=self.get_parameter('sync_mode').value == 'lockstep')

    @staticmethod
    def _offered() -> dict[str, Any]:
        """Return topic -> the QoS the node offers on it (what a bag records)."""
        qos = offered_qos(OUTPUT_QOS.reliability == ReliabilityPolicy.RELIABLE, OUTPUT_QOS.depth)
        return dict.fromkeys(tuple(spec.topic for spec in OUTPUTS) + (
            topics.CLOCK_TOPIC, topics.DIAGNOSTICS_TOPIC), qos)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response):
        """``reset``: restart from t = 0 with the current (incl. pending) parameter values."""
        with self._pacer.executor_at_normal_priority():
            return self._reset(response)

    def _reset(self, response: Trigger.Response):
        log = self.get_logger()
        try:
            cfg = SimConfig.from_dict(self._parameter_values())
            self._check_lockstep(cfg)
            TrainSimulator(cfg).advance(1)     # what cannot run fails before anything changed
            self._resets += 1
            writer = self._open_bag(cfg, first=False)
        except Exception as exc:  # noqa: BLE001 - e.g. the new bag cannot be created
            response.success = False
            reason = ros_parameters.rejection_reason(exc)
            response.message = f'reset refused, nothing changed: {reason}'
            log.error(f'reset service: {response.message}')
            return response
        with self._lock.held():
            pending = self._pending_changes(cfg)
            old = self._outputs.take_writer()
            self._start(cfg, writer)
        if old is not None:
            self._closed_bag(old, log)
        rec = f'; recording to {writer.path}' if writer else ''
        response.success = True
        response.message = ('restarted from t = 0 ' + (f'with the pending changes {pending}'
                            if pending else '(no pending parameter changes)') + rec)
        log.info(f'reset service: {response.message}')
        return response

    # -- diagnostics -----------------------------------------------------------------------
    def _diagnostics_timer(self, period: float):
        """Return a timer publishing /diagnostics every ``period`` wall seconds (steady clock)."""
        return self.create_timer(period, shutdown_safe(self, self._publish_diagnostics),
                                 clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _publish_diagnostics(self) -> None:
        pending = self.pending_changes()
        with self._lock.held():
            now = time.monotonic()
            sim_report = self._simulation_report(now, pending)
            in_report = self._input_report(now)
            brake_report = self._brake_system_report()
        run_metrics = self._outputs.metrics.diagnostic()     # its own lock: not the sim's
        msg = diagnostic_array(sim_report, in_report, self.get_fully_qualified_name(),
                               self.get_clock().now().to_msg(), run_metrics, brake_report)
        try:
            self._pub_diag.publish(msg)
        except Exception:  # noqa: BLE001 - shutting down
            return
        if self._control.lockstep:
            return   # not in the bag: a lock-step bag holds only what the loop determines
        with self._lock.held():
            self._outputs.record(topics.DIAGNOSTICS_TOPIC, topics.DIAGNOSTIC_ARRAY,
                                 time_ns(self._pacer.sim.t), serialize_message(msg))

    def _simulation_report(self, now: float, pending: str) -> SimulationReport:
        """Return the simulation's state (simulation lock held)."""
        pacer, cfg, writer = self._pacer, self._cfg, self._outputs.writer
        sim = pacer.sim
        report = SimulationReport(
            t=sim.t, steps=sim.steps, n=sim.n, fault=sim.fault, finished=pacer.finished,
            behind=pacer.behind, real_time_factor=pacer.real_time_factor,
            achieved=pacer.measure_rtf(now), lag_dropped=pacer.lag_dropped,
            lag_events=pacer.lag_events, model_type=cfg.model_type,
            scale_factor=cfg.scale_factor, h=sim.h, rate=self._outputs.rate,
            duration=pacer.duration, behind_warn=BEHIND_WARN, pending=pending,
            integration=sim.integration_stats, control=self._control.report(),
            waiting=self._control.waiting(now),
            parameter_file_warning='; '.join(self.parameter_file_warnings),
            scheduling=pacer.scheduling, cpu_wake_latency=pacer.cpu_wake_latency)
        if writer is not None:
            report.recording, report.recorded = str(writer.path), writer.written
            report.backlog, report.record_error = writer.backlog, writer.error
            report.backlog_bytes = writer.backlog_bytes
        return report

    def _brake_system_report(self) -> BrakeSystemReport | None:
        """Return the EP / ECP and radio state (simulation lock held); None: neither."""
        sim = self._pacer.sim
        pneu = sim.pneu
        if pneu is None or (pneu.brake_system == 'pneumatic' and not sim.remotes):
            return None
        valves = pneu.valve_state
        return BrakeSystemReport(
            system=pneu.brake_system, train_line=pneu.train_line,
            head_command=pneu.ep_command, vehicle_command=pneu.ep_command_at_vehicles,
            filling=int(np.sum(valves > 0.5)), lapped=int(np.sum(np.abs(valves) < 0.5)),
            venting=int(np.sum(valves < -0.5)),
            remotes=', '.join(topics.vehicle_names(sim.remotes)), radio_ok=pneu.radio_ok,
            radio_age=pneu.radio_age, radio_sent=pneu.radio_sent, radio_lost=pneu.radio_lost,
            radio_received=pneu.radio_received)

    def _input_report(self, now: float) -> InputReport:
        """Return the brake inputs' state (simulation lock held)."""
        inputs = self._inputs
        return InputReport(
            mode=self._running.brake_input, timeout=inputs.timeout, on_timeout=inputs.on_timeout,
            max_age=inputs.max_age(now), stale=inputs.stale, emergency=inputs.emergency,
            stale_names=', '.join(inputs.stale_names), accepted=inputs.accepted,
            rejected=dict(inputs.rejected), last_rejected=inputs.last_rejected,
            wrong_type={k: list(v) for k, v in inputs.wrong_type.items()},
            multiple_publishers=dict(inputs.multiple_publishers), late=inputs.late)

    # -- public, read-only -----------------------------------------------------------------
    @property
    def finished(self) -> bool:
        """Return True once ``duration`` is reached (or a fault ended a run with it)."""
        return self._pacer.finished

    @property
    def exit_code(self) -> int:
        """Return the exit status: 0; 3 numerical fault; 4 lock-step timeout; 1 failed record."""
        writer = self._outputs.writer if hasattr(self, '_outputs') else None
        if self._pacer.exit_code == 0 and (self._record_failed or (
                writer is not None and writer.error is not None)):
            return EXIT_RECORD_FAILED
        return self._pacer.exit_code

    @property
    def simulator(self) -> TrainSimulator:
        """Return the simulator of the current run."""
        return self._pacer.sim

    @property
    def sim_time(self) -> float:
        """Return the simulation time [s]."""
        return self._pacer.sim.t

    @property
    def fault(self) -> str | None:
        """Return the numerical fault that stopped the run, or None."""
        return self._pacer.sim.fault

    @property
    def bag_path(self):
        """Return the path of the bag being recorded, or None."""
        w = self._outputs.writer
        return None if w is None else w.path

    def destroy_node(self) -> None:
        """Stop the simulation thread, finish the bag, then destroy the node."""
        if not self._destroyed and hasattr(self, '_pacer'):
            self._destroyed = True
            self._pacer.stop_thread()
            if self._pacer.executor_tid == threading.get_native_id():
                normal_priority()      # finishing the bag and shutting down: no hurry
            if getattr(self, '_wake_latency', None) is not None:
                self._wake_latency.release()
            writer = self._outputs.take_writer()
            if writer is not None:
                # After SIGINT/SIGTERM the context is gone: log without /rosout.
                log = self.get_logger() if self.context.ok() else rclpy.logging.get_logger(
                    f'{self.get_name()}.shutdown')
                self._closed_bag(writer, log)
        super().destroy_node()

    def _closed_bag(self, writer: BagWriter, log: Any) -> None:
        """Close a bag; report what it holds, or its failure (then the exit status is 1)."""
        writer.close()
        if writer.error is None:
            log.info(writer.closed_message())
        else:
            self._record_failed = True
            log.error(writer.closed_message())


def main(args: list[str] | None = None) -> int:
    """
    Run ``ros2 run train_dynamics sim_node``; SIGINT/SIGTERM stop it with the bag closed.

    Exit status: 0, 2 invalid parameters, 3 numerical fault (with ``duration``), 4 lock-step
    timeout (``lockstep_on_timeout`` stop) or refused, 1 other errors (a recording that failed
    included).
    """
    def create() -> SimNode:
        node = SimNode()
        # this thread spins the executor: it follows the simulation thread's priority (pacing)
        node._pacer.executor_tid = threading.get_native_id()
        freeze_startup_heap()       # no full garbage collection of start-up's objects later
        return node

    return run_node('sim_node', create, args, node_name=NODE_NAME, specs=SPECS, summary=(
        'The train_dynamics simulator: longitudinal dynamics of a braking train, real time or '
        'any real_time_factor, outputs couplers, coaches, brake_cylinders, /diagnostics.'),
        exits=(
        ExitOn((ConfigError, ParameterException, FileExistsError, ValueError),
               'invalid parameters', 2),
        ExitOn((BagError, OSError), 'cannot record', 1)))


if __name__ == '__main__':
    sys.exit(main())
