"""
One command input of ``sim_node``: the subscriptions, checks and hold of one input kind.

A :class:`CommandChannel` serves one row of :data:`train_dynamics.input_kinds.INPUT_KINDS`
that is not a brake pressure (those are :mod:`train_dynamics.ros.brake_channel`'s):
traction commands, the EP / ECP command, the slide-protection valves, the ED force commands,
the brake control unit's demand, emergency and ED trip. Everything that differs between them
is in the row: topic, message type and field, the rule refusing a value, the vehicles that
take it on the run's train, the simulator setter, the fail-safe and the staleness policy,
the lock-step family and whether a message is stamped.

Subscribed best-effort keep-last 10 (reliable when its lock-step family is declared) for
every vehicle that takes it (a train-wide kind: one topic). A value takes effect at the next
integration step (zero-order hold) and is recorded as received. Refused values are counted
with the node's other inputs (:class:`~train_dynamics.ros.controller_inputs.ControllerInputs`)
per reason: the row's (``non_finite``, ``out_of_range`` ...) and ``malformed``.

Lock-step: an unstamped message (``std_msgs/Float64``, ``Int8``) answers the latest output
published before it arrived (the node tags it with that output's stamp,
:meth:`CommandChannel.output_published`); a stamped one answers the output of its header
stamp. A period waits until the applied value of every vehicle answers its output
(:meth:`CommandChannel.unanswered`); a second answer to one output is not used (counted).

A kind's stamped twins (``train_dynamics_msgs`` messages; rows whose ``twin`` names the kind)
are served by the same channel: their topics are subscribed beside the kind's, a value from
either is the vehicle's value (recorded on the topic it came by), and either answers a
lock-step period for the vehicle.

Staleness (``input_timeout`` > 0 s wall after a first value; the row's ``on_stale``):
``policy``: with ``on_input_timeout`` emergency the value falls to the fail-safe (recorded)
until a new one arrives or the policy changes, with ``hold`` the last one holds; ``failsafe``:
the fail-safe whatever the policy; ``line``: the EP / ECP train line is lost
(``set_train_line``) until the next value; ``''``: not supervised.
"""
from __future__ import annotations

import functools
import threading
import time
from typing import Any, Callable

from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message

from train_dynamics.input_kinds import failsafe_value, InputKind
from train_dynamics.recording.outputs import time_ns
from train_dynamics.ros.publishers import message_class, stamp

Record = Callable[[str, str, int, bytes], None]
Reject = Callable[[str, str, str], None]


def decode(kind: InputKind, data: bytes, cfg: Any) -> tuple[Any, int | None]:
    """
    Return (value, header stamp [ns] or None) of a raw message of ``kind``.

    Raise ValueError(reason, detail) if it cannot be read or the row's rule refuses it (the
    rule the offline input bags are read by).
    """
    try:
        msg = deserialize_message(data, message_class(kind.msgtype))
        value = kind.value(msg)
    except Exception as exc:  # noqa: BLE001 - anything rclpy raises on a bad buffer
        raise ValueError('malformed', f'cannot deserialise: {exc}') from None
    why = kind.rule(value, cfg)
    if why is not None:
        raise ValueError(*why)
    st = msg.header.stamp if kind.stamped else None
    return value, (None if st is None else st.sec * 1_000_000_000 + st.nanosec)


class CommandChannel:
    """Subscribe to, check and hold one command input kind of one node (see the module)."""

    def __init__(self, kind: InputKind, node: Node, qos: Any, reject: Reject,
                 notify: Callable[[], None] = lambda: None,
                 twins: tuple[InputKind, ...] = ()) -> None:
        self.kind = kind
        #: the kind and its stamped twins: the rows whose topics this channel subscribes
        self.kinds = (kind,) + tuple(twins)
        self._node = node
        self._qos = qos
        self._reject = reject           # (resolved topic, reason, detail): count and warn
        self._notify = notify           # called after each accepted value (wakes lock-step)
        self._log = node.get_logger()
        self._subs: dict[str, Any] = {}
        self._vehicle: dict[str, int] = {}         # resolved topic -> its 0-based vehicle
        self._lock = threading.Lock()
        self._cfg: Any = None
        self._indices: list[int] = []
        self._value: dict[int, Any] = {}
        self._arrival: dict[int, float] = {}       # [s wall] of each vehicle's last value
        #: accepted since the last apply: (the row it came by, CDR)
        self._dirty: dict[int, tuple[InputKind, bytes]] = {}
        #: each vehicle's last accepted value: (the row it came by, CDR)
        self._raw: dict[int, tuple[InputKind, bytes]] = {}
        self._period_ns = -1                       # stamp of the latest output published
        self._tag: dict[int, int] = {}             # the output each last value answers
        self._applied_tag: dict[int, int] = {}     # simulation lock: of the value applied
        self._stale: set[int] = set()              # simulation lock: stale vehicles
        self._held: set[int] = set()               # stale ones the fail-safe holds
        self._line = True                          # on_stale line: the train line
        self.accepted = 0
        #: lock-step on this kind: a second value after one output is not used
        self.dedupe = False
        self.duplicates = 0
        self.on_duplicate: Callable[[str], None] | None = None   # (resolved topic): warn

    def start(self, cfg: Any) -> None:
        """Subscribe to the topics of the vehicles that take the kind on ``cfg``'s train."""
        indices = list(self.kind.takes(cfg))
        with self._lock:
            self._cfg = cfg
            self._indices = indices
            self._value = {i: self.kind.initial_value(cfg) for i in indices}
            self._arrival = {}
            self._dirty = {}
            self._raw = {}
            self._period_ns = -1
            self._tag = {}
        self.duplicates = 0
        self._applied_tag = {}
        self._stale = set()
        self._held = set()
        self._line = True
        self._subscribe_all()

    def set_qos(self, qos: Any) -> None:
        """Subscribe with ``qos`` from now on (reliable in lock-step)."""
        if qos == self._qos:
            return
        self._qos = qos
        for name in list(self._subs):
            self._node.destroy_subscription(self._subs.pop(name))
        self._subscribe_all()

    def subscriptions(self) -> list[Any]:
        """Return the subscriptions of the run's topics of this kind (and of its twins)."""
        return list(self._subs.values())

    def unconnected(self) -> list[str]:
        """Return the topics of the vehicles none of whose topics (kind, twins) has a publisher."""
        live = {self._vehicle[name] for name, sub in self._subs.items()
                if sub.get_publisher_count() > 0}
        return [self._node.resolve_topic_name(self.kind.topic_of(i))
                for i in self._indices if i not in live]

    def _subscribe_all(self) -> None:
        wanted = {self._node.resolve_topic_name(kind.topic_of(i)): (i, kind)
                  for kind in self._available() for i in self._indices}
        self._vehicle = {name: i for name, (i, _) in wanted.items()}
        for name in list(self._subs):
            if name not in wanted:
                self._node.destroy_subscription(self._subs.pop(name))
        for name, (i, kind) in wanted.items():
            if name not in self._subs:
                cb = functools.partial(self._on_message, name, i, kind)
                self._subs[name] = self._node.create_subscription(
                    message_class(kind.msgtype), name, cb, self._qos, raw=True)

    def _available(self) -> list[InputKind]:
        """Return the kind and those of its twins whose message class imports (warned once)."""
        out = [self.kind]
        for twin in self.kinds[1:]:
            try:
                message_class(twin.msgtype)
            except ImportError as exc:
                self._log.warning(f'{twin.display} not subscribed: {exc} (build the typed '
                                  'messages: tools/build_msgs.sh)', once=True)
                continue
            out.append(twin)
        return out

    @property
    def active(self) -> bool:
        """Return True if the run has a vehicle (or the train) that takes this kind."""
        return bool(self._indices)

    def subscribed(self, resolved: str) -> bool:
        """Return True if ``resolved`` is one of this run's topics of the kind."""
        return resolved in self._subs

    def _on_message(self, resolved: str, index: int, kind: InputKind, data: bytes) -> None:
        try:
            value, stamp_ns = decode(kind, data, self._cfg)
        except ValueError as exc:
            self._reject(resolved, *exc.args)
            return
        with self._lock:
            if index not in self._value:        # a reset changed the train meanwhile
                return
            tag = self._period_ns if stamp_ns is None else stamp_ns
            last = self._tag.get(index)
            duplicate = self.dedupe and tag >= 0 and last == tag
            if not duplicate:
                self._value[index] = value
                self._arrival[index] = time.monotonic()
                self._dirty[index] = self._raw[index] = (kind, bytes(data))
                self._tag[index] = tag
        if duplicate:          # lock-step: the first value after the output answers it
            self.duplicates += 1
            if self.on_duplicate is not None:
                self.on_duplicate(resolved)
            return
        self.accepted += 1
        self._notify()

    def output_published(self, t_ns: int) -> None:
        """Tag the unstamped values arriving from now on as answers to the output ``t_ns``."""
        with self._lock:
            self._period_ns = t_ns

    def unanswered(self, t_ns: int, clock: bool = False) -> list[str]:
        """
        Lock-step: the topics whose applied value does not answer the output ``t_ns``.

        ``clock`` (``lockstep_answer`` clock): a stamped value answers when stamped at or
        after ``t_ns``; an unstamped one (tagged with the output it followed) as in echo.
        """
        tags = self._applied_tag
        if clock and self.kind.stamped:
            return [self.kind.topic_of(i) for i in self._indices if tags.get(i, -1) < t_ns]
        return [self.kind.topic_of(i) for i in self._indices if tags.get(i) != t_ns]

    def connected(self) -> bool:
        """Return True if every vehicle has a publisher on its topic or a twin's."""
        return not self.unconnected()

    @property
    def _supervised(self) -> bool:
        """Return True if staleness is reported (``/diagnostics``) for this kind."""
        return self.kind.on_stale in ('policy', 'failsafe')

    @property
    def stale_names(self) -> list[str]:
        """Return the topics of the stale vehicles (simulation lock held)."""
        if not self._supervised:
            return []
        return [self.kind.topic_of(i) for i in sorted(self._stale)]

    @property
    def emergency(self) -> bool:
        """Return True while the fail-safe holds a stale vehicle's value."""
        return bool(self._held)

    def max_age(self, now: float) -> float:
        """Return the age [s wall] of the oldest value received (0 before any)."""
        if not self._supervised:
            return 0.0
        with self._lock:
            ages = [now - t for t in self._arrival.values()]
        return max(ages, default=0.0)

    def apply(self, now: float, sim: Any, record: Record, timeout: float,
              emergency: bool) -> None:
        """
        Put the values received since the last call (or the fail-safe) into ``sim``.

        ``timeout``: ``input_timeout`` [s wall] (0: never stale); ``emergency``:
        ``on_input_timeout`` is emergency.
        """
        kind = self.kind
        if not kind.on_stale:
            timeout = 0.0
        with self._lock:
            dirty, self._dirty = self._dirty, {}
            stale = {i for i, t in self._arrival.items()
                     if timeout > 0.0 and now - t > timeout} - set(dirty)
            values = dict(self._value)
            raws = dict(self._raw)
            for i in dirty:
                self._applied_tag[i] = self._tag[i]
        t_ns = time_ns(sim.t)
        for i, (came, raw) in dirty.items():
            self._stale.discard(i)
            self._held.discard(i)
            kind.apply(sim, kind.sim_value(values[i], self._cfg), i)
            record(came.topic_of(i), came.msgtype, t_ns, raw)
        if kind.on_stale == 'line':
            self._supervise_line(sim, not stale)
            return
        self._report_stale(stale, timeout, emergency)
        self._stale = stale
        failsafe = stale if kind.on_stale == 'failsafe' or (
            kind.on_stale == 'policy' and emergency) else set()
        for i in sorted(self._held - failsafe):       # the last value holds again
            came, raw = raws[i]
            kind.apply(sim, kind.sim_value(values[i], self._cfg), i)
            record(came.topic_of(i), came.msgtype, t_ns, raw)
        if failsafe - self._held:
            fail = failsafe_value(kind, self._cfg)
            raw = self._synthetic(sim, fail)
            for i in sorted(failsafe - self._held):
                kind.apply(sim, kind.sim_value(fail, self._cfg), i)
                record(kind.topic_of(i), kind.msgtype, t_ns, raw)
        self._held = set(failsafe)

    def _report_stale(self, stale: set[int], timeout: float, emergency: bool) -> None:
        label = self.kind.label
        for i in sorted(stale - self._stale):
            held = self.kind.on_stale == 'failsafe' or emergency
            action = (f'set to {failsafe_value(self.kind, self._cfg):g}' if held
                      else 'holding the last one')
            self._log.warning(f'{label} of coach_{i + 1} stale: nothing for more '
                              f'than {timeout:g} s; {action}')
        for i in sorted(self._stale - stale):          # input_timeout raised or switched off
            self._log.info(f'{label} of coach_{i + 1} no longer stale')

    def _supervise_line(self, sim: Any, line: bool) -> None:
        """``on_stale`` line: the train line is healthy while values arrive."""
        if line != self._line:
            self._line = line
            sim.set_train_line(line)
            self._log.warning(f'{self.kind.topic}: train line {"restored" if line else "lost"}')

    def _synthetic(self, sim: Any, value: Any) -> bytes:
        """Return the message (CDR) of a value the node applies itself (the fail-safe)."""
        msg = message_class(self.kind.msgtype)(**{self.kind.field: value})
        if self.kind.stamped:
            msg.header.stamp = stamp(time_ns(sim.t))
            msg.header.frame_id = 'train_dynamics/input_timeout'
        return serialize_message(msg)
