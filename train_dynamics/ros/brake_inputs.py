"""
The brake inputs of ``sim_node``: subscriptions, validation, staleness and the fail-safe.

Inputs (``sensor_msgs/FluidPressure``, ABSOLUTE Pa; gauge = absolute - ``atmospheric_pressure``),
relative names, subscribed best-effort keep-last 10 so that reliable and best-effort publishers
both connect:

- ``brake_pipe/pressure`` (``brake_input`` = ``pipe_head``),
- ``coach_<i>/brake_pipe/pressure`` (``pipe_per_coach``), ``coach_<i>/brake_cylinder/pressure``
  (``cylinder_per_coach``), i = 1..N.

A message takes effect at the next integration step (zero-order hold); with ``input_timing``
``stamp`` it is held until the simulation is about to integrate across its header stamp, then
handed to :meth:`TrainSimulator.schedule <train_dynamics.physics.train.TrainSimulator.schedule>`
(:meth:`BrakeInputs.schedule_due`): it takes effect at its stamp exactly, the step that spans
the stamp split there, as the offline command replays an input at its bag time
(``cylinder_per_coach``, ``pipe_per_coach``; ``pipe_head`` and the pneumatic brake take inputs
at the first integration step at or after the stamp). One that can no longer act there (its
stamp in the past; without exact inputs, its step done) takes effect at once and is counted in
:attr:`BrakeInputs.late`; it is recorded at the instant it acted. The header stamps of the
values the simulator holds tell the lock-step whether every input has answered an output
(:meth:`BrakeInputs.answered`; with the traction and EP commands and the WSP valves when
``lockstep_inputs`` declares them: :meth:`BrakeInputs.unanswered`). Active input topics
with more than one publisher are found by the graph scan and warned about
(:attr:`BrakeInputs.multiple_publishers`). Rejected and counted per
reason (:data:`REJECT_REASONS`, in ``/diagnostics``, with a throttled warning naming the topic):
``non_finite`` (NaN, +-inf), ``negative`` (absolute pressure < 0), ``too_high`` (absolute
pressure > :data:`MAX_ABSOLUTE_PRESSURE` = 20 bar), ``wrong_mode`` (a topic of another
``brake_input``), ``unknown_coach`` (``coach_<i>`` with i outside 1..N), ``out_of_range`` (a
traction command outside [-1, 1], :mod:`train_dynamics.ros.traction_inputs`), ``malformed`` (not
deserialisable), ``not_locomotive`` (a traction command for a vehicle without traction or
dynamic brake; one for a vehicle outside 1..N is ``unknown_coach``: the offline replay warns
and ignores both); the first three by the rule the offline replay applies too
(:func:`train_dynamics.physics.config.input_rejection`). Publishers of another message type
on an input topic (never received: DDS does not match them) are found by the graph scan and
reported as ``wrong_type`` in ``/diagnostics``. The head topic and the per-coach topics of the
active mode are subscribed from the start; topics of the other modes and of coaches that do not
exist, and traction-command topics of vehicles that take none, are found by a graph scan every
:data:`GRAPH_SCAN_PERIOD` s and subscribed then (only to count and reject their messages:
keeping 2N idle subscriptions would slow rclpy's executor for long trains).

Stale inputs: ``input_timeout`` > 0 s (wall) without a brake input (any coach of a per-coach mode)
is reported in ``/diagnostics``; ``on_input_timeout`` ``hold`` keeps the last values, ``emergency``
applies the fail-safe (head pipe vented / all pipe pressures 0 gauge / all cylinders at
``max_cylinder_pressure``) until every input is fresh again. The fail-safe pressures are recorded
with ``frame_id`` ``train_dynamics/input_timeout``. The locomotives' traction commands go stale
by the same timeout and policy (:mod:`train_dynamics.ros.traction_inputs`: the fail-safe sets
them to 0); ``/diagnostics`` reports both together (:attr:`BrakeInputs.stale`,
:attr:`BrakeInputs.emergency`, :attr:`BrakeInputs.stale_names`, :meth:`BrakeInputs.max_age`).
"""
from __future__ import annotations

import functools
import math
import threading
import time
from typing import Any, Callable

import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import FluidPressure
from std_msgs.msg import Float64

from train_dynamics import topics
from train_dynamics.physics.config import input_rejection, SimConfig
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import time_ns
from train_dynamics.ros.blending_inputs import BlendingInputs
from train_dynamics.ros.ep_inputs import EpInputs
from train_dynamics.ros.lockstep_inputs import LockstepInputs
from train_dynamics.ros.publishers import stamp
from train_dynamics.ros.throttle import Throttle
from train_dynamics.ros.traction_inputs import TractionInputs
from train_dynamics.ros.wsp_inputs import WspInputs

HEAD = topics.PIPE_HEAD
CYL = topics.CYLINDER_PER_COACH
PER_COACH = (topics.PIPE_PER_COACH, topics.CYLINDER_PER_COACH)
MAX_ABSOLUTE_PRESSURE = topics.MAX_ABSOLUTE_PRESSURE
#: Reasons an input message is rejected (keys of the counts in /diagnostics).
REJECT_REASONS = ('non_finite', 'negative', 'too_high', 'wrong_mode', 'unknown_coach',
                  'malformed', 'out_of_range', 'not_locomotive')
GRAPH_SCAN_PERIOD = 2.0  # [s wall] search for input topics of other modes / unknown coaches
MAX_EXTRA_SUBSCRIPTIONS = 256   # cap on the subscriptions made by the graph scan

INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)

Record = Callable[[str, str, int, bytes], None]


class Rejected(Exception):
    """An input message that is not used; ``reason`` is one of :data:`REJECT_REASONS`."""

    def __init__(self, reason: str, detail: str) -> None:
        super().__init__(f'{detail} ({reason})')
        self.reason = reason


def absolute_pressure(data: bytes) -> tuple[float, int]:
    """
    Return (pressure [Pa absolute], header stamp [ns]) of a raw FluidPressure.

    Raises :class:`Rejected`.
    """
    try:
        msg = deserialize_message(data, FluidPressure)
    except Exception as exc:  # noqa: BLE001
        raise Rejected('malformed', f'cannot deserialise: {exc}') from None
    p = msg.fluid_pressure
    why = input_rejection(p)       # the offline replay applies the same rule
    if why is not None:
        raise Rejected(*why)
    return p, msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


class InputBuffer:
    """
    The latest accepted input of every slot of one run (head: 1 slot; per coach: N slots).

    Made per run: ``mode``, ``n``, ``atm``, ``topics``, ``default`` and ``recording`` never
    change; the other attributes are guarded by the input lock.
    """

    def __init__(self, mode: str, n: int, atm: float, default: float,
                 recording: bool) -> None:
        slots = 1 if mode == HEAD else n
        self.mode = mode
        self.n = n
        self.atm = atm                                  # [Pa] atmospheric_pressure
        self.topics = [topics.input_topic(mode, i) for i in range(1, slots + 1)]
        self.default = np.full(slots, default)          # [Pa gauge] the initial inputs
        self.recording = recording
        self.value = self.default.copy()                # [Pa gauge] latest accepted
        self.raw: list[bytes | None] = [None] * slots   # its CDR (None: the default)
        self.arrival = np.full(slots, time.monotonic())  # [s wall] when it arrived
        self.dirty = False                  # a value arrived since the simulator took them
        self.records: list[tuple[str, bytes]] = []      # accepted since, to record
        self.stamp = np.full(slots, -1, dtype=np.int64)  # [ns] header stamp of ``value``
        self.last = np.full(slots, -1, dtype=np.int64)   # [ns] stamp of the last accepted
        #: ``input_timing`` stamp: accepted messages not yet handed to the simulator, in
        #: arrival order: (stamp [ns], slot, value [Pa gauge], raw CDR, topic)
        self.pending: list[tuple[int, int, float, bytes, str]] = []


class BrakeInputs(LockstepInputs):
    """
    Subscribe to, check and hold the brake inputs; apply them (or the fail-safe) to a run.

    Lock discipline, by owner:

    - executor thread only (subscription callbacks, the graph-scan timer, the reset service):
      the subscriptions, the rejection counts (``rejected``, ``accepted``, ``last_rejected``);
    - the input lock (``_in_lock``): the fields of the run's :class:`InputBuffer` that the
      subscription callbacks write and the simulation thread takes; ``_buffer`` itself is
      replaced under both locks (by :meth:`start`);
    - the simulation lock (held by the simulation thread in :meth:`apply` and
      :meth:`hold_for_input`, by the executor thread in :meth:`start` and when it sets the
      policy): the staleness state, the timeout policy, the wait state, ``_active``.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._log = node.get_logger()
        self._throttle = Throttle()
        # executor thread only
        self._subs: dict[str, Any] = {}       # resolved topic name -> subscription
        self._sub_info: dict[str, tuple[str, str | None, int | None]] = {}
        self.free_qos = INPUT_QOS             # outside lock-step (LOCKSTEP_QOS in it)
        self._qos = INPUT_QOS                 # of the active mode's subscriptions
        self._n_base_subs = 0
        self._accepted = 0
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.last_rejected = ''
        self.wrong_type: dict[str, list[str]] = {}     # input topic -> wrong publisher types
        # input lock
        self._in_lock = threading.Lock()
        self._buffer: InputBuffer | None = None
        # simulation lock
        self._active: tuple[Any, ...] = ()    # subscriptions of the active mode's topics
        self.timeout = 0.0                    # [s wall] input_timeout, 0 = never stale
        self.on_timeout = 'hold'
        self.wait_for_input = 0.0             # [s wall]
        self._failsafe_cylinder = 0.0         # [Pa gauge] max_cylinder_pressure
        self._stale = False
        self._emergency = False
        self._stale_names: list[str] = []
        self._stale_count = 0
        self._wait_since: float | None = None
        self._wait_ready: float | None = None
        #: ``input_timing`` stamp: hold messages until the simulation reaches their stamp
        self.by_stamp = False
        #: called (executor thread) after each accepted message: wakes a waiting simulation
        self.on_input: Callable[[], None] | None = None
        self.late = 0                          # input_timing stamp: applied after their stamp
        #: active input topics with more than one publisher (resolved name -> count)
        self.multiple_publishers: dict[str, int] = {}
        # simulation lock: the header stamps of the values the simulator holds
        self._applied_stamp = np.zeros(0, dtype=np.int64)
        #: the locomotives' traction commands (same validation counts, timeout and policy)
        self.traction = TractionInputs(node, INPUT_QOS, self._reject_traction, self._notify)
        #: the EP / ECP train-line command (same validation counts and timeout)
        self.ep = EpInputs(node, INPUT_QOS, self._reject_traction, self._notify)
        #: the slide-protection valves (wsp external; same validation counts and timeout)
        self.wsp = WspInputs(node, INPUT_QOS, self._reject_traction, self._notify)
        #: the brake control unit's demand, emergency, ED trip (blending builtin)
        self.blending = BlendingInputs(node, INPUT_QOS, self._reject_traction, self._notify)

    def _notify(self) -> None:
        """Tell the simulation thread that an input was accepted (executor thread)."""
        if self.on_input is not None:
            self.on_input()

    def _reject_traction(self, resolved: str, reason: str, detail: str) -> None:
        self._reject(resolved, Rejected(reason, detail))

    # -- what /diagnostics reports: brake inputs and traction commands together ------------
    @property
    def stale(self) -> bool:
        """Return True while a brake input or a traction command is stale."""
        return self._stale or bool(self.traction.stale_names or self.wsp.stale_names
                                   or self.blending.ed.stale_names)

    @property
    def emergency(self) -> bool:
        """Return True while a fail-safe holds (emergency brake, or a traction command 0)."""
        return (self._emergency or self.traction.emergency or self.wsp.emergency
                or self.blending.ed.emergency)

    @property
    def stale_names(self) -> list[str]:
        """Return the stale brake inputs, then the stale traction-command topics."""
        return ((self._stale_names if self._stale else []) + self.traction.stale_names
                + self.wsp.stale_names + self.blending.ed.stale_names)

    @property
    def accepted(self) -> int:
        """Return the accepted brake inputs and traction commands."""
        return (self._accepted + self.traction.accepted + self.ep.accepted + self.wsp.accepted
                + self.blending.accepted)

    # -- a run (executor thread, simulation lock held) -------------------------------------
    def start(self, cfg: SimConfig, n: int, recording: bool) -> None:
        """Take inputs for a new run of ``cfg`` with ``n`` coaches, from its initial inputs."""
        mode = cfg.brake_input
        default = 0.0 if mode == CYL else float(cfg.pipe_nominal_pressure)
        buffer = InputBuffer(mode, n, float(cfg.atmospheric_pressure), default, recording)
        with self._in_lock:
            self._buffer = buffer
        self.set_policy(cfg.input_timeout, cfg.on_input_timeout)
        self._failsafe_cylinder = float(cfg.max_cylinder_pressure)
        self._stale = False
        self._emergency = False
        self._stale_names = []
        self._stale_count = 0
        self._wait_since = None
        self.late = 0
        self.duplicates_brake = 0
        self._applied_stamp = buffer.stamp.copy()
        self._update_subscriptions(mode, n)
        self.traction.start(cfg.consist.commanded if cfg.external_forces else [])
        self.ep.start(cfg.ep_commanded)
        self.wsp.start(list(range(n)) if cfg.wsp == 'external' else [],
                       bool(cfg.bogie_wheelsets))
        self.blending.start(cfg)

    def set_policy(self, timeout: float, on_timeout: str) -> None:
        """Report inputs older than ``timeout`` [s wall]; ``on_timeout``: hold/emergency."""
        self.timeout = float(timeout)
        self.on_timeout = on_timeout

    def _update_subscriptions(self, mode: str, n: int) -> None:
        """Subscribe to the head topic and the active mode's per-coach topics."""
        wanted: dict[str, tuple[str, str | None, int | None]] = {
            topics.HEAD_PIPE_TOPIC: (topics.HEAD_PIPE_TOPIC, HEAD, None)}
        if mode != HEAD:
            for i in range(1, n + 1):
                rel = topics.input_topic(mode, i)
                wanted[rel] = (rel, mode, i - 1)
        resolved = {self._node.resolve_topic_name(rel): info for rel, info in wanted.items()}
        for name in list(self._subs):
            if self._sub_info[name] != resolved.get(name):
                self._node.destroy_subscription(self._subs.pop(name))
                del self._sub_info[name]
        for name, info in resolved.items():
            if name not in self._subs:
                self._subscribe(name, info, self._qos)
        self._n_base_subs = len(resolved)
        self._active = tuple(self._subs[name] for name, info in resolved.items()
                             if info[1] == mode)

    def _subscribe(self, resolved: str, info: tuple[str, str | None, int | None],
                   qos: QoSProfile = INPUT_QOS) -> None:
        rel, family, index = info
        cb = functools.partial(self._on_input, rel, resolved, family, index)
        self._subs[resolved] = self._node.create_subscription(FluidPressure, resolved, cb,
                                                              qos, raw=True)
        self._sub_info[resolved] = info

    def scan_graph(self) -> None:
        """
        Subscribe to input topics of other modes and of coaches that do not exist.

        Their messages are then counted and rejected. (Graph-scan timer, executor thread.)
        """
        node = self._node
        ns = node.get_namespace().rstrip('/') + '/'
        n = self._buffer.n          # (replaced by start(), on this thread)
        try:
            found = node.get_topic_names_and_types()
        except Exception:  # noqa: BLE001 - shutting down
            return
        self.wrong_type = self._wrong_type(found, ns)
        self._check_publishers()
        for name, types in found:
            if name in self._subs or not name.startswith(ns):
                continue
            rel = name[len(ns):]
            if topics.FLOAT64 in types:
                m = topics.TRACTION_TOPIC_PATTERN.fullmatch(rel)
                if m is not None and not self.traction.subscribed(name):
                    if len(self._subs) - self._n_base_subs >= MAX_EXTRA_SUBSCRIPTIONS:
                        return
                    self._subscribe_traction(name, int(m.group(1)), n)
            if topics.FLUID_PRESSURE not in types:
                continue
            for family in PER_COACH:
                m = topics.INPUT_TOPIC_PATTERNS[family].fullmatch(rel)
                if m is None:
                    continue
                if len(self._subs) - self._n_base_subs >= MAX_EXTRA_SUBSCRIPTIONS:
                    return
                i = int(m.group(1))
                self._subscribe(name, (rel, family if 1 <= i <= n else None, None))
                break

    def _check_publishers(self) -> None:
        """Warn when an active input topic has more than one publisher (their values mix)."""
        multiple = {}
        for sub in self._active:
            count = sub.get_publisher_count()
            if count > 1:
                multiple[sub.topic_name] = count
                if self._throttle(('publishers', sub.topic_name), time.monotonic()) is not None:
                    self._log.warning(
                        f'{count} publishers on the active brake input {sub.topic_name}: '
                        'their values mix, the latest message of either wins')
        self.multiple_publishers = multiple

    def _subscribe_traction(self, resolved: str, vehicle: int, n: int) -> None:
        """Count and reject the commands of a traction topic no locomotive of ours has."""
        if 1 <= vehicle <= n:
            why = Rejected('not_locomotive', f'vehicle {vehicle} has no traction or dynamic '
                           'brake')
        else:
            why = Rejected('unknown_coach', f'coach index outside 1..{n}')

        def reject(data: bytes) -> None:
            self._reject(resolved, why)

        self._subs[resolved] = self._node.create_subscription(Float64, resolved, reject,
                                                              INPUT_QOS, raw=True)
        self._sub_info[resolved] = (resolved, 'traction', None)

    def _wrong_type(self, found: list[tuple[str, list[str]]], ns: str) -> dict[str, list[str]]:
        """Return input topic -> the types of its publishers that are not FluidPressure."""
        out: dict[str, list[str]] = {}
        for name, types in found:
            if not name.startswith(ns) or all(t == topics.FLUID_PRESSURE for t in types):
                continue
            rel = name[len(ns):]
            if not any(p.fullmatch(rel) for p in topics.INPUT_TOPIC_PATTERNS.values()):
                continue
            wrong = [info.topic_type for info in self._node.get_publishers_info_by_topic(name)
                     if info.topic_type != topics.FLUID_PRESSURE]
            if wrong:
                out[name] = wrong
                if self._throttle(('wrong_type', name), time.monotonic()) is not None:
                    self._log.warning(f'{len(wrong)} publisher(s) on input topic {name} of '
                                      f'type {", ".join(sorted(set(wrong)))}, not '
                                      f'{topics.FLUID_PRESSURE}: their messages are never '
                                      'received')
        return out

    # -- messages (subscription callbacks, executor thread) --------------------------------
    def _on_input(self, rel: str, resolved: str, family: str | None, index: int | None,
                  data: bytes) -> None:
        """Check a brake-input message (raw CDR); keep it for the next integration step."""
        with self._in_lock:
            buffer = self._buffer
        try:
            if family is None:
                raise Rejected('unknown_coach', f'coach index outside 1..{buffer.n}')
            if family != buffer.mode:
                raise Rejected('wrong_mode', f'topic of brake_input {family}, the node runs '
                                             f'{buffer.mode}')
            p, stamp_ns = absolute_pressure(data)
        except Rejected as exc:
            self._reject(resolved, exc)
            return
        slot = 0 if index is None else index
        gauge, raw = p - buffer.atm, bytes(data)
        with self._in_lock:
            if self._buffer is not buffer:      # a reset replaced the run meanwhile
                return
            duplicate = self._duplicate_answer(int(buffer.last[slot]), stamp_ns)
            if not duplicate:
                buffer.last[slot] = stamp_ns
                buffer.arrival[slot] = time.monotonic()
                self._accept(buffer, slot, stamp_ns, gauge, raw, rel)
        if duplicate:                           # lock-step: the first answer holds
            self.duplicates_brake += 1
            self.duplicate(resolved)
            return
        self._accepted += 1
        self._notify()

    def _accept(self, buffer: InputBuffer, slot: int, stamp_ns: int, gauge: float, raw: bytes,
                rel: str) -> None:
        """Keep an accepted message for the simulation thread (input lock held)."""
        if self.by_stamp:       # takes effect at its stamp (apply)
            buffer.pending.append((stamp_ns, slot, gauge, raw, rel))
        else:
            buffer.stamp[slot] = stamp_ns
            buffer.value[slot] = gauge
            buffer.raw[slot] = raw
            buffer.dirty = True
            if buffer.recording:
                buffer.records.append((rel, raw))

    def _reject(self, resolved: str, exc: Rejected) -> None:
        self.rejected[exc.reason] += 1
        self.last_rejected = f'{resolved}: {exc.reason}'
        suppressed = self._throttle((resolved, exc.reason), time.monotonic())
        if suppressed is not None:
            more = f' ({suppressed} more since the last warning)' if suppressed else ''
            self._log.warning(f'rejected input on {resolved}: {exc}{more}')

    def max_age(self, now: float) -> float:
        """Return the age [s wall] of the oldest input (brake inputs and traction commands)."""
        with self._in_lock:
            ages = now - self._buffer.arrival
            age = float(np.max(ages)) if ages.size else 0.0
        return max(age, self.traction.max_age(now), self.wsp.max_age(now),
                   self.blending.ed.max_age(now))

    # -- the simulation thread (simulation lock held) --------------------------------------
    def discard_records(self) -> None:
        """Drop the accepted inputs not yet recorded (the run has ended)."""
        with self._in_lock:
            self._buffer.records.clear()

    def apply(self, now: float, sim: TrainSimulator, record: Record) -> None:
        """Put the inputs received since the last call (or the fail-safe) into ``sim``."""
        self.traction.apply(now, sim, record, self.timeout, self.on_timeout == 'emergency')
        self.ep.apply(now, sim, record, self.timeout)
        self.wsp.apply(now, sim, record, self.timeout, False)
        self.blending.apply(sim, record, now, self.timeout)
        if self._buffer.pending:        # input_timing stamp (or just switched off): those due
            self.schedule_due(sim, sim.t if self.by_stamp else math.inf, record)
        news = self._take(now)
        if news is None:
            return
        dirty, stale, values, raws, records, stamps = news
        t_ns = time_ns(sim.t)
        if stale != self._stale:
            self._report_stale(stale)
        if stale and self.on_timeout == 'emergency':
            if not self._emergency:
                self._enter_failsafe(sim, t_ns, record)
            return       # inputs arriving meanwhile wait until every input is fresh
        if self._emergency:
            # Back from the fail-safe: the latest value of every input holds again, and
            # answers a lock-step output as it would have without the fail-safe.
            self._emergency = False
            self._set(sim, values)
            self._applied_stamp = stamps
            buffer = self._buffer
            for k, topic in enumerate(buffer.topics):
                raw = raws[k] if raws[k] is not None else self._synthetic(
                    sim, buffer.default[k], 'train_dynamics/default')
                record(topic, topics.FLUID_PRESSURE, t_ns, raw)
            return
        if dirty:
            self._set(sim, values)
            self._applied_stamp = stamps
            for topic, raw in records:
                record(topic, topics.FLUID_PRESSURE, t_ns, raw)

    def _take(self, now: float) -> tuple | None:
        """Return (dirty, stale, values, raws, records) of the buffer; None: nothing to do."""
        buffer = self._buffer
        with self._in_lock:
            stale = False
            if self.timeout > 0.0:
                stale_idx = np.nonzero(now - buffer.arrival > self.timeout)[0]
                stale = stale_idx.size > 0
                if stale != self._stale or (stale and stale_idx.size != self._stale_count):
                    self._stale_names = [buffer.topics[k] for k in stale_idx[:10]]
                    if stale_idx.size > 10:
                        self._stale_names.append(f'... ({stale_idx.size} inputs)')
                    self._stale_count = stale_idx.size
            dirty = buffer.dirty
            if not dirty and stale == self._stale and \
                    self._emergency == (stale and self.on_timeout == 'emergency'):
                return None
            buffer.dirty = False
            records, buffer.records = buffer.records, []
            return (dirty, stale, buffer.value.copy(), list(buffer.raw), records,
                    buffer.stamp.copy())

    def schedule_due(self, sim: TrainSimulator, until: float, record: Record) -> None:
        """
        ``input_timing`` stamp: hand ``sim`` the held messages stamped up to ``until`` [s].

        The simulation thread calls it before it integrates up to ``until``. Each message
        acts at its stamp (:meth:`TrainSimulator.schedule`; stamp order, arrival order among
        equal stamps); one the simulation has passed (:meth:`TrainSimulator.missed`) acts at
        once and is counted late.
        """
        limit_ns = time_ns(until) if until != math.inf else None
        with self._in_lock:
            buffer = self._buffer
            if limit_ns is None:
                due, buffer.pending = buffer.pending, []
            else:
                due = [e for e in buffer.pending if e[0] <= limit_ns]
                if not due:
                    return
                buffer.pending = [e for e in buffer.pending if e[0] > limit_ns]
        due.sort(key=lambda e: e[0])
        for entry in due:
            t = entry[0] * 1e-9
            late = sim.missed(t)
            if late:
                self.late += 1
            exact = sim.exact_inputs and not late
            sim.schedule(t, functools.partial(self._act, sim, buffer, entry, exact, record))

    def _act(self, sim: TrainSimulator, buffer: InputBuffer,
             entry: tuple[int, int, float, bytes, str], exact: bool, record: Record) -> None:
        """``input_timing`` stamp: one held message takes effect now (inside ``sim.advance``)."""
        stamp_ns, slot, gauge, raw, rel = entry
        with self._in_lock:
            buffer.stamp[slot] = stamp_ns
            buffer.value[slot] = gauge
            buffer.raw[slot] = raw
        if self._emergency:
            return      # the fail-safe holds; the latest values act when all are fresh again
        mode = buffer.mode
        if mode == HEAD:
            sim.set_head_pipe_pressure(gauge)
        elif mode == CYL:
            sim.set_cylinder_pressure(gauge, slot)
        else:
            sim.set_pipe_pressure(gauge, slot)
        self._applied_stamp[slot] = stamp_ns
        if buffer.recording:    # at the instant it acted: the offline replay acts there too
            record(rel, topics.FLUID_PRESSURE, stamp_ns if exact else time_ns(sim.t), raw)

    def _report_stale(self, stale: bool) -> None:
        self._stale = stale
        if stale:
            what = ', '.join(self._stale_names)
            self._log.warning(
                f'brake input stale: nothing for more than {self.timeout:g} s on {what}; '
                + ('applying the emergency brake' if self.on_timeout == 'emergency'
                   else 'holding the last values'))
        else:
            self._stale_names = []
            self._log.info('brake input fresh again')

    def _enter_failsafe(self, sim: TrainSimulator, t_ns: int, record: Record) -> None:
        buffer = self._buffer
        slots = len(buffer.topics)
        if buffer.mode == CYL:
            fail = np.full(slots, self._failsafe_cylinder)
        else:
            fail = np.zeros(slots)
        self._set(sim, fail)
        for k, topic in enumerate(buffer.topics):
            record(topic, topics.FLUID_PRESSURE, t_ns,
                   self._synthetic(sim, fail[k], 'train_dynamics/input_timeout'))
        self._emergency = True

    def _set(self, sim: TrainSimulator, values: np.ndarray) -> None:
        mode = self._buffer.mode
        if mode == HEAD:
            sim.set_head_pipe_pressure(float(values[0]))
        elif mode == CYL:
            sim.set_cylinder_pressure(values)
        else:
            sim.set_pipe_pressure(values)

    def _synthetic(self, sim: TrainSimulator, gauge: float, frame_id: str) -> bytes:
        """Return a FluidPressure (CDR) the node applies itself, stamped with ``sim.t``."""
        msg = FluidPressure(fluid_pressure=float(gauge + self._buffer.atm), variance=0.0)
        msg.header.stamp = stamp(time_ns(sim.t))
        msg.header.frame_id = frame_id
        return serialize_message(msg)
