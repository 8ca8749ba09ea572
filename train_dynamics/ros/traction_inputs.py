"""
The traction inputs of ``sim_node``: ``coach_<i>/traction/command`` of each locomotive.

``std_msgs/Float64``, a fraction in [-1, 1] of the force available at the present speed
(> 0 traction, < 0 dynamic brake), subscribed best-effort keep-last 10 for every locomotive
of the consist (vehicles with ``max_tractive_force`` or ``max_dynamic_brake_force`` > 0). A
command takes effect at the next integration step (zero-order hold) and is recorded as
received. Rejected and counted (in the brake inputs' counts of ``/diagnostics``):
``non_finite``, ``out_of_range`` (|c| > 1), ``malformed``; commands for a vehicle that is not
a locomotive (``not_locomotive``) or not in the train (``unknown_coach``) are found and
counted by the brake inputs' graph scan.

Lock-step (``sync_mode`` lockstep with ``traction`` in ``lockstep_inputs``): a Float64 has no
header stamp, so a command answers the latest output published before it arrived (the node
tags it with that output's stamp, :meth:`TractionInputs.output_published`); each period waits
until every locomotive's applied command answers the period's output
(:meth:`TractionInputs.unanswered`). A controller sends one command per locomotive and output
(its last one again when nothing changes: that is its "ready").

Staleness: with ``input_timeout`` > 0 a locomotive that has received a command and then
nothing for ``input_timeout`` wall seconds is stale; with ``on_input_timeout`` ``emergency``
its command falls to 0 (the fail-safe: no traction, no dynamic brake; recorded with the value
0) until a new command arrives (or the policy changes: then the last command holds again);
with ``hold`` it keeps the last one. The staleness is reported in ``/diagnostics`` beside the
brake inputs' (:class:`train_dynamics.ros.brake_inputs.BrakeInputs` adds :attr:`stale_names`,
:attr:`emergency` and :meth:`max_age` to its own).
"""
from __future__ import annotations

import functools
import threading
import time
from typing import Any, Callable

from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from std_msgs.msg import Float64

from train_dynamics import topics
from train_dynamics.physics.config import traction_rejection
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import time_ns

Record = Callable[[str, str, int, bytes], None]
Reject = Callable[[str, str, str], None]


def float64_command(data: bytes, rule: Callable[[float], tuple[str, str] | None]) -> float:
    """
    Return the value of a raw Float64 command checked by ``rule``.

    Raise ValueError(reason, detail) if it cannot be read or ``rule`` rejects it (the rules
    of physics/config/inputs.py, shared with the offline input bags).
    """
    try:
        value = float(deserialize_message(data, Float64).data)
    except Exception as exc:  # noqa: BLE001 - anything rclpy raises on a bad buffer
        raise ValueError('malformed', f'cannot deserialise: {exc}') from None
    why = rule(value)
    if why is not None:
        raise ValueError(*why)
    return value


def traction_command(data: bytes) -> float:
    """Return the command of a raw traction Float64; raise ValueError(reason, detail)."""
    return float64_command(data, traction_rejection)


class TractionInputs:
    """
    Subscribe to, check and hold the locomotives' traction commands of one node.

    The per-vehicle command inputs differ in the class attributes below (message, topic,
    check, setter, fail-safe value; :class:`train_dynamics.ros.wsp_inputs.WspInputs`).
    """

    #: message class, its type string, what the log calls it, the fail-safe value
    MSG = Float64
    MSG_TYPE = topics.FLOAT64
    LABEL = 'traction command'
    FAILSAFE = 0.0
    #: True: a stale input takes the fail-safe whatever on_input_timeout says
    ALWAYS_FAILSAFE = False
    topic = staticmethod(topics.traction_topic)
    decode = staticmethod(traction_command)

    @staticmethod
    def put(sim: TrainSimulator, value: Any, index: int) -> None:
        """Hand ``value`` of vehicle ``index`` (0-based) to the simulator."""
        sim.set_traction_command(value, index)

    def __init__(self, node: Node, qos: Any, reject: Reject,
                 notify: Callable[[], None] = lambda: None) -> None:
        self._node = node
        self._qos = qos
        self._reject = reject           # (resolved topic, reason, detail): count and warn
        self._notify = notify           # called after each accepted command (wakes lock-step)
        self._log = node.get_logger()
        self._subs: dict[str, Any] = {}
        self._lock = threading.Lock()
        self._locos: list[int] = []
        self._value: dict[int, float] = {}
        self._arrival: dict[int, float] = {}       # [s wall] of each loco's last command
        self._dirty: dict[int, bytes | None] = {}  # accepted since the last apply
        self._raw: dict[int, bytes] = {}           # each loco's last accepted command (CDR)
        self._period_ns = -1                       # stamp of the latest output published
        self._tag: dict[int, int] = {}             # the output each loco's last command answers
        self._applied_tag: dict[int, int] = {}     # simulation lock: of the command applied
        self._stale: set[int] = set()              # simulation lock: stale locomotives
        self._zeroed: set[int] = set()             # stale ones the fail-safe holds at 0
        self.accepted = 0
        #: lock-step on these commands: a second command after one output is not used
        self.dedupe = False
        self.duplicates = 0
        self.on_duplicate: Callable[[str], None] | None = None   # (resolved topic): warn

    def start(self, locomotives: list[int]) -> None:
        """Subscribe to the commands of ``locomotives`` (0-based) for a new run."""
        with self._lock:
            self._locos = list(locomotives)
            self._value = dict.fromkeys(self._locos, 0.0)
            self._arrival = {}
            self._dirty = {}
            self._raw = {}
            self._period_ns = -1
            self._tag = {}
        self.duplicates = 0
        self._applied_tag = {}
        self._stale = set()
        self._zeroed = set()
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
        """Return the subscriptions of the run's command topics."""
        return list(self._subs.values())

    def _subscribe_all(self) -> None:
        wanted = {self._node.resolve_topic_name(self.topic(i + 1)): i
                  for i in self._locos}
        for name in list(self._subs):
            if name not in wanted:
                self._node.destroy_subscription(self._subs.pop(name))
        for name, i in wanted.items():
            if name not in self._subs:
                cb = functools.partial(self._on_command, name, i)
                self._subs[name] = self._node.create_subscription(self.MSG, name, cb, self._qos,
                                                                  raw=True)

    @property
    def active(self) -> bool:
        """Return True if the run has a locomotive that takes commands."""
        return bool(self._locos)

    def subscribed(self, resolved: str) -> bool:
        """Return True if ``resolved`` is the command topic of one of our locomotives."""
        return resolved in self._subs

    def _on_command(self, resolved: str, index: int, data: bytes) -> None:
        try:
            value = self.decode(data)
        except ValueError as exc:
            reason, detail = exc.args
            self._reject(resolved, reason, detail)
            return
        with self._lock:
            if index not in self._value:        # a reset changed the train meanwhile
                return
            duplicate = (self.dedupe and self._period_ns >= 0
                         and self._tag.get(index) == self._period_ns)
            if not duplicate:
                self._value[index] = value
                self._arrival[index] = time.monotonic()
                self._dirty[index] = self._raw[index] = bytes(data)
                self._tag[index] = self._period_ns
        if duplicate:          # lock-step: the first command after the output answers it
            self.duplicates += 1
            if self.on_duplicate is not None:
                self.on_duplicate(resolved)
            return
        self.accepted += 1
        self._notify()

    def output_published(self, t_ns: int) -> None:
        """Tag the commands arriving from now on as answers to the output stamped ``t_ns``."""
        with self._lock:
            self._period_ns = t_ns

    def unanswered(self, t_ns: int) -> list[str]:
        """Lock-step: the command topics whose applied command does not answer ``t_ns``."""
        tags = self._applied_tag
        return [self.topic(i + 1) for i in self._locos if tags.get(i) != t_ns]

    def connected(self) -> bool:
        """Return True if every locomotive's command topic has a publisher."""
        return all(sub.get_publisher_count() > 0 for sub in self._subs.values())

    @property
    def stale_names(self) -> list[str]:
        """Return the command topics of the stale locomotives (simulation lock held)."""
        return [self.topic(i + 1) for i in sorted(self._stale)]

    @property
    def emergency(self) -> bool:
        """Return True while the fail-safe holds a stale locomotive's command at 0."""
        return bool(self._zeroed)

    def max_age(self, now: float) -> float:
        """Return the age [s wall] of the oldest command received (0 before any)."""
        with self._lock:
            ages = [now - t for t in self._arrival.values()]
        return max(ages, default=0.0)

    def apply(self, now: float, sim: TrainSimulator, record: Record, timeout: float,
              emergency: bool) -> None:
        """Put the commands received since the last call (or the fail-safe 0) into ``sim``."""
        with self._lock:
            dirty, self._dirty = self._dirty, {}
            stale = {i for i, t in self._arrival.items()
                     if timeout > 0.0 and now - t > timeout} - set(dirty)
            values = dict(self._value)
            raws = dict(self._raw)
            for i in dirty:
                self._applied_tag[i] = self._tag[i]
        t_ns = time_ns(sim.t)
        for i, raw in dirty.items():
            self._stale.discard(i)
            self._zeroed.discard(i)
            self.put(sim, values[i], i)
            record(self.topic(i + 1), self.MSG_TYPE, t_ns, raw)
        for i in sorted(stale - self._stale):
            action = (f'set to {self.FAILSAFE:g}' if emergency or self.ALWAYS_FAILSAFE
                      else 'holding the last one')
            self._log.warning(f'{self.LABEL} of coach_{i + 1} stale: nothing for more '
                              f'than {timeout:g} s; {action}')
        for i in sorted(self._stale - stale):          # input_timeout raised or switched off
            self._log.info(f'{self.LABEL} of coach_{i + 1} no longer stale')
        self._stale = stale
        failsafe = stale if emergency or self.ALWAYS_FAILSAFE else set()
        for i in sorted(self._zeroed - failsafe):       # the last command holds again
            self.put(sim, values[i], i)
            record(self.topic(i + 1), self.MSG_TYPE, t_ns, raws[i])
        for i in sorted(failsafe - self._zeroed):
            self.put(sim, self.FAILSAFE, i)
            record(self.topic(i + 1), self.MSG_TYPE, t_ns,
                   serialize_message(self.MSG(data=self.FAILSAFE)))
        self._zeroed = set(failsafe)
