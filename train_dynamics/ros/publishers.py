"""
The outputs of ``sim_node``: publishers, the output schedule and the run's recorder.

Outputs (reliable, keep-last 10, ``header.stamp`` = simulation time), at ``publish_rate`` in
simulation time, at the integration steps nearest to k / publish_rate
(:func:`train_dynamics.simulation.runner.output_step`, the offline command's grid):

- ``couplers``: JointState ``coupler_1..N-1``: position y [m], velocity ydot [m/s], effort F [N];
- ``coaches``: JointState ``coach_1..N``: position x [m], velocity v [m/s], effort Fb [N];
- ``brake_cylinders``: JointState ``coach_1..N``: position = brake-cylinder gauge pressure [Pa],
  effort = local brake-pipe gauge pressure [Pa] (as the offline command writes);
- ``brake_ep/state`` (``brake_system`` ep or ecp), ``distributed_power/state`` (remote
  locomotives): the EP / ECP command and valve state per vehicle, the radio link per remote
  (:mod:`train_dynamics.recording.outputs`);
- ``vehicle_motion``: JointState ``coach_1..N`` (``frame_id`` ``track``): position = track
  position [m], velocity v [m/s], effort = acceleration [m/s^2] over the last output period;
- ``vehicle_forces`` (a train with resistance, track or traction): JointState ``coach_1..N``:
  position = traction / dynamic-brake force, velocity = running + curve resistance, effort =
  gradient force [N, on the vehicle, forward > 0];
- ``wheelsets`` (a train with rotating wheelsets): JointState ``coach_1..N``: position =
  available adhesion [-], velocity = wheel peripheral speed [m/s], effort = creep force [N];
- ``/clock`` (``rosgraph_msgs/Clock``) when ``publish_clock``, ``clock`` in the node's
  namespace with ``namespaced_clock`` (:mod:`train_dynamics.ros.clock`).

A topic's publisher exists only while the run publishes it (``brake_reservoirs`` with the
pneumatic brake, the clock while ``publish_clock``): nothing is advertised unused.

Output messages are CDR-encoded once per output (:class:`OutputEncoder`: names and header
layout computed once), then published and recorded as the same bytes: ~10x cheaper than
filling JointState objects whose N names rclpy converts again on every publish (the simulation
thread holds the GIL meanwhile: output jitter).
"""
from __future__ import annotations

import time
from typing import Callable

from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from train_dynamics import topics
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording.outputs import OutputEncoder, time_ns
from train_dynamics.ros.clock import ClockOutput
from train_dynamics.ros.live_metrics import LiveMetrics
from train_dynamics.ros.recorder import BagWriter
from train_dynamics.simulation.runner import output_step

OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)


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
        self._pubs = {topic: node.create_publisher(JointState, topic, OUTPUT_QOS)
                      for topic in topics.OUTPUT_TOPICS}
        #: /clock (or the namespaced clock), advertised only while publish_clock
        self.clock = ClockOutput(node, OUTPUT_QOS)
        self._pub_motion = node.create_publisher(JointState, topics.VEHICLE_MOTION_TOPIC,
                                                 OUTPUT_QOS)
        self._node = node
        self._pub_forces = None         # vehicle_forces, created for a train that has them
        self._forces = False
        self._pub_wheelsets = None      # wheelsets, created for a train that has them
        self._wheelsets = False
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
              writer: BagWriter | None, forces: bool = False,
              metrics: RunMetrics | None = None, wheelsets: bool = False) -> None:
        """
        Begin a run at t = 0: outputs at ``rate`` [Hz] on steps ``h``.

        ``encoder``: the run's output encoder (``OutputEncoder.for_config``): the JointState
        topics published (and recorded) at every output, as the offline command writes
        them; ``forces``: also publish ``vehicle_forces`` (a train with resistance, track or
        traction); ``wheelsets``: also publish ``wheelsets`` (a train with rotating
        wheelsets); ``metrics``: the run metrics, fed with every published sample (as the
        offline command does).
        """
        self.metrics.start(metrics)
        self._encoder = encoder
        self._publish_only(encoder.topics)
        self._forces = bool(forces)
        if self._forces and self._pub_forces is None:
            self._pub_forces = self._node.create_publisher(
                JointState, topics.VEHICLE_FORCES_TOPIC, OUTPUT_QOS)
        self._wheelsets = bool(wheelsets)
        if self._wheelsets and self._pub_wheelsets is None:
            self._pub_wheelsets = self._node.create_publisher(
                JointState, topics.WHEELSETS_TOPIC, OUTPUT_QOS)
        self.rate = float(rate)
        self._h = h
        self.publish_clock = bool(publish_clock)
        self.writer = writer
        self._index = 0
        self.next_step = 0
        self.published = 0
        self.last_step = -1
        self.last_t_ns = -1

    def _publish_only(self, wanted) -> None:
        """Create the JointState publishers of ``wanted`` not yet there; destroy the others."""
        for topic in [t for t in self._pubs if t not in wanted]:
            self._node.destroy_publisher(self._pubs.pop(topic))
        for topic in wanted:     # e.g. the brake-system states, created when first used
            if topic not in self._pubs:
                self._pubs[topic] = self._node.create_publisher(JointState, topic, OUTPUT_QOS)

    @property
    def publish_clock(self) -> bool:
        """Return True while the clock is published."""
        return self.clock.active

    @publish_clock.setter
    def publish_clock(self, value: bool) -> None:
        """Publish the clock or not (``namespaced_clock``: where); executor thread."""
        self.clock.configure(bool(value), bool(self._node.get_parameter('namespaced_clock').value))

    def subscribed(self) -> bool:
        """Return True if a subscriber is matched on one of the JointState outputs."""
        return any(pub.get_subscription_count() > 0 for pub in self._pubs.values())

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
        encoded = self._encoder.encode(t_ns, sim)
        for topic, data in zip(self._encoder.topics, encoded):
            self._pubs[topic].publish(data)
        motion = self._encoder.encode_motion(t_ns, sim)
        self._pub_motion.publish(motion)
        forces = self._encoder.encode_forces(t_ns, sim) if self._forces else None
        if forces is not None:
            self._pub_forces.publish(forces)
        wheels = self._encoder.encode_wheelsets(t_ns, sim) if self._wheelsets else None
        if wheels is not None:
            self._pub_wheelsets.publish(wheels)
        self.metrics.put(sim)
        clock = self.clock.publish(stamp(t_ns))
        w = self.writer
        if w is not None:
            for topic, data in zip(self._encoder.topics, encoded):
                w.write(topic, topics.JOINT_STATE, t_ns, data)
            w.write(topics.VEHICLE_MOTION_TOPIC, topics.JOINT_STATE, t_ns, motion)
            if forces is not None:
                w.write(topics.VEHICLE_FORCES_TOPIC, topics.JOINT_STATE, t_ns, forces)
            if wheels is not None:
                w.write(topics.WHEELSETS_TOPIC, topics.JOINT_STATE, t_ns, wheels)
            if clock is not None:
                w.write(self.clock.topic, topics.CLOCK_TYPE, t_ns, serialize_message(clock))
        self.published += 1
        self.last_step = sim.steps
        self.last_t_ns = t_ns
        self.last_wall = time.monotonic()
