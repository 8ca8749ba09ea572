"""
The brake control unit's inputs of ``sim_node`` (``blending: builtin``).

``brake_demand``, ``brake_emergency``, ``ed_brake/trip`` (``std_msgs/Float64``, topics of
:mod:`train_dynamics.topics`; meaning in :mod:`train_dynamics.simulation.demand`), subscribed
best-effort keep-last 10 while the run blends. The latest value of each reaches the
simulator at the next integration step; the brake control unit acts on it at its next cycle
(``blending_period``). Recorded as received. Rejected and counted with the traction commands'
reasons: ``non_finite``, ``out_of_range`` (a negative demand, or a fraction above 1),
``malformed``.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from rclpy.node import Node
from std_msgs.msg import Float64

from train_dynamics import topics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import time_ns
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
        self._pending: dict[str, tuple[float, bytes]] = {}
        self._cfg = None
        self.accepted = 0

    def start(self, cfg: Any) -> None:
        """Subscribe (``blending: builtin``) or unsubscribe for a new run of ``cfg``."""
        with self._lock:
            self._pending = {}
        self._cfg = cfg
        active = cfg.blending == 'builtin'
        if active and not self._subs:
            for kind, topic in BLENDING_TOPICS.items():
                name = self._node.resolve_topic_name(topic)
                self._subs[kind] = self._node.create_subscription(
                    Float64, name, lambda data, k=kind, n=name: self._on_value(k, n, data),
                    self._qos, raw=True)
        elif not active and self._subs:
            for sub in self._subs.values():
                self._node.destroy_subscription(sub)
            self._subs = {}

    @property
    def active(self) -> bool:
        """Return True if the run takes the brake control unit's inputs."""
        return bool(self._subs)

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
            self._pending[kind] = (value, bytes(data))
        self.accepted += 1
        self._notify()

    def apply(self, sim: TrainSimulator, record: Record) -> None:
        """Put the values received since the last call into ``sim``'s brake control unit."""
        if not self._subs or sim.bcu is None:
            return
        with self._lock:
            pending, self._pending = self._pending, {}
        for kind, (value, raw) in pending.items():
            apply_blending_input(sim, kind, value)
            record(BLENDING_TOPICS[kind], topics.FLOAT64, time_ns(sim.t), raw)
