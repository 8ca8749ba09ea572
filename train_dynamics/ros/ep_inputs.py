"""
The EP / ECP input of ``sim_node``: ``brake_ep/command`` (``brake_system`` ep or ecp).

``std_msgs/Float64``, a fraction of full service in [0, 1] (0 release), subscribed best-effort
keep-last 10 while the train has an EP or ECP brake (``brake_model`` pneumatic). The latest
command reaches the simulator at the next integration step and acts at the vehicles after the
EP valve delay (:meth:`train_dynamics.physics.pneumatic.PneumaticBrake.set_ep_command`); it is
recorded as received. Rejected and counted with the brake inputs' reasons: ``non_finite``,
``out_of_range``, ``malformed``.

Lock-step (``ep`` in ``lockstep_inputs``): as the traction commands
(:mod:`train_dynamics.ros.traction_inputs`), a command answers the latest output published
before it arrived; each period waits until the applied command answers its output.

Train line: healthy while commands arrive. With ``input_timeout`` > 0, no command for that many
wall seconds after a first one is a lost train line (EP: the pipe brakes, ECP: penalty
application); the next command restores it.
"""
from __future__ import annotations

import threading
import time
from typing import Any, Callable

from rclpy.node import Node
from std_msgs.msg import Float64

from train_dynamics import topics
from train_dynamics.physics.config import ep_rejection
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import time_ns
from train_dynamics.ros.traction_inputs import float64_command, Record, Reject


def ep_command(data: bytes) -> float:
    """Return the command of a raw EP Float64; raise ValueError(reason, detail)."""
    return float64_command(data, ep_rejection)


class EpInputs:
    """Subscribe to, check and hold the EP / ECP train-line command of one node."""

    def __init__(self, node: Node, qos: Any, reject: Reject,
                 notify: Callable[[], None] = lambda: None) -> None:
        self._node = node
        self._qos = qos
        self._reject = reject
        self._notify = notify           # called after each accepted command (wakes lock-step)
        self._sub = None
        self._lock = threading.Lock()
        #: the latest command not yet applied: (value, raw CDR, the output it answers [ns])
        self._pending: tuple[float, bytes, int] | None = None
        self._arrival: float | None = None
        self._period_ns = -1            # stamp of the latest output published
        self._applied_tag = -1          # simulation lock: the output the applied one answers
        self._line = True
        self.accepted = 0
        self._tag = -1                  # the output the last accepted command answers
        #: lock-step on this command: a second command after one output is not used
        self.dedupe = False
        self.duplicates = 0
        self.on_duplicate: Callable[[str], None] | None = None   # (resolved topic): warn

    def start(self, active: bool) -> None:
        """Subscribe (``active``: an EP or ECP train) or unsubscribe for a new run."""
        with self._lock:
            self._pending = None
            self._arrival = None
            self._period_ns = -1
            self._tag = -1
        self._applied_tag = -1
        self.duplicates = 0
        self._line = True
        if active and self._sub is None:
            self._subscribe()
        elif not active and self._sub is not None:
            self._node.destroy_subscription(self._sub)
            self._sub = None

    def _subscribe(self) -> None:
        name = self._node.resolve_topic_name(topics.EP_COMMAND_TOPIC)
        self._sub = self._node.create_subscription(
            Float64, name, lambda data: self._on_command(name, data), self._qos, raw=True)

    def set_qos(self, qos: Any) -> None:
        """Subscribe with ``qos`` from now on (reliable in lock-step)."""
        if qos == self._qos:
            return
        self._qos = qos
        if self._sub is not None:
            self._node.destroy_subscription(self._sub)
            self._subscribe()

    def subscriptions(self) -> list[Any]:
        """Return the subscription of the command topic ([] when the run takes none)."""
        return [] if self._sub is None else [self._sub]

    @property
    def active(self) -> bool:
        """Return True if the run takes EP / ECP commands."""
        return self._sub is not None

    def subscribed(self, resolved: str) -> bool:
        """Return True if ``resolved`` is the command topic we take."""
        return self._sub is not None and resolved == self._sub.topic_name

    def _on_command(self, resolved: str, data: bytes) -> None:
        try:
            value = ep_command(data)
        except ValueError as exc:
            self._reject(resolved, *exc.args)
            return
        with self._lock:
            duplicate = self.dedupe and self._period_ns >= 0 and self._tag == self._period_ns
            if not duplicate:
                self._pending = (value, bytes(data), self._period_ns)
                self._arrival = time.monotonic()
                self._tag = self._period_ns
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
        """Lock-step: ``[brake_ep/command]`` unless the applied command answers ``t_ns``."""
        if self._sub is None or self._applied_tag == t_ns:
            return []
        return [topics.EP_COMMAND_TOPIC]

    def connected(self) -> bool:
        """Return True if the command topic has a publisher (or is not taken)."""
        return self._sub is None or self._sub.get_publisher_count() > 0

    def apply(self, now: float, sim: TrainSimulator, record: Record, timeout: float) -> None:
        """Put the command received since the last call into ``sim``; supervise the line."""
        if self._sub is None:
            return
        with self._lock:
            pending, self._pending = self._pending, None
            arrival = self._arrival
        line = not (timeout > 0.0 and arrival is not None and now - arrival > timeout)
        if pending is not None:
            value, raw, self._applied_tag = pending
            sim.set_ep_command(value)
            record(topics.EP_COMMAND_TOPIC, topics.FLOAT64, time_ns(sim.t), raw)
        if line != self._line:
            self._line = line
            sim.set_train_line(line)
            self._node.get_logger().warning(
                f'{topics.EP_COMMAND_TOPIC}: train line {"restored" if line else "lost"}')
