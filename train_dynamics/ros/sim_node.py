"""``sim_node``: the real-time ROS 2 node (node name ``train_dynamics``) around the physics core.

A thin wrapper: parameters, topics, pacing, recording. The model is
:class:`train_dynamics.physics.train.TrainSimulator`, the same class the offline command runs.

Inputs (``sensor_msgs/FluidPressure``, ABSOLUTE Pa; gauge = absolute - ``atmospheric_pressure``),
relative names, subscribed best-effort keep-last 10 so that reliable and best-effort publishers
both connect:

- ``brake_pipe/pressure`` (``brake_input`` = ``pipe_head``),
- ``coach_<i>/brake_pipe/pressure`` (``pipe_per_coach``), ``coach_<i>/brake_cylinder/pressure``
  (``cylinder_per_coach``), i = 1..N.

A message takes effect at the next integration step (zero-order hold). Rejected and counted per
reason in ``/diagnostics`` (with a throttled warning naming the topic): ``non_finite`` (NaN,
+-inf), ``negative`` (absolute pressure < 0), ``too_high`` (absolute pressure >
:data:`MAX_ABSOLUTE_PRESSURE` = 20 bar), ``wrong_mode`` (a topic of another ``brake_input``),
``unknown_coach`` (``coach_<i>`` with i outside 1..N), ``malformed`` (not deserialisable). The
head topic and the per-coach topics of the active mode are subscribed from the start; topics of
the other modes and of coaches that do not exist are found by a graph scan every
:data:`GRAPH_SCAN_PERIOD` s and subscribed then (only to count and reject their messages:
keeping 2N idle subscriptions would slow rclpy's executor for long trains).

Outputs (reliable, keep-last 10, ``header.stamp`` = simulation time), at ``publish_rate`` in
simulation time, at the integration steps nearest to k / publish_rate:

- ``couplers``: JointState ``coupler_1..N-1``: position y [m], velocity ydot [m/s], effort F [N];
- ``coaches``: JointState ``coach_1..N``: position x [m], velocity v [m/s], effort Fb [N];
- ``brake_cylinders``: JointState ``coach_1..N``: position = brake-cylinder gauge pressure [Pa],
  effort = local brake-pipe gauge pressure [Pa] (as the offline command writes);
- ``/clock`` (``rosgraph_msgs/Clock``) when ``publish_clock``;
- ``/diagnostics`` (~1 Hz wall): status ``train_dynamics: simulation`` (real-time factor and the
  achieved one, sim time, steps, lag, integrator health, pending parameter changes, recording)
  and ``train_dynamics: brake input`` (input age, staleness, emergency, rejected counts).

Pacing: a dedicated thread advances the simulator in whole integration steps so that simulation
time = start + ``real_time_factor`` * (wall time since start); each step is computed when its
wall time arrives (at most every :data:`MIN_SLEEP` s) and outputs are published the moment
their wall time arrives. Behind schedule it catches up as fast as it can (warning after
:data:`BEHIND_WARN` s); more than :data:`MAX_LAG` s behind, it stops catching up: the pacing
restarts from the current state, the dropped wall time is counted (``lag_dropped_s``) and
logged, and the simulation then runs that much behind the wall clock. ``real_time_factor`` 0:
as fast as possible, in chunks of at most :data:`CHUNK_BUDGET` s so that subscriptions,
parameters and services stay responsive.

Parameters: every parameter of :data:`train_dynamics.physics.parameters.PARAMETERS` plus the node's own
(:data:`NODE_PARAMETERS`): ``duration`` (simulation seconds after which the node stops by
itself, 0 = forever), ``wait_for_input`` (hold t = 0 until the brake-input topics have
publishers, at most that many wall seconds) and ``record_flush_period``. Invalid values are
rejected with a reason and change nothing. ``model_type``, ``scale_factor``,
``real_time_factor``, ``publish_clock``, ``input_timeout``, ``on_input_timeout`` and
``duration`` act at once (the state is untouched). Every other (structural) parameter is
accepted as PENDING: it is stored, logged as pending and applied by the ``reset`` service
(``~/reset``, i.e. ``/train_dynamics/reset``, ``std_srvs/srv/Trigger``), which restarts the
scenario from t = 0 with the current parameter values and says in its response (and the log)
what changed.

Stale inputs: ``input_timeout`` > 0 s (wall) without a brake input (any coach of a per-coach
mode) is reported in ``/diagnostics``; ``on_input_timeout`` ``hold`` keeps the last values,
``emergency`` applies the fail-safe (head pipe vented / all pipe pressures 0 gauge / all
cylinders at ``max_cylinder_pressure``) until every input is fresh again.

Numerical fault (``sim.fault``): integration stops, the last good state stays, an ERROR
diagnostic and an error log line say why, the recording stays intact, ``reset`` recovers. With
``duration`` set the node then exits (status 3) instead of waiting forever.

``record_bag``: inputs (raw CDR as received, bag time = simulation time of the step at which the
message took effect, so ``train-dynamics simulate --input BAG`` replays the run) and outputs
(bag time = header stamp) go to a rosbag2 (MCAP) written on a separate thread. The MCAP file is
finished every ``record_flush_period`` s (wall): a SIGKILL loses at most that much; SIGINT and
SIGTERM close the bag completely. A ``reset`` continues in a new bag ``<record_bag>_reset<k>``
(each bag is one run from t = 0). Only accepted inputs are recorded, plus the fail-safe
pressures the node applies on a stale input (``frame_id`` ``train_dynamics/input_timeout``).
"""
from __future__ import annotations

import contextlib
import functools
import math
import os
import queue
import re
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import rclpy
import rclpy.logging
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import FluidPressure, JointState
from std_srvs.srv import Trigger

from train_dynamics.recording import bags as bagio
from train_dynamics.recording.bags import BagError
from train_dynamics.physics.parameters import (BOOL, DOUBLE, DOUBLE_ARRAY, INTEGER, PARAMETERS, STRING,
                                   ConfigError, SimConfig, validate_value)
from train_dynamics import topics
from train_dynamics.physics.runner import end_step, output_step
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import OutputEncoder, parameters_json, run_metadata, time_ns

__all__ = ['SimNode', 'main', 'make_executor', 'INPUT_QOS', 'OUTPUT_QOS', 'MAX_ABSOLUTE_PRESSURE',
           'REJECT_REASONS', 'NODE_PARAMETERS']

NODE_NAME = 'train_dynamics'

#: Inputs above this ABSOLUTE pressure [Pa] (20 bar) are rejected as implausible.
MAX_ABSOLUTE_PRESSURE = 2.0e6
#: Reasons an input message is rejected (keys of the counts in /diagnostics).
REJECT_REASONS = ('non_finite', 'negative', 'too_high', 'wrong_mode', 'unknown_coach',
                  'malformed')

MIN_SLEEP = 0.001        # [s wall] shortest pause between two pacing iterations
CHUNK_BUDGET = 0.005     # [s wall] longest stretch the simulation thread integrates in one go
BEHIND_WARN = 0.05       # [s wall] behind schedule by more: throttled warning
MAX_LAG = 1.0            # [s wall] behind schedule by more: stop catching up (drop the lag)
WARN_PERIOD = 5.0        # [s wall] throttle of repeated warnings
DIAGNOSTICS_PERIOD = 1.0  # [s wall]
GRAPH_SCAN_PERIOD = 2.0  # [s wall] search for input topics of other modes / unknown coaches
MAX_EXTRA_SUBSCRIPTIONS = 256   # cap on the subscriptions made by the graph scan
INPUT_SETTLE = 0.3       # [s wall] wait_for_input: pause after the inputs are connected
MAX_RECORD_BACKLOG = 20000       # messages queued for the bag writer before the simulation waits

INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)
OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)

HEAD, PIPE, CYL = 'pipe_head', 'pipe_per_coach', 'cylinder_per_coach'
HEAD_TOPIC = 'brake_pipe/pressure'
_FAMILY_TOPIC = {PIPE: 'coach_{i}/brake_pipe/pressure', CYL: 'coach_{i}/brake_cylinder/pressure'}
_COACH_TOPIC_RE = re.compile(r'coach_(\d+)/brake_(pipe|cylinder)/pressure')
JOINT_STATE = 'sensor_msgs/msg/JointState'
FLUID_PRESSURE = 'sensor_msgs/msg/FluidPressure'

#: The node's own parameters (not part of the simulator configuration):
#: name -> (default, description, min, max).
NODE_PARAMETERS: dict[str, tuple[float, str, float, float]] = {
    'duration': (0.0, 'Simulation time [s] after which the node stops by itself (outputs up to '
                      'and including t = duration); 0 = run until shut down. Changeable while '
                      'running.', 0.0, 1.0e9),
    'wait_for_input': (0.0, 'Before the simulation clock starts (and after each reset), wait up '
                            'to this many wall seconds until a publisher is connected to every '
                            'brake-input topic of brake_input (the state stays at t = 0 '
                            'meanwhile); 0 = start at once.', 0.0, 3600.0),
    'record_flush_period': (10.0, 'Wall-clock period [s] at which the record_bag MCAP file is '
                                  'finished and a new one started: a SIGKILL loses at most this '
                                  'much of the recording.', 0.1, 3600.0),
}

_LIVE = ('model_type', 'scale_factor', 'real_time_factor', 'publish_clock', 'input_timeout',
         'on_input_timeout')


def make_executor(context=None):
    """The executor ``main`` spins: rclpy's (experimental) EventsExecutor where available, else
    (or with ``TRAIN_DYNAMICS_EXECUTOR=single``) a SingleThreadedExecutor.

    Measured here: the SingleThreadedExecutor rebuilds its wait set in Python on every wake-up,
    so with the 300 subscriptions of a 300-coach per-coach input it manages ~30 callbacks/s;
    the EventsExecutor's cost does not grow with the number of entities. Spin it from one
    thread with ``spin_once`` (its ``spin()`` in a background thread deadlocks with entity
    creation in another thread in rclpy 7.1).
    """
    if os.environ.get('TRAIN_DYNAMICS_EXECUTOR', '').lower() != 'single':
        try:
            from rclpy.experimental import EventsExecutor
        except ImportError:   # pragma: no cover - older rclpy
            pass
        else:
            return EventsExecutor(context=context)
    return rclpy.executors.SingleThreadedExecutor(context=context)


def _stamp(t_ns: int) -> Time:
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f'{value:g}'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_fmt(v) for v in value) + ']'
    return repr(value) if isinstance(value, str) else str(value)


def _descriptor(name: str) -> ParameterDescriptor:
    """ParameterDescriptor (type, description, range, choices) of a simulator parameter."""
    spec = PARAMETERS[name]
    ptype = {DOUBLE: ParameterType.PARAMETER_DOUBLE, INTEGER: ParameterType.PARAMETER_INTEGER,
             STRING: ParameterType.PARAMETER_STRING, BOOL: ParameterType.PARAMETER_BOOL,
             DOUBLE_ARRAY: ParameterType.PARAMETER_DOUBLE_ARRAY}[spec.kind]
    when = ('changeable while running' if name in _LIVE
            else 'structural: pending until the reset service is called')
    constraints = []
    if spec.choices:
        constraints.append('one of: ' + ', '.join(spec.choices))
    if spec.min is not None:
        constraints.append(('> ' if spec.min_exclusive else '>= ') + f'{spec.min:g}')
    if spec.max is not None:
        constraints.append(f'<= {spec.max:g}')
    if spec.kind == DOUBLE_ARRAY and constraints:
        constraints[0] = 'every element ' + constraints[0]
    d = ParameterDescriptor(name=name, type=ptype, description=f'{spec.description} ({when})',
                            additional_constraints=', '.join(constraints), read_only=False)
    if spec.kind == DOUBLE and spec.min is not None and spec.max is not None:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.min),
                                                     to_value=float(spec.max), step=0.0)]
    elif spec.kind == INTEGER and spec.min is not None and spec.max is not None:
        d.integer_range = [IntegerRange(from_value=int(spec.min), to_value=int(spec.max), step=1)]
    return d


def _as_double(param: Parameter, kind: str) -> Parameter:
    """An integer given for a double (array) parameter as a double; an empty array of any type
    for a double array (``ros2 param set`` sends ``[]`` as a bool array)."""
    t = param.type_
    if kind == DOUBLE and t == Parameter.Type.INTEGER:
        return Parameter(param.name, Parameter.Type.DOUBLE, float(param.value))
    if kind == DOUBLE_ARRAY and t in (Parameter.Type.INTEGER_ARRAY, Parameter.Type.BOOL_ARRAY,
                                      Parameter.Type.BYTE_ARRAY, Parameter.Type.STRING_ARRAY):
        values = list(param.value)
        if t == Parameter.Type.INTEGER_ARRAY or not values:
            return Parameter(param.name, Parameter.Type.DOUBLE_ARRAY, [float(v) for v in values])
    return param


def _param_kind(name: str) -> str | None:
    if name in PARAMETERS:
        return PARAMETERS[name].kind
    if name in NODE_PARAMETERS:
        return DOUBLE
    return None


class _Throttle:
    """At most one message per key and period; counts what it suppressed."""

    def __init__(self, period: float = WARN_PERIOD) -> None:
        self.period = period
        self._last: dict[Any, float] = {}
        self._suppressed: dict[Any, int] = {}

    def __call__(self, key: Any, now: float) -> int | None:
        """None to stay quiet, else the number of suppressed occurrences since the last one."""
        last = self._last.get(key)
        if last is not None and now - last < self.period:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return None
        self._last[key] = now
        return self._suppressed.pop(key, 0)


class _BagWriter:
    """Writes recorded messages to a BagRecorder on its own thread (bag I/O never delays the
    simulation); finishes the MCAP file every ``flush_period`` s of wall time."""

    def __init__(self, recorder, logger, flush_period: float) -> None:
        self.recorder = recorder
        self.path = Path(recorder.path)
        self.written = 0
        self.error: str | None = None
        self._logger = logger
        self._flush_period = float(flush_period)
        # Bounded: when the disk cannot keep up, the simulation waits (and says it is behind)
        # rather than the queue eating the memory.
        self._q: queue.Queue = queue.Queue(maxsize=MAX_RECORD_BACKLOG)
        self._known: set[str] = set()
        self._thread = threading.Thread(target=self._run, name='train_dynamics_bag',
                                        daemon=True)
        self._thread.start()

    def write(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        """Queue raw CDR bytes."""
        self._q.put((topic, msgtype, t_ns, data))

    @property
    def backlog(self) -> int:
        return self._q.qsize()

    def close(self, timeout: float | None = 30.0) -> None:
        """Write what is queued, finish the bag (idempotent)."""
        if self._thread.is_alive():
            self._q.put(None)
            self._thread.join(timeout)

    def _run(self) -> None:
        rec = self.recorder
        last_flush = time.monotonic()
        unflushed = False
        try:
            while True:
                try:
                    item = self._q.get(timeout=0.5)
                except queue.Empty:
                    item = ()
                if item is None:
                    break
                if item and self.error is None:
                    topic, msgtype, t_ns, data = item
                    try:
                        if topic not in self._known:
                            rec.add_topic(topic, msgtype)
                            self._known.add(topic)
                        rec.write(topic, t_ns, data)
                        self.written += 1
                        unflushed = True
                    except Exception as exc:  # noqa: BLE001 - disk full, closed bag, ...
                        self.error = f'{type(exc).__name__}: {exc}'.splitlines()[0]
                        self._logger.error(f'recording to {self.path} failed: {self.error}; '
                                           'no further messages are recorded')
                now = time.monotonic()
                if unflushed and self.error is None and now - last_flush >= self._flush_period:
                    try:
                        rec.flush()
                    except Exception as exc:  # noqa: BLE001
                        self.error = f'{type(exc).__name__}: {exc}'.splitlines()[0]
                        self._logger.error(f'recording to {self.path} failed: {self.error}')
                    last_flush, unflushed = now, False
        finally:
            try:
                rec.close()
            except Exception as exc:  # noqa: BLE001
                self._logger.error(f'closing the bag {self.path} failed: {exc}')


class SimNode(Node):
    """The simulator node (``train_dynamics``); see the module documentation."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(NODE_NAME, **kwargs)
        self._lock = threading.Lock()        # simulator, pacing, outputs, recorder
        self._in_lock = threading.Lock()     # input buffers (subscription callbacks)
        self._waiting = 0                    # other threads waiting for self._lock
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._warn_throttle = _Throttle()
        self._destroyed = False
        self._writer: _BagWriter | None = None
        self._resets = 0

        self._declare_parameters()
        values = self._parameter_values()
        cfg = SimConfig.from_dict(values)          # raises ConfigError (main reports it)
        self._duration = float(self.get_parameter('duration').value)
        self._wait_for_input = float(self.get_parameter('wait_for_input').value)
        self._flush_period = float(self.get_parameter('record_flush_period').value)
        if cfg.record_bag:
            self._check_bag_path(cfg.record_bag)

        # Publishers (outputs) and the reset service.
        self._pub_outputs = [self.create_publisher(JointState, topic, OUTPUT_QOS)
                             for topic in topics.OUTPUT_TOPICS]
        self._pub_clock = self.create_publisher(Clock, topics.CLOCK_TOPIC, OUTPUT_QOS)
        self._pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', OUTPUT_QOS)
        self._reset_srv = self.create_service(Trigger, '~/reset', self._on_reset)

        # Inputs: the active mode's topics and the head topic; others via the graph scan.
        self._subs: dict[str, Any] = {}            # resolved topic name -> subscription
        self._sub_info: dict[str, tuple[str, str | None, int | None]] = {}
        self._accepted = 0
        self._rejected = {r: 0 for r in REJECT_REASONS}
        self._last_rejected = ''

        self._lag_dropped = 0.0
        self._lag_events = 0
        self._achieved_rtf = float('nan')
        self._start(cfg, self._make_writer(cfg, first=True), first=True)
        self.add_pre_set_parameters_callback(self._coerce_parameters)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._diag_timer = self.create_timer(DIAGNOSTICS_PERIOD, self._publish_diagnostics)
        self._scan_timer = self.create_timer(GRAPH_SCAN_PERIOD, self._scan_graph)
        self._thread = threading.Thread(target=self._run, name='train_dynamics_sim', daemon=True)
        self._thread.start()

    # ===================================================================== parameters ====
    def _declare_parameters(self) -> None:
        overrides = getattr(self, '_parameter_overrides', None)
        for name, spec in PARAMETERS.items():
            if isinstance(overrides, dict) and name in overrides:
                # An integer in a parameter file for a double (the offline command accepts it).
                overrides[name] = _as_double(overrides[name], spec.kind)
            descriptor = _descriptor(name)
            if spec.kind == DOUBLE_ARRAY:
                self.declare_parameter(name, Parameter.Type.DOUBLE_ARRAY, descriptor)
                try:
                    self.get_parameter(name)
                except ParameterUninitializedException:
                    self.set_parameters([Parameter(name, Parameter.Type.DOUBLE_ARRAY,
                                                   list(spec.default))])
            else:
                self.declare_parameter(name, spec.default, descriptor)
        for name, (default, description, lo, hi) in NODE_PARAMETERS.items():
            if name in PARAMETERS:      # pragma: no cover - if the core ever declares it
                continue
            if isinstance(overrides, dict) and name in overrides:
                overrides[name] = _as_double(overrides[name], DOUBLE)
            self.declare_parameter(name, float(default), ParameterDescriptor(
                name=name, type=ParameterType.PARAMETER_DOUBLE, description=description,
                additional_constraints=f'>= {lo:g}, <= {hi:g}',
                floating_point_range=[FloatingPointRange(from_value=lo, to_value=hi,
                                                         step=0.0)]))

    def _parameter_values(self) -> dict[str, Any]:
        out = {}
        for name, spec in PARAMETERS.items():
            value = self.get_parameter(name).value
            out[name] = list(value) if spec.kind == DOUBLE_ARRAY else value
        return out

    def _coerce_parameters(self, params: list[Parameter]) -> list[Parameter]:
        out = []
        for p in params:
            kind = _param_kind(p.name)
            out.append(_as_double(p, kind) if kind in (DOUBLE, DOUBLE_ARRAY) else p)
        return out

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate the whole batch; apply live parameters, keep structural ones pending."""
        changes: dict[str, Any] = {}
        node_changes: dict[str, float] = {}
        try:
            for p in params:
                if p.name in NODE_PARAMETERS:     # (also if the core ever lists them)
                    value = p.value
                    _, _, lo, hi = NODE_PARAMETERS[p.name]
                    if isinstance(value, bool) or not isinstance(value, (int, float)) \
                            or not math.isfinite(value) or not lo <= value <= hi:
                        raise ConfigError(f'{p.name}: must be a number in [{lo:g}, {hi:g}], '
                                          f'got {value!r}')
                    node_changes[p.name] = float(value)
                    if p.name in PARAMETERS:
                        changes[p.name] = validate_value(p.name, value)
                elif p.name in PARAMETERS:
                    changes[p.name] = validate_value(p.name, p.value)
            candidate = SimConfig.from_dict({**self._parameter_values(), **changes})
            if 'record_bag' in changes and changes['record_bag'] \
                    and changes['record_bag'] != self._cfg.record_bag:
                self._check_bag_path(changes['record_bag'])
        except (ConfigError, FileExistsError) as exc:
            reason = str(exc)
            self.get_logger().warning(f'parameter change rejected: {reason}')
            return SetParametersResult(successful=False, reason=reason)

        with self._locked():
            if 'model_type' in changes or 'scale_factor' in changes:
                self._sim.set_model(candidate.model_type, candidate.scale_factor)
                self._cfg.values['model_type'] = candidate.model_type
                self._cfg.values['scale_factor'] = candidate.scale_factor
                self.get_logger().info(
                    f't = {self._sim.t:.3f} s: coupler model {candidate.model_type}, '
                    f'scale_factor {candidate.scale_factor:g} s/m')
            if 'real_time_factor' in changes:
                self._cfg.values['real_time_factor'] = candidate.real_time_factor
                self._anchor(time.monotonic())
                self._wake.set()
            for name in ('publish_clock', 'input_timeout', 'on_input_timeout'):
                if name in changes:
                    self._cfg.values[name] = changes[name]
            if 'duration' in node_changes:
                self._duration = node_changes['duration']
                self._update_end_step()
                if self._finished and self._end_step > self._sim.steps:
                    self._finished = False
                self._wake.set()
            if 'wait_for_input' in node_changes:
                self._wait_for_input = node_changes['wait_for_input']
            if 'record_flush_period' in node_changes:
                self._flush_period = node_changes['record_flush_period']
        pending = self._pending_changes(candidate)
        reason = ''
        structural = [n for n in changes if n not in _LIVE and n not in NODE_PARAMETERS]
        if structural:
            reason = ('pending until the reset service is called: '
                      + ', '.join(f'{n} = {_fmt(changes[n])}' for n in structural))
            self.get_logger().info(f'parameter change accepted, {reason} '
                                   f'(all pending: {pending or "none"})')
        return SetParametersResult(successful=True, reason=reason)

    def _pending_changes(self, cfg: SimConfig | None = None) -> str:
        """'name: old -> new, ...' for parameter values the running simulation does not use."""
        if cfg is None:
            try:
                cfg = SimConfig.from_dict(self._parameter_values())
            except ConfigError:    # pragma: no cover - parameters are validated as a whole
                return '?'
        running = self._cfg.values
        diffs = [f'{n}: {_fmt(running[n])} -> {_fmt(v)}' for n, v in cfg.values.items()
                 if n not in _LIVE and n not in NODE_PARAMETERS and running.get(n) != v]
        return ', '.join(diffs)

    @staticmethod
    def _check_bag_path(path: str) -> None:
        p = Path(path)
        if p.exists() or p.is_symlink():
            raise FileExistsError(f'record_bag: {path} exists already, not overwriting')

    # ======================================================== start / reset (locked) ====
    def _start(self, cfg: SimConfig, writer: '_BagWriter | None', first: bool = False) -> None:
        """(Re)build the simulator for ``cfg`` at t = 0; caller holds the lock (or __init__)."""
        self._cfg = cfg
        # Warm-up on a throw-away copy: loads the compiled kernels (numba cache) now, not in
        # the first real-time step.
        TrainSimulator(cfg).advance(1)
        self._sim = TrainSimulator(cfg)
        self._writer = writer
        n = self._sim.n
        self._h = self._sim.h
        self._rate = float(cfg.publish_rate)
        self._atm = float(cfg.atmospheric_pressure)
        self._mode = cfg.brake_input
        self._finished = False
        self._exit_code = 0
        self._fault_reported = False
        self._pub_index = 0
        self._next_pub_step = 0
        self._update_end_step()
        self._behind = 0.0
        self._step_cost = 1e-5            # [s wall per step], running estimate
        self._rtf_window = (time.monotonic(), 0.0)
        # Output messages are CDR-encoded once per output (names and header layout computed
        # once), then published and recorded as the same bytes: ~10x cheaper than filling
        # JointState objects whose N names rclpy converts again on every publish (the sim
        # thread holds the GIL meanwhile: output jitter).
        self._encoder = OutputEncoder(n)
        # Inputs: latest accepted gauge values per slot (head: 1 slot; per coach: N slots),
        # starting from the simulator's initial inputs (charged pipe, empty cylinders).
        slots = 1 if self._mode == HEAD else n
        default = 0.0 if self._mode == CYL else float(cfg.pipe_nominal_pressure)
        with self._in_lock:
            self._in_default = np.full(slots, default)
            self._in_value = self._in_default.copy()
            self._in_raw: list[bytes | None] = [None] * slots
            self._in_topic = ([HEAD_TOPIC] if self._mode == HEAD else
                              [_FAMILY_TOPIC[self._mode].format(i=i) for i in range(1, n + 1)])
            self._in_arrival = np.full(slots, time.monotonic())
            self._in_dirty = False
            self._in_record: list[tuple[str, bytes]] = []
        self._emergency = False
        self._stale = False
        self._stale_names: list[str] = []
        self._stale_count = 0
        self._update_subscriptions()
        self._anchor(time.monotonic())
        self._need_anchor = True          # again after the first output (first publish is slow)
        self._wait_since: float | None = None
        where = f'; recording to {writer.path.resolve()}' if writer else ''
        rtf = cfg.real_time_factor
        self.get_logger().info(
            f'{"started" if first else "reset"}: {n} coaches, brake_input {self._mode}, '
            f'{cfg.model_type} model (scale_factor {cfg.scale_factor:g} s/m), step '
            f'{self._h:g} s, outputs at {self._rate:g} Hz, real_time_factor '
            f'{rtf:g}{" (as fast as possible)" if rtf == 0 else ""}'
            f'{f", duration {self._duration:g} s" if self._duration > 0 else ""}{where}')

    def _update_end_step(self) -> None:
        d = self._duration
        self._end_step = end_step(d, self._h) if d > 0 else None

    def _make_writer(self, cfg: SimConfig, first: bool) -> '_BagWriter | None':
        """A recorder for ``cfg.record_bag`` (after a reset: the first free
        ``<record_bag>_reset<k>``); None when not recording. Raises if the bag cannot be made."""
        base = cfg.record_bag
        if not base:
            return None
        from train_dynamics.recording.bags import BagRecorder

        path = Path(base)
        if not first:
            k = self._resets
            while True:
                path = Path(f'{str(base).rstrip("/")}_reset{k}')
                if not (path.exists() or path.is_symlink()):
                    break
                k += 1
        rec = BagRecorder(path)
        try:
            info = run_metadata(cfg, 'sim_node', node=self.get_fully_qualified_name(),
                                parameters=parameters_json(cfg))
            for key, value in info.items():
                rec.set_custom_data(key, value)
            for topic in topics.OUTPUT_TOPICS:
                rec.add_topic(topic, topics.JOINT_STATE)
        except Exception:
            rec.abort()
            raise
        return _BagWriter(rec, self.get_logger(), self._flush_period)

    def _on_reset(self, request: Trigger.Request, response: Trigger.Response):
        """``reset``: restart from t = 0 with the current (incl. pending) parameter values."""
        try:
            cfg = SimConfig.from_dict(self._parameter_values())
            self._resets += 1
            writer = self._make_writer(cfg, first=False)
        except Exception as exc:  # noqa: BLE001 - e.g. the new bag cannot be created
            response.success = False
            response.message = f'reset refused, nothing changed: {exc}'
            self.get_logger().error(f'reset service: {response.message}')
            return response
        with self._locked():
            pending = self._pending_changes(cfg)
            old = self._writer
            self._start(cfg, writer)
            self._wake.set()
        if old is not None:
            old.close()
            self.get_logger().info(f'bag closed: {old.path} ({old.written} messages)')
        rec = f'; recording to {writer.path}' if writer else ''
        response.success = True
        response.message = ('restarted from t = 0 ' + (f'with the pending changes {pending}'
                            if pending else '(no pending parameter changes)') + rec)
        self.get_logger().info(f'reset service: {response.message}')
        return response

    @contextlib.contextmanager
    def _locked(self):
        """The simulator lock, for threads other than the simulation thread (which yields to
        them)."""
        self._waiting += 1
        try:
            self._lock.acquire()
        finally:
            self._waiting -= 1
        try:
            yield
        finally:
            self._lock.release()

    # ======================================================================== inputs ====
    def _update_subscriptions(self) -> None:
        """Subscriptions for the head topic and the active mode's per-coach topics."""
        wanted: dict[str, tuple[str, str | None, int | None]] = {
            HEAD_TOPIC: (HEAD_TOPIC, HEAD, None)}
        if self._mode != HEAD:
            for i in range(1, self._sim.n + 1):
                rel = _FAMILY_TOPIC[self._mode].format(i=i)
                wanted[rel] = (rel, self._mode, i - 1)
        wanted_resolved = {self.resolve_topic_name(rel): info for rel, info in wanted.items()}
        for name in list(self._subs):
            if self._sub_info[name] != wanted_resolved.get(name):
                self.destroy_subscription(self._subs.pop(name))
                del self._sub_info[name]
        for name, info in wanted_resolved.items():
            if name not in self._subs:
                self._subscribe(name, info)
        self._n_base_subs = len(wanted_resolved)

    def _subscribe(self, resolved: str, info: tuple[str, str | None, int | None]) -> None:
        rel, family, index = info
        cb = functools.partial(self._on_input, rel, resolved, family, index)
        self._subs[resolved] = self.create_subscription(FluidPressure, resolved, cb, INPUT_QOS,
                                                        raw=True)
        self._sub_info[resolved] = info

    def _scan_graph(self) -> None:
        """Subscribe to input topics of other modes and of coaches that do not exist, so that
        their messages are counted and rejected."""
        ns = self.get_namespace().rstrip('/') + '/'
        n = self._sim.n
        try:
            topics = self.get_topic_names_and_types()
        except Exception:  # noqa: BLE001 - shutting down
            return
        for name, types in topics:
            if name in self._subs or not name.startswith(ns) or FLUID_PRESSURE not in types:
                continue
            m = _COACH_TOPIC_RE.fullmatch(name[len(ns):])
            if m is None:
                continue
            if len(self._subs) - self._n_base_subs >= MAX_EXTRA_SUBSCRIPTIONS:
                return
            i = int(m.group(1))
            family = PIPE if m.group(2) == 'pipe' else CYL
            self._subscribe(name, (name[len(ns):], family if 1 <= i <= n else None, None))

    def _reject(self, rel: str, resolved: str, reason: str, detail: str) -> None:
        self._rejected[reason] += 1
        self._last_rejected = f'{resolved}: {reason}'
        suppressed = self._warn_throttle((resolved, reason), time.monotonic())
        if suppressed is not None:
            more = f' ({suppressed} more since the last warning)' if suppressed else ''
            self.get_logger().warning(f'rejected input on {resolved}: {detail}{more}')

    def _on_input(self, rel: str, resolved: str, family: str | None, index: int | None,
                  data: bytes) -> None:
        """A brake-input message (raw CDR): check it, store it for the next integration step."""
        if family is None:
            self._reject(rel, resolved, 'unknown_coach',
                         f'coach index outside 1..{self._sim.n} (unknown_coach)')
            return
        if family != self._mode:
            self._reject(rel, resolved, 'wrong_mode',
                         f'topic of brake_input {family}, the node runs {self._mode} '
                         '(wrong_mode)')
            return
        try:
            msg = deserialize_message(data, FluidPressure)
        except Exception as exc:  # noqa: BLE001
            self._reject(rel, resolved, 'malformed', f'cannot deserialise: {exc} (malformed)')
            return
        p = msg.fluid_pressure
        if not math.isfinite(p):
            self._reject(rel, resolved, 'non_finite', f'pressure {p} (non_finite)')
            return
        if p < 0.0:
            self._reject(rel, resolved, 'negative', f'absolute pressure {p:g} Pa < 0 (negative)')
            return
        if p > MAX_ABSOLUTE_PRESSURE:
            self._reject(rel, resolved, 'too_high', f'absolute pressure {p:g} Pa > '
                         f'{MAX_ABSOLUTE_PRESSURE:g} Pa (too_high)')
            return
        slot = 0 if index is None else index
        with self._in_lock:
            if slot >= len(self._in_value):     # pragma: no cover - raced with a reset
                return
            self._in_value[slot] = p - self._atm
            self._in_raw[slot] = bytes(data)
            self._in_arrival[slot] = time.monotonic()
            self._in_dirty = True
            if self._writer is not None:
                self._in_record.append((rel, bytes(data)))
        self._accepted += 1

    def _synthetic(self, gauge: float, frame_id: str) -> bytes:
        t_ns = int(round(self._sim.t * 1e9))
        msg = FluidPressure(fluid_pressure=float(gauge + self._atm), variance=0.0)
        msg.header.stamp = _stamp(t_ns)
        msg.header.frame_id = frame_id
        return serialize_message(msg)

    def _set_inputs(self, values: np.ndarray) -> None:
        sim = self._sim
        if self._mode == HEAD:
            sim.set_head_pipe_pressure(float(values[0]))
        elif self._mode == PIPE:
            sim.set_pipe_pressure(values)
        else:
            sim.set_cylinder_pressure(values)

    def _apply_inputs(self, now: float) -> None:
        """Inputs received since the last call (and the stale-input rule) into the simulator."""
        cfg = self._cfg
        timeout = float(cfg.input_timeout)
        with self._in_lock:
            dirty = self._in_dirty
            stale = False
            if timeout > 0.0:
                stale_idx = np.nonzero(now - self._in_arrival > timeout)[0]
                stale = stale_idx.size > 0
                if stale != self._stale or (stale and stale_idx.size != self._stale_count):
                    self._stale_names = [self._in_topic[k] for k in stale_idx[:10]]
                    if stale_idx.size > 10:
                        self._stale_names.append(f'... ({stale_idx.size} inputs)')
                    self._stale_count = stale_idx.size
            if not dirty and stale == self._stale and \
                    self._emergency == (stale and cfg.on_input_timeout == 'emergency'):
                return
            self._in_dirty = False
            values = self._in_value.copy()
            raws = list(self._in_raw)
            records, self._in_record = self._in_record, []
        t_ns = int(round(self._sim.t * 1e9))
        if stale != self._stale:
            self._stale = stale
            if stale:
                what = ', '.join(self._stale_names)
                self.get_logger().warning(
                    f'brake input stale: nothing for more than {timeout:g} s on {what}; '
                    + ('applying the emergency brake' if cfg.on_input_timeout == 'emergency'
                       else 'holding the last values'))
            else:
                self._stale_names = []
                self.get_logger().info('brake input fresh again')
        emergency = stale and cfg.on_input_timeout == 'emergency'
        if emergency:
            if not self._emergency:
                if self._mode == CYL:
                    fail = np.full(len(values), float(cfg.max_cylinder_pressure))
                else:
                    fail = np.zeros(len(values))
                self._set_inputs(fail)
                for k, topic in enumerate(self._in_topic):
                    self._record(topic, FLUID_PRESSURE, t_ns,
                                 self._synthetic(fail[k], 'train_dynamics/input_timeout'))
                self._emergency = True
            return       # inputs arriving meanwhile wait until every input is fresh
        if self._emergency:
            # Back from the fail-safe: the latest value of every input holds again.
            self._emergency = False
            self._set_inputs(values)
            for k, topic in enumerate(self._in_topic):
                raw = raws[k] if raws[k] is not None else self._synthetic(
                    self._in_default[k], 'train_dynamics/default')
                self._record(topic, FLUID_PRESSURE, t_ns, raw)
            return
        if dirty:
            self._set_inputs(values)
            for topic, raw in records:
                self._record(topic, FLUID_PRESSURE, t_ns, raw)

    # ====================================================================== outputs ====
    def _record(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        if self._writer is not None:
            self._writer.write(topic, msgtype, t_ns, data)

    def _publish(self) -> None:
        """Outputs of the present state (caller holds the lock)."""
        sim = self._sim
        t_ns = time_ns(sim.t)
        encoded = self._encoder.encode(t_ns, sim)
        for pub, data in zip(self._pub_outputs, encoded):
            pub.publish(data)
        clock = None
        if self._cfg.publish_clock:
            clock = Clock(clock=_stamp(t_ns))
            self._pub_clock.publish(clock)
        w = self._writer
        if w is not None:
            for topic, data in zip(topics.OUTPUT_TOPICS, encoded):
                w.write(topic, topics.JOINT_STATE, t_ns, data)
            if clock is not None:
                w.write(topics.CLOCK_TOPIC, topics.CLOCK_TYPE, t_ns, serialize_message(clock))

    def _pub_step(self, j: int) -> int:
        """Integration step of the j-th output, t_j = j / publish_rate."""
        return output_step(j, self._rate, self._h)

    def _publish_due(self) -> None:
        """Publish if the present step is an output step; move to the next output step."""
        steps = self._sim.steps
        if steps < self._next_pub_step:
            return
        self._publish()
        while self._next_pub_step <= steps:
            self._pub_index += 1
            self._next_pub_step = self._pub_step(self._pub_index)

    # ======================================================================= pacing ====
    def _anchor(self, now: float) -> None:
        self._anchor_wall = now
        self._anchor_sim = self._sim.steps * self._h

    def _wall_of_step(self, step: int) -> float:
        return self._anchor_wall + (step * self._h - self._anchor_sim) / \
            self._cfg.real_time_factor

    def _run(self) -> None:
        """The simulation thread."""
        log = self.get_logger()
        while not self._stop.is_set():
            try:
                with self._lock:
                    wake = self._iterate()
            except Exception as exc:  # noqa: BLE001
                if self._stop.is_set() or not self.context.ok():
                    break            # shut down under our feet (SIGINT/SIGTERM)
                log.error(f'simulation thread: {type(exc).__name__}: {exc}')
                with self._lock:
                    self._finished = True
                    self._exit_code = 1
                wake = time.monotonic() + 0.1
            if wake is None:
                if self._waiting:
                    time.sleep(0.0002)
                continue
            delay = wake - time.monotonic()
            if delay > 0:
                self._wake.wait(delay)
                self._wake.clear()
            elif self._waiting:
                time.sleep(0.0002)

    def _iterate(self) -> float | None:
        """One pacing iteration; returns the wall time to wake up at (None: at once)."""
        sim = self._sim
        now = time.monotonic()
        if self._finished or sim.fault is not None:
            with self._in_lock:
                self._in_record.clear()     # nothing acts any more: nothing to record
            return now + 0.1
        self._apply_inputs(now)
        self._publish_due()                 # t = 0 (and right after a reset)
        if self._need_anchor:
            if self._hold_for_input(now):
                return now + 0.02
            self._need_anchor = False
            now = time.monotonic()
            self._anchor(now)
            self._rtf_window = (now, sim.t)
        rtf = float(self._cfg.real_time_factor)
        if rtf > 0.0:
            target = int(math.floor(((now - self._anchor_wall) * rtf + self._anchor_sim)
                                    / self._h + 0.5))
            behind = now - self._wall_of_step(sim.steps + 1)
            if behind > MAX_LAG:
                self._lag_dropped += behind
                self._lag_events += 1
                self.get_logger().warning(
                    f'cannot keep up with real_time_factor {rtf:g}: {behind:.2f} s behind '
                    f'at t = {sim.t:.3f} s; dropping the lag (the simulation now runs '
                    f'{self._lag_dropped:.2f} s behind the wall clock in total; achieved rtf '
                    f'{self._achieved_rtf:.3g})', throttle_duration_sec=WARN_PERIOD)
                self._anchor(now)
                target = sim.steps + 1
            elif behind > BEHIND_WARN:
                self.get_logger().warning(
                    f'falling behind real time: {behind * 1000:.0f} ms behind schedule at '
                    f't = {sim.t:.3f} s (real_time_factor {rtf:g}, achieved '
                    f'{self._achieved_rtf:.3g}); catching up', throttle_duration_sec=WARN_PERIOD)
            self._behind = max(behind, 0.0)
        else:
            target = None
            self._behind = 0.0
        done = self._integrate(target, now + CHUNK_BUDGET)
        if self._finished or sim.fault is not None:
            return now + 0.1
        if not done or rtf <= 0.0:
            return None
        # Next wake-up: the next output's wall time, or the next step's (>= MIN_SLEEP away).
        now = time.monotonic()
        nxt = self._wall_of_step(sim.steps + 1)
        nxt = max(nxt, now + MIN_SLEEP)
        return min(nxt, self._wall_of_step(self._next_pub_step))

    def _hold_for_input(self, now: float) -> bool:
        """``wait_for_input``: True while the start waits for brake-input publishers."""
        limit = self._wait_for_input
        if limit <= 0.0:
            return False
        log = self.get_logger()
        subs = [self._subs[name] for name, info in self._sub_info.items()
                if info[1] == self._mode]
        if self._wait_since is None:
            self._wait_since = now
            self._wait_ready = None
            log.info(f'waiting up to {limit:g} s for publishers on the {len(subs)} brake-input '
                     f'topic(s) of {self._mode} before starting the clock')
        if all(s.get_publisher_count() > 0 for s in subs):
            if self._wait_ready is None:
                self._wait_ready = now
            if now - self._wait_ready < INPUT_SETTLE:
                return True          # let the other direction (e.g. their /clock) match too
            log.info(f'brake input connected after {now - self._wait_since:.2f} s; starting')
            return False
        self._wait_ready = None
        if now - self._wait_since >= limit:
            log.warning(f'no publisher on every brake-input topic after {limit:g} s; '
                        'starting anyway')
            return False
        return True

    def _integrate(self, target: int | None, deadline: float) -> bool:
        """Integrate toward step ``target`` (None: no limit), publishing on the way, until the
        deadline (wall); True if the target was reached."""
        sim = self._sim
        while True:
            stop = self._next_pub_step
            if target is not None:
                stop = min(stop, target)
            if self._end_step is not None:
                stop = min(stop, self._end_step)
            if sim.steps >= stop:
                if self._end_step is not None and sim.steps >= self._end_step:
                    self._finish('duration reached')
                return target is None or sim.steps >= target
            n = stop - sim.steps
            n = max(1, min(n, int(CHUNK_BUDGET / max(self._step_cost, 1e-9))))
            t0 = time.monotonic()
            sim.advance(n)
            t1 = time.monotonic()
            self._step_cost = 0.8 * self._step_cost + 0.2 * (t1 - t0) / n
            if sim.fault is not None:
                self._on_fault()
                return True
            self._publish_due()
            if t1 >= deadline:
                return False
            self._apply_inputs(t1)

    def _on_fault(self) -> None:
        if self._fault_reported:
            return
        self._fault_reported = True
        self.get_logger().error(
            f'NUMERICAL FAULT: {self._sim.fault}. The simulation keeps its last good state '
            f'(t = {self._sim.t:.4f} s) and stops integrating; call the reset service to '
            'start again' + ('' if self._writer is None else
                             f'; the recording {self._writer.path} stays intact'))
        if self._end_step is not None:
            self._finish('numerical fault', code=3)

    def _finish(self, why: str, code: int = 0) -> None:
        if self._finished:
            return
        self._finished = True
        self._exit_code = code
        self.get_logger().info(f'{why} at t = {self._sim.t:.3f} s ({self._sim.steps} steps); '
                               'simulation stopped')

    # ================================================================== diagnostics ====
    def _publish_diagnostics(self) -> None:
        with self._locked():
            sim = self._sim
            now = time.monotonic()
            w0, s0 = self._rtf_window
            if now - w0 > 0.2:
                achieved = (sim.t - s0) / (now - w0)
                self._achieved_rtf = achieved if achieved >= 0 else float('nan')
                self._rtf_window = (now, sim.t)
            cfg = self._cfg
            fault = sim.fault
            t, steps = sim.t, sim.steps
            finished, behind = self._finished, self._behind
            with self._in_lock:
                ages = now - self._in_arrival
                max_age = float(np.max(ages)) if ages.size else 0.0
            writer = self._writer
            mode, stale, emergency = self._mode, self._stale, self._emergency
            stale_names = ', '.join(self._stale_names)
            n = sim.n
        pending = self._pending_changes()
        rtf = float(cfg.real_time_factor)
        achieved = self._achieved_rtf
        sim_status = DiagnosticStatus(name=f'{NODE_NAME}: simulation',
                                      hardware_id=self.get_fully_qualified_name())
        if fault is not None:
            sim_status.level = DiagnosticStatus.ERROR
            sim_status.message = f'numerical fault: {fault}; stopped, call reset'
        elif writer is not None and writer.error:
            sim_status.level = DiagnosticStatus.ERROR
            sim_status.message = f'recording failed: {writer.error}'
        elif finished:
            sim_status.level = DiagnosticStatus.OK
            sim_status.message = 'finished (duration reached)'
        elif rtf > 0 and behind > BEHIND_WARN:
            sim_status.level = DiagnosticStatus.WARN
            sim_status.message = (f'behind real time by {behind:.3f} s (rtf {rtf:g}, '
                                  f'achieved {achieved:.3g})')
        else:
            sim_status.level = DiagnosticStatus.OK
            sim_status.message = (f'running, real_time_factor {rtf:g}, achieved '
                                  f'{achieved:.3g}' if rtf > 0 else
                                  f'running as fast as possible, achieved rtf {achieved:.3g}')
        kv = {
            'sim_time': f'{t:.6f}', 'steps': str(steps), 'real_time_factor': f'{rtf:g}',
            'achieved_real_time_factor': f'{achieved:.6g}', 'behind_s': f'{behind:.6f}',
            'lag_dropped_s': f'{self._lag_dropped:.6f}', 'lag_drop_events': str(self._lag_events),
            'integrator': 'fault' if fault else 'ok', 'fault': fault or '',
            'num_coaches': str(n), 'model_type': str(cfg.model_type),
            'scale_factor': f'{float(cfg.scale_factor):g}', 'integration_step': f'{self._h:g}',
            'publish_rate': f'{self._rate:g}', 'duration': f'{self._duration:g}',
            'finished': str(finished).lower(), 'pending_changes': pending,
            'recording': str(writer.path) if writer else '',
            'recorded_messages': str(writer.written) if writer else '0',
            'record_backlog': str(writer.backlog) if writer else '0',
        }
        sim_status.values = [KeyValue(key=k, value=v) for k, v in kv.items()]

        timeout = float(cfg.input_timeout)
        in_status = DiagnosticStatus(name=f'{NODE_NAME}: brake input',
                                     hardware_id=self.get_fully_qualified_name())
        rejected = sum(self._rejected.values())
        if emergency:
            in_status.level = DiagnosticStatus.ERROR
            in_status.message = f'stale (> {timeout:g} s): emergency brake applied ({stale_names})'
        elif stale:
            in_status.level = DiagnosticStatus.WARN
            in_status.message = f'stale (> {timeout:g} s): holding the last values ({stale_names})'
        elif rejected:
            in_status.level = DiagnosticStatus.WARN
            in_status.message = (f'{rejected} input message(s) rejected '
                                 f'(last: {self._last_rejected})')
        else:
            in_status.level = DiagnosticStatus.OK
            in_status.message = 'ok'
        kv = {'brake_input': mode, 'input_timeout': f'{timeout:g}',
              'on_input_timeout': str(cfg.on_input_timeout), 'input_age_s': f'{max_age:.3f}',
              'stale': str(stale).lower(), 'stale_inputs': stale_names,
              'emergency_applied': str(emergency).lower(),
              'accepted': str(self._accepted), 'rejected_total': str(rejected)}
        kv.update({f'rejected_{r}': str(c) for r, c in self._rejected.items()})
        kv['last_rejected'] = self._last_rejected
        in_status.values = [KeyValue(key=k, value=v) for k, v in kv.items()]

        msg = DiagnosticArray(status=[sim_status, in_status])
        msg.header.stamp = self.get_clock().now().to_msg()
        try:
            self._pub_diag.publish(msg)
        except Exception:  # noqa: BLE001 - shutting down
            return
        with self._locked():
            if self._writer is not None:
                self._record('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
                             int(round(self._sim.t * 1e9)), serialize_message(msg))

    # ============================================================ public read-only ====
    @property
    def finished(self) -> bool:
        """True once ``duration`` is reached (or a fault ended a run with ``duration``)."""
        return self._finished

    @property
    def exit_code(self) -> int:
        return self._exit_code

    @property
    def sim_time(self) -> float:
        return self._sim.t

    @property
    def fault(self) -> str | None:
        return self._sim.fault

    @property
    def bag_path(self) -> Path | None:
        w = self._writer
        return None if w is None else w.path

    def destroy_node(self) -> None:
        """Stop the simulation thread, finish the bag, then destroy the node."""
        if not self._destroyed:
            self._destroyed = True
            self._stop.set()
            self._wake.set()
            thread = getattr(self, '_thread', None)
            if thread is not None:
                thread.join(10.0)
            writer, self._writer = self._writer, None
            if writer is not None:
                writer.close()
                # After SIGINT/SIGTERM the context is gone: log without /rosout.
                log = self.get_logger() if self.context.ok() else rclpy.logging.get_logger(
                    f'{self.get_name()}.shutdown')
                log.info(f'bag closed: {writer.path} ({writer.written} messages)')
        super().destroy_node()


def main(args: list[str] | None = None) -> int:
    """``ros2 run train_dynamics sim_node``; SIGINT/SIGTERM (rclpy's handlers) stop it cleanly,
    with the bag closed. Exit status: 0, 2 invalid parameters, 3 numerical fault (with
    ``duration``), 1 other errors."""
    rclpy.init(args=args)
    sys.setswitchinterval(0.0005)     # the simulation thread gets the GIL back quickly
    node = None
    executor = None
    code = 0
    try:
        node = SimNode()
        executor = make_executor()
        executor.add_node(node)
        while not node.finished:
            executor.spin_once(timeout_sec=0.1)
        code = node.exit_code
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ConfigError, ParameterException, FileExistsError, ValueError) as exc:
        if rclpy.ok():
            print(f'sim_node: invalid parameters: {exc}', file=sys.stderr)
            code = 2
    except (BagError, OSError) as exc:
        if rclpy.ok():
            print(f'sim_node: cannot record: {exc}', file=sys.stderr)
            code = 1
    except Exception:
        if rclpy.ok():       # not a signal shutting the context down mid-callback
            raise
    finally:
        # the executor lets go of the node's callbacks first: the EventsExecutor aborts the
        # process ("Destroying callback manager with callbacks remaining") otherwise
        if executor is not None:
            if node is not None:
                try:
                    executor.remove_node(node)
                except Exception:   # noqa: BLE001 - shutting down anyway
                    pass
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 - a signal handler shut the context down first
            pass
    return code


if __name__ == '__main__':
    sys.exit(main())
