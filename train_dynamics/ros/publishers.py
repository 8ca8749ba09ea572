"""
The outputs of ``sim_node``: publishers, the output schedule and the run's recorder.

Outputs (reliable, keep-last 10, ``header.stamp`` = simulation time), at ``publish_rate`` in
simulation time, at the integration steps nearest to k / publish_rate
(:func:`train_dynamics.simulation.runner.output_step`, the offline command's grid): the topics
of the table :data:`train_dynamics.recording.output_specs.OUTPUTS` that the run has (each
row says what it carries and when a run has it; docs/ros_interface.md shows the table), and
``/clock`` (``rosgraph_msgs/Clock``) when ``publish_clock`` (``clock`` in the node's namespace
with ``namespaced_clock``: :mod:`train_dynamics.ros.clock`). A topic has a publisher only
while the run has it: a reset to a run without it destroys its publisher, and the clock's
exists only while it is published.

Output messages are CDR-encoded once per output (:class:`OutputEncoder`: names and header
layout computed once), then published and recorded as the same bytes: ~10x cheaper than
filling JointState objects whose N names rclpy converts again on every publish (the simulation
thread holds the GIL meanwhile: output jitter).
"""
from __future__ import annotations

import functools
import importlib
import time
from typing import Any, Callable

from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message

from train_dynamics import topics
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.output_specs import OutputRun
from train_dynamics.recording.outputs import OutputEncoder, time_ns
from train_dynamics.ros.clock import ClockOutput
from train_dynamics.ros.live_metrics import LiveMetrics
from train_dynamics.ros.recorder import BagWriter
from train_dynamics.simulation.runner import output_step

OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)


@functools.lru_cache(maxsize=None)
def message_class(msgtype: str) -> Any:
    """Return the rclpy message class of a type string (``std_msgs/msg/Float64``)."""
    package, sub, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{package}.{sub}'), name)


def stamp(t_ns: int) -> Time:
    """Return the ``builtin_interfaces/Time`` of ``t_ns`` nanoseconds."""
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


class Outputs:
    """
    Publish the outputs at their steps, and record what is published.

    Lock discipline: every attribute is guarded by the simulation lock. The simulation thread
    calls :meth:`publish_due` and :meth:`record` while it holds it; the executor thread calls
    :meth:`start` (reset), :meth:`record` (diagnostics) and sets ``publish_clock`` under it.
    The ``writer`` of the run is owned here: replaced by :meth:`start`, taken back by
    :meth:`take_writer` (both under the lock); closing it is up to the caller.
    ``metrics`` (:class:`LiveMetrics`, never replaced) has its own lock: the pacing folds
    and /diagnostics reads it without the simulation lock.
    """

    def __init__(self, node: Node) -> None:
        #: topic -> publisher of the run's outputs (:meth:`start` makes and destroys them)
        self._pubs: dict[str, Any] = {}
        #: /clock (or the namespaced clock), advertised only while publish_clock
        self.clock = ClockOutput(node, OUTPUT_QOS)
        self._node = node
        self.writer: BagWriter | None = None
        self.rate = 0.0                 # [Hz] publish_rate of the run
        self.next_step = 0              # integration step of the next output
        self._h = 0.0
        self._index = 0                 # number of the next output, t = index / rate
        self._encoder: OutputEncoder | None = None
        self.published = 0              # outputs published in this run
        self.last_step = -1             # integration step of the last output
        self.last_t_ns = -1             # [ns] its stamp
        self.last_wall = 0.0            # [s wall, monotonic] when it was published
        self.metrics = LiveMetrics()    # the run's metrics, fed every output
        #: called with the stamp [ns] of each output just before it is published
        self.on_output: Callable[[int], None] | None = None

    def start(self, encoder: OutputEncoder, rate: float, h: float, publish_clock: bool,
              writer: BagWriter | None, metrics: RunMetrics | None = None) -> None:
        """
        Begin a run at t = 0: outputs at ``rate`` [Hz] on steps ``h``.

        ``encoder``: the run's output encoder (``OutputEncoder.for_config``): the topics
        published (and recorded) at every output, as the offline command writes them;
        ``metrics``: the run metrics, fed with every published sample (as the offline
        command does).
        """
        self.metrics.start(metrics)
        self._encoder = encoder
        for topic in [t for t in self._pubs if t not in encoder.topics]:
            self._node.destroy_publisher(self._pubs.pop(topic))
        for topic, msgtype in zip(encoder.topics, encoder.msgtypes):
            if topic not in self._pubs:
                cls = self._message_class(msgtype)
                if cls is not None:
                    self._pubs[topic] = self._node.create_publisher(cls, topic, OUTPUT_QOS)
        self.rate = float(rate)
        self._h = h
        self.publish_clock = bool(publish_clock)
        self.writer = writer
        self._index = 0
        self.next_step = 0
        self.published = 0
        self.last_step = -1
        self.last_t_ns = -1

    def _message_class(self, msgtype: str) -> Any:
        """
        Return the rclpy class of ``msgtype``; None for a typed one not built (warned once).

        The typed messages (``train_dynamics_msgs``) need the package that
        ``tools/build_msgs.sh`` builds; without it their topics are recorded, not published.
        """
        try:
            return message_class(msgtype)
        except ImportError as exc:
            if not msgtype.startswith(topics.MSGS_PACKAGE + '/'):
                raise
            self._node.get_logger().warning(
                f'{msgtype} not published: {exc} (build it: tools/build_msgs.sh)', once=True)
            return None

    @property
    def publish_clock(self) -> bool:
        """Return True while the clock is published."""
        return self.clock.active

    @publish_clock.setter
    def publish_clock(self, value: bool) -> None:
        """Publish the clock or not (``namespaced_clock``: where); executor thread."""
        self.clock.configure(bool(value), bool(self._node.node_value('namespaced_clock')))

    @property
    def run(self) -> OutputRun | None:
        """Return what the run's outputs keep between two (the stopping target), or None."""
        return None if self._encoder is None else self._encoder.run

    def subscribed(self) -> bool:
        """Return True if a subscriber is matched on one of the outputs (not ``/clock``)."""
        return any(pub.get_subscription_count() > 0 for pub in self._pubs.values())

    def clock_subscribed(self) -> bool:
        """Return True if a subscriber is matched on ``/clock`` (lock-step on the clock)."""
        return self.clock.subscription_count() > 0

    def repeat_clock(self) -> None:
        """Publish ``/clock`` of the last output again, unrecorded (a lost one stalls a timer)."""
        if self.last_t_ns >= 0:
            self.clock.publish(stamp(self.last_t_ns))

    def take_writer(self) -> BagWriter | None:
        """Return the run's writer and stop recording (to close it, or at a reset)."""
        writer, self.writer = self.writer, None
        return writer

    def record(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        """Record raw CDR ``data`` at bag time ``t_ns`` (if recording)."""
        if self.writer is not None:
            self.writer.write(topic, msgtype, t_ns, data)

    def publish_due(self, sim: TrainSimulator) -> None:
        """Publish if the present step is an output step; move on to the next output step."""
        steps = sim.steps
        if steps < self.next_step:
            return
        self._publish(sim)
        while self.next_step <= steps:
            self._index += 1
            self.next_step = output_step(self._index, self.rate, self._h)

    def _publish(self, sim: TrainSimulator) -> None:
        """Publish (and record) the outputs of the present state."""
        t_ns = time_ns(sim.t)
        if self.on_output is not None:
            self.on_output(t_ns)
        encoder = self._encoder
        encoded = encoder.encode(t_ns, sim)
        pubs = self._pubs
        for topic, data in zip(encoder.topics, encoded):
            pub = pubs.get(topic)
            if pub is not None:
                pub.publish(data)
        self.metrics.put(sim)
        clock = self.clock.publish(stamp(t_ns))
        w = self.writer
        if w is not None:
            for topic, msgtype, data in zip(encoder.topics, encoder.msgtypes, encoded):
                w.write(topic, msgtype, t_ns, data)
            if clock is not None:
                w.write(self.clock.topic, topics.CLOCK_TYPE, t_ns, serialize_message(clock))
        self.published += 1
        self.last_step = sim.steps
        self.last_t_ns = t_ns
        self.last_wall = time.monotonic()
