"""
The brake-pressure channel of ``sim_node``: the ``brake_input`` kinds of the input table.

Rows ``pipe_head``, ``pipe_per_coach``, ``cylinder_per_coach`` of
:data:`train_dynamics.input_kinds.INPUT_KINDS` (``sensor_msgs/FluidPressure``, ABSOLUTE Pa;
gauge = absolute - ``atmospheric_pressure``), relative names, subscribed best-effort keep-last
10 so that reliable and best-effort publishers both connect: the head topic and the per-coach
topics of the active mode from the start; topics of the other modes and of coaches that do
not exist are found by the graph scan (:meth:`BrakeChannel.scan`) and subscribed then, only
to count and reject their messages (``wrong_mode``, ``unknown_coach``).

What sets this channel apart from the commands (:mod:`train_dynamics.ros.command_channel`):
one of three kinds is active per run and the others are refused; its messages are stamped,
so that ``input_timing`` ``stamp`` holds them until the simulation is about to integrate
across their header stamp and then hands them to :meth:`TrainSimulator.schedule
<train_dynamics.physics.train.TrainSimulator.schedule>` (:meth:`BrakeChannel.schedule_due`):
a message takes effect at its stamp exactly, the step that spans it split there, as the
offline command replays an input at its bag time (``cylinder_per_coach``,
``pipe_per_coach``; ``pipe_head`` and the pneumatic brake take inputs at the first
integration step at or after the stamp). One that can no longer act there (its stamp in the
past; without exact inputs, its step done) takes effect at once and is counted in
:attr:`BrakeChannel.late`; it is recorded at the instant it acted. Without ``input_timing``
``stamp`` a message takes effect at the next integration step (zero-order hold).

Stale inputs: ``input_timeout`` > 0 s (wall) without a brake input (any coach of a per-coach
mode) is reported; ``on_input_timeout`` ``emergency`` applies the whole train's fail-safe
(the row's: head pipe vented / all pipe pressures 0 gauge / all cylinders at
``max_cylinder_pressure``) until every input is fresh again, recorded with ``frame_id``
``train_dynamics/input_timeout``.
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
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure

from train_dynamics import topics
from train_dynamics.input_kinds import BRAKE_KINDS, failsafe_value, KINDS
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import time_ns
from train_dynamics.ros.command_channel import decode
from train_dynamics.ros.publishers import stamp
from train_dynamics.ros.throttle import Throttle

HEAD = topics.PIPE_HEAD
MAX_EXTRA_SUBSCRIPTIONS = 256   # cap on the subscriptions made by the graph scan

INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                       reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)

Record = Callable[[str, str, int, bytes], None]
Reject = Callable[[str, str, str], None]


class InputBuffer:
    """
    The latest accepted input of every slot of one run (head: 1 slot; per coach: N slots).

    Made per run: ``mode``, ``n``, ``cfg``, ``topics``, ``default`` and ``recording`` never
    change; the other attributes are guarded by the input lock.
    """

    def __init__(self, cfg: Any, n: int, recording: bool) -> None:
        kind = KINDS[cfg.brake_input]
        slots = n if kind.per_vehicle else 1
        self.mode = kind.name
        self.kind = kind
        self.cfg = cfg
        self.n = n
        self.atm = float(cfg.atmospheric_pressure)      # [Pa] atmospheric_pressure
        self.topics = [kind.topic_of(i) for i in range(slots)]
        self.default = np.full(slots, float(kind.initial_value(cfg)))  # [Pa gauge]
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

    def hand(self, sim: TrainSimulator, values: np.ndarray) -> None:
        """Hand every slot's value [Pa gauge] to ``sim`` through the kind's setter."""
        if self.kind.per_vehicle:
            self.kind.apply(sim, values, None)
        else:
            self.kind.apply(sim, float(values[0]), 0)


class BrakeChannel:
    """
    Subscribe to, check and hold the brake inputs; apply them (or the fail-safe) to a run.

    Lock discipline, by owner: executor thread only (subscription callbacks, the graph scan,
    the reset service): the subscriptions, ``accepted``; the input lock (``_in_lock``): the
    fields of the run's :class:`InputBuffer` that the callbacks write and the simulation
    thread takes (``buffer`` itself is replaced under both locks by :meth:`start`); the
    simulation lock: the staleness state, ``applied_stamp``, ``late``.
    """

    def __init__(self, node: Node, reject: Reject, notify: Callable[[], None],
                 answered_before: Callable[[int, int], bool],
                 on_duplicate: Callable[[str], None]) -> None:
        self._node = node
        self._log = node.get_logger()
        self._throttle = Throttle()
        self._reject = reject              # (resolved topic, reason, detail): count and warn
        self._notify = notify              # an accepted message: wake the simulation
        self._answered_before = answered_before   # lock-step: (last stamp, stamp) -> dup?
        self._on_duplicate = on_duplicate
        # executor thread only
        self.subs: dict[str, Any] = {}        # resolved topic name -> subscription
        self._sub_info: dict[str, tuple[str, str | None, int | None]] = {}
        self.free_qos = INPUT_QOS             # outside lock-step (LOCKSTEP_QOS in it)
        self._qos = INPUT_QOS                 # of the active mode's subscriptions
        self.n_base_subs = 0
        self.accepted = 0
        self.wrong_type: dict[str, list[str]] = {}     # input topic -> wrong publisher types
        # input lock
        self._in_lock = threading.Lock()
        self.buffer: InputBuffer | None = None
        # simulation lock
        self.active: tuple[Any, ...] = ()     # subscriptions of the active mode's topics
        self.stale = False
        self.emergency = False
        self.stale_names: list[str] = []
        self._stale_count = 0
        #: ``input_timing`` stamp: hold messages until the simulation reaches their stamp
        self.by_stamp = False
        self.late = 0                          # input_timing stamp: applied after their stamp
        self.duplicates = 0                    # lock-step answers not used (a second answer)
        #: active input topics with more than one publisher (resolved name -> count)
        self.multiple_publishers: dict[str, int] = {}
        #: the header stamps of the values the simulator holds
        self.applied_stamp = np.zeros(0, dtype=np.int64)

    # -- a run (executor thread, simulation lock held) -------------------------------------
    def start(self, cfg: Any, n: int, recording: bool) -> None:
        """Take inputs for a new run of ``cfg`` with ``n`` coaches, from its initial inputs."""
        buffer = InputBuffer(cfg, n, recording)
        with self._in_lock:
            self.buffer = buffer
        self.stale = False
        self.emergency = False
        self.stale_names = []
        self._stale_count = 0
        self.late = 0
        self.duplicates = 0
        self.applied_stamp = buffer.stamp.copy()
        self._update_subscriptions(buffer.mode, n)

    def set_qos(self, qos: QoSProfile) -> None:
        """Subscribe the head topic and the active mode's topics with ``qos`` from now on."""
        if qos == self._qos:
            return
        self._qos = qos
        buffer = self.buffer
        if buffer is None:                  # before the first run: it subscribes with it
            return
        for name, info in list(self._sub_info.items()):
            if info[1] in (HEAD, buffer.mode):
                self._node.destroy_subscription(self.subs.pop(name))
                del self._sub_info[name]
        self._update_subscriptions(buffer.mode, buffer.n)

    def _update_subscriptions(self, mode: str, n: int) -> None:
        """Subscribe to the head topic and the active mode's per-coach topics."""
        head = KINDS[HEAD]
        wanted: dict[str, tuple[str, str | None, int | None]] = {
            head.topic: (head.topic, HEAD, None)}
        if KINDS[mode].per_vehicle:
            for i in range(n):
                rel = KINDS[mode].topic_of(i)
                wanted[rel] = (rel, mode, i)
        resolved = {self._node.resolve_topic_name(rel): info for rel, info in wanted.items()}
        for name in list(self.subs):
            if self._sub_info[name] != resolved.get(name):
                self._node.destroy_subscription(self.subs.pop(name))
                del self._sub_info[name]
        for name, info in resolved.items():
            if name not in self.subs:
                self._subscribe(name, info, self._qos)
        self.n_base_subs = len(resolved)
        self.active = tuple(self.subs[name] for name, info in resolved.items()
                            if info[1] == mode)

    def _subscribe(self, resolved: str, info: tuple[str, str | None, int | None],
                   qos: QoSProfile = INPUT_QOS) -> None:
        rel, family, index = info
        cb = functools.partial(self._on_input, rel, resolved, family, index)
        self.subs[resolved] = self._node.create_subscription(FluidPressure, resolved, cb,
                                                             qos, raw=True)
        self._sub_info[resolved] = info

    def scan(self, found: list[tuple[str, list[str]]], ns: str, room: Callable[[], bool]
             ) -> None:
        """
        Subscribe to brake-input topics of other modes and of coaches that do not exist.

        Their messages are then counted and rejected. ``found``: the graph's topics;
        ``room()``: False once the graph scan's subscriptions reach their cap. (Graph-scan
        timer, executor thread.)
        """
        n = self.buffer.n          # (replaced by start(), on this thread)
        self.wrong_type = self._wrong_type(found, ns)
        self._check_publishers()
        per_vehicle = [k for k in BRAKE_KINDS if k.per_vehicle]
        for name, types in found:
            if name in self.subs or not name.startswith(ns) or \
                    topics.FLUID_PRESSURE not in types:
                continue
            rel = name[len(ns):]
            for kind in per_vehicle:
                m = kind.pattern.fullmatch(rel)
                if m is None:
                    continue
                if not room():
                    return
                i = int(m.group(1))
                self._subscribe(name, (rel, kind.name if 1 <= i <= n else None, None))
                break

    @property
    def extra_subscriptions(self) -> int:
        """Return the subscriptions the graph scan made (beyond the run's own)."""
        return len(self.subs) - self.n_base_subs

    def _check_publishers(self) -> None:
        """Warn when an active input topic has more than one publisher (their values mix)."""
        multiple = {}
        for sub in self.active:
            count = sub.get_publisher_count()
            if count > 1:
                multiple[sub.topic_name] = count
                if self._throttle(('publishers', sub.topic_name), time.monotonic()) is not None:
                    self._log.warning(
                        f'{count} publishers on the active brake input {sub.topic_name}: '
                        'their values mix, the latest message of either wins')
        self.multiple_publishers = multiple

    def _wrong_type(self, found: list[tuple[str, list[str]]], ns: str) -> dict[str, list[str]]:
        """Return input topic -> the types of its publishers that are not FluidPressure."""
        out: dict[str, list[str]] = {}
        for name, types in found:
            if not name.startswith(ns) or all(t == topics.FLUID_PRESSURE for t in types):
                continue
            rel = name[len(ns):]
            if not any(k.pattern.fullmatch(rel) for k in BRAKE_KINDS):
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
            buffer = self.buffer
        if family is None:
            self._reject(resolved, 'unknown_coach', f'coach index outside 1..{buffer.n}')
            return
        if family != buffer.mode:
            self._reject(resolved, 'wrong_mode', f'topic of brake_input {family}, the node '
                                                 f'runs {buffer.mode}')
            return
        try:
            p, stamp_ns = decode(buffer.kind, data, buffer.cfg)
        except ValueError as exc:
            self._reject(resolved, *exc.args)
            return
        slot = 0 if index is None else index
        gauge, raw = buffer.kind.sim_value(p, buffer.cfg), bytes(data)
        with self._in_lock:
            if self.buffer is not buffer:       # a reset replaced the run meanwhile
                return
            duplicate = self._answered_before(int(buffer.last[slot]), stamp_ns)
            if not duplicate:
                buffer.last[slot] = stamp_ns
                buffer.arrival[slot] = time.monotonic()
                self._accept(buffer, slot, stamp_ns, gauge, raw, rel)
        if duplicate:                           # lock-step: the first answer holds
            self.duplicates += 1
            self._on_duplicate(resolved)
            return
        self.accepted += 1
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

    def max_age(self, now: float) -> float:
        """Return the age [s wall] of the oldest brake input."""
        with self._in_lock:
            ages = now - self.buffer.arrival
            return float(np.max(ages)) if ages.size else 0.0

    # -- the simulation thread (simulation lock held) --------------------------------------
    def discard_records(self) -> None:
        """Drop the accepted inputs not yet recorded (the run has ended)."""
        with self._in_lock:
            self.buffer.records.clear()

    def apply(self, now: float, sim: TrainSimulator, record: Record, timeout: float,
              emergency: bool) -> None:
        """
        Put the inputs received since the last call (or the fail-safe) into ``sim``.

        ``timeout``: ``input_timeout`` [s wall]; ``emergency``: ``on_input_timeout`` is
        emergency.
        """
        if self.buffer.pending:        # input_timing stamp (or just switched off): those due
            self.schedule_due(sim, sim.t if self.by_stamp else math.inf, record)
        news = self._take(now, timeout, emergency)
        if news is None:
            return
        dirty, stale, values, raws, records, stamps = news
        t_ns = time_ns(sim.t)
        if stale != self.stale:
            self._report_stale(stale, timeout, emergency)
        if stale and emergency:
            if not self.emergency:
                self._enter_failsafe(sim, t_ns, record)
            return       # inputs arriving meanwhile wait until every input is fresh
        buffer = self.buffer
        if self.emergency:
            # Back from the fail-safe: the latest value of every input holds again, and
            # answers a lock-step output as it would have without the fail-safe.
            self.emergency = False
            buffer.hand(sim, values)
            self.applied_stamp = stamps
            for k, topic in enumerate(buffer.topics):
                raw = raws[k] if raws[k] is not None else self._synthetic(
                    sim, buffer.default[k], 'train_dynamics/default')
                record(topic, topics.FLUID_PRESSURE, t_ns, raw)
            return
        if dirty:
            buffer.hand(sim, values)
            self.applied_stamp = stamps
            for topic, raw in records:
                record(topic, topics.FLUID_PRESSURE, t_ns, raw)

    def _take(self, now: float, timeout: float, emergency: bool) -> tuple | None:
        """Return (dirty, stale, values, raws, records, stamps); None: nothing to do."""
        buffer = self.buffer
        with self._in_lock:
            stale = False
            if timeout > 0.0:
                stale_idx = np.nonzero(now - buffer.arrival > timeout)[0]
                stale = stale_idx.size > 0
                if stale != self.stale or (stale and stale_idx.size != self._stale_count):
                    self.stale_names = [buffer.topics[k] for k in stale_idx[:10]]
                    if stale_idx.size > 10:
                        self.stale_names.append(f'... ({stale_idx.size} inputs)')
                    self._stale_count = stale_idx.size
            dirty = buffer.dirty
            if not dirty and stale == self.stale and \
                    self.emergency == (stale and emergency):
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
            buffer = self.buffer
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
        if self.emergency:
            return      # the fail-safe holds; the latest values act when all are fresh again
        buffer.kind.apply(sim, gauge, slot)
        self.applied_stamp[slot] = stamp_ns
        if buffer.recording:    # at the instant it acted: the offline replay acts there too
            record(rel, topics.FLUID_PRESSURE, stamp_ns if exact else time_ns(sim.t), raw)

    def _report_stale(self, stale: bool, timeout: float, emergency: bool) -> None:
        self.stale = stale
        if stale:
            what = ', '.join(self.stale_names)
            self._log.warning(
                f'brake input stale: nothing for more than {timeout:g} s on {what}; '
                + ('applying the emergency brake' if emergency else 'holding the last values'))
        else:
            self.stale_names = []
            self._log.info('brake input fresh again')

    def _enter_failsafe(self, sim: TrainSimulator, t_ns: int, record: Record) -> None:
        buffer = self.buffer
        fail = np.full(len(buffer.topics), float(failsafe_value(buffer.kind, buffer.cfg)))
        buffer.hand(sim, fail)
        for k, topic in enumerate(buffer.topics):
            record(topic, topics.FLUID_PRESSURE, t_ns,
                   self._synthetic(sim, fail[k], 'train_dynamics/input_timeout'))
        self.emergency = True

    def _synthetic(self, sim: TrainSimulator, gauge: float, frame_id: str) -> bytes:
        """Return a FluidPressure (CDR) the node applies itself, stamped with ``sim.t``."""
        msg = FluidPressure(fluid_pressure=float(gauge + self.buffer.atm), variance=0.0)
        msg.header.stamp = stamp(time_ns(sim.t))
        msg.header.frame_id = frame_id
        return serialize_message(msg)
