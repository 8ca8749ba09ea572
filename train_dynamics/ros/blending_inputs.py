"""
The brake control unit's inputs of ``sim_node`` (``blending: builtin``).

``brake_demand``, ``brake_emergency``, ``ed_brake/trip`` (``std_msgs/Float64``, topics of
:mod:`train_dynamics.topics`; meaning in :mod:`train_dynamics.simulation.demand`), subscribed
best-effort keep-last 10 while the run blends. The latest value of each reaches the
simulator at the next integration step; the brake control unit acts on it at its next cycle
(``blending_period``). Recorded as received. Rejected and counted with the traction commands'
reasons: ``non_finite``, ``out_of_range`` (a negative demand, or a fraction above 1),
``malformed``.

Lock-step (``blending`` in ``lockstep_inputs``): as the traction commands
(:mod:`train_dynamics.ros.traction_inputs`), a Float64 has no stamp, so a value answers the
latest output published before it arrived; each period waits until the applied value of
**each** of the three topics answers its output (a controller or test script sends all three
once per output, the same value again when nothing changes), and a second value on one topic
to one output is not used (counted). The values of a period are applied in the fixed order
demand, emergency, ED trip, whatever order they arrived in, so that the run is the same on
every run. With ``blending: external`` the family is the motor cars' ED force commands
``coach_<i>/ed_brake/force`` (:mod:`train_dynamics.ros.ed_force_inputs`), which this class
holds, starts and applies too.
"""
from __future__ import annotations

import threading
import time
from typing import Any, Callable

from rclpy.node import Node
from std_msgs.msg import Float64

from train_dynamics import topics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import time_ns
from train_dynamics.ros.ed_force_inputs import EdForceInputs, motor_cars
from train_dynamics.ros.traction_inputs import float64_command, Record, Reject
from train_dynamics.simulation.demand import (apply_blending_input, blending_rejection,
                                              BLENDING_TOPICS)


class BlendingInputs:
    """Subscribe to, check and hold the brake control unit's inputs of one node."""

    def __init__(self, node: Node, qos: Any, reject: Reject,
                 notify: Callable[[], None] = lambda: None) -> None:
        self._node = node
        self._qos = qos
        self._reject = reject
        self._notify = notify
        self._subs: dict[str, Any] = {}
        self._lock = threading.Lock()
        #: kind -> (value, raw CDR) received and not yet applied
        self._pending: dict[str, tuple[float, bytes, int]] = {}
        self._cfg = None
        self._accepted = 0
        self._period_ns = -1                       # stamp of the latest output published
        self._tag: dict[str, int] = {}             # the output each topic's last value answers
        self._applied_tag: dict[str, int] = {}     # simulation lock: of the value applied
        #: blending external: the motor cars' ED force commands
        self.ed = EdForceInputs(node, qos, reject, notify)
        self._dedupe = False
        self._duplicates = 0
        self._on_duplicate: Callable[[str], None] | None = None

    @property
    def dedupe(self) -> bool:
        """Lock-step on these inputs: a second value after one output is not used."""
        return self._dedupe

    @dedupe.setter
    def dedupe(self, value: bool) -> None:
        self._dedupe = self.ed.dedupe = bool(value)

    @property
    def on_duplicate(self) -> Callable[[str], None] | None:
        """Return what is called with the resolved topic of an answer not used (warns)."""
        return self._on_duplicate

    @on_duplicate.setter
    def on_duplicate(self, value: Callable[[str], None] | None) -> None:
        self._on_duplicate = self.ed.on_duplicate = value

    @property
    def accepted(self) -> int:
        """Return how many values were taken, the ED force commands included."""
        return self._accepted + self.ed.accepted

    @property
    def duplicates(self) -> int:
        """Return the values not used because their topic had answered the output."""
        return self._duplicates + self.ed.duplicates

    def start(self, cfg: Any) -> None:
        """Subscribe (``blending: builtin``) or unsubscribe for a new run of ``cfg``."""
        with self._lock:
            self._pending = {}
            self._period_ns = -1
            self._tag = {}
        self._applied_tag = {}
        self._duplicates = 0
        self._cfg = cfg
        self.ed.start(motor_cars(cfg))
        active = cfg.blending == 'builtin'
        if active and not self._subs:
            self._subscribe()
        elif not active and self._subs:
            self._unsubscribe()

    def _subscribe(self) -> None:
        for kind, topic in BLENDING_TOPICS.items():
            name = self._node.resolve_topic_name(topic)
            self._subs[kind] = self._node.create_subscription(
                Float64, name, lambda data, k=kind, n=name: self._on_value(k, n, data),
                self._qos, raw=True)

    def _unsubscribe(self) -> None:
        for sub in self._subs.values():
            self._node.destroy_subscription(sub)
        self._subs = {}

    def set_qos(self, qos: Any) -> None:
        """Subscribe with ``qos`` from now on (reliable in lock-step)."""
        if qos == self._qos:
            return
        self._qos = qos
        self.ed.set_qos(qos)
        if self._subs:
            self._unsubscribe()
            self._subscribe()

    def subscriptions(self) -> list[Any]:
        """Return the subscriptions of the family's topics ([] when the run does not blend)."""
        return list(self._subs.values()) + self.ed.subscriptions()

    def output_published(self, t_ns: int) -> None:
        """Tag the values arriving from now on as answers to the output stamped ``t_ns``."""
        with self._lock:
            self._period_ns = t_ns
        self.ed.output_published(t_ns)

    def unanswered(self, t_ns: int) -> list[str]:
        """Lock-step: the topics whose applied value does not answer the output ``t_ns``."""
        out = self.ed.unanswered(t_ns)
        if not self._subs:
            return out
        tags = self._applied_tag
        return out + [topic for kind, topic in BLENDING_TOPICS.items()
                      if tags.get(kind) != t_ns]

    @property
    def active(self) -> bool:
        """Return True if the run takes the brake control unit's inputs (or ED forces)."""
        return bool(self._subs) or self.ed.active

    def _on_value(self, kind: str, resolved: str, data: bytes) -> None:
        cfg = self._cfg

        def rule(value: float):
            why = blending_rejection(kind, value, cfg)
            return None if why is None else (why, f'{BLENDING_TOPICS[kind]} {value:g}')
        try:
            value = float64_command(data, rule)
        except ValueError as exc:
            self._reject(resolved, *exc.args)
            return
        with self._lock:
            duplicate = (self.dedupe and self._period_ns >= 0
                         and self._tag.get(kind) == self._period_ns)
            if not duplicate:
                self._pending[kind] = (value, bytes(data), self._period_ns)
                self._tag[kind] = self._period_ns
        if duplicate:          # lock-step: the first value after the output answers it
            self._duplicates += 1
            if self.on_duplicate is not None:
                self.on_duplicate(resolved)
            return
        self._accepted += 1
        self._notify()

    def apply(self, sim: TrainSimulator, record: Record, now: float | None = None,
              timeout: float = 0.0) -> None:
        """
        Put the values received since the last call into ``sim``'s brake control unit.

        ``timeout`` [s wall] > 0: the ED force commands older than that at ``now``
        (time.monotonic) release their car's ED (EdForceInputs' fail-safe).
        """
        if sim.ed_force is not None and self.ed.active:     # blending external
            self.ed.apply(time.monotonic() if now is None else now, sim, record, timeout,
                          False)
        if not self._subs or sim.bcu is None:
            return
        with self._lock:
            pending, self._pending = self._pending, {}
        for kind in BLENDING_TOPICS:              # a fixed order, not the arrival order
            if kind not in pending:
                continue
            value, raw, self._applied_tag[kind] = pending[kind]
            apply_blending_input(sim, kind, value)
            record(BLENDING_TOPICS[kind], topics.FLOAT64, time_ns(sim.t), raw)
