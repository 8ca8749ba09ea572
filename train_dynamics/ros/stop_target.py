"""
The stopping target's input topic: ``target_stop_position`` (``std_msgs/msg/Float64``).

A run with a target stopping point (parameter ``target_stop_position`` set) subscribes to the
topic of the same name (relative). A message moves the target to its value [m, track position
of vehicle 1's front], checked as the parameter is (finite, within its range): the next
output's ``distance_to_go`` is measured to it, and the recording holds the message at the
simulation time it took effect. A rejected value is logged (at most once per
:data:`WARN_PERIOD` wall seconds) and counted, and changes nothing. QoS: best-effort, keep-last
10 (the brake inputs' :data:`~train_dynamics.ros.brake_channel.INPUT_QOS`: reliable and
best-effort publishers both connect).
"""
from __future__ import annotations

import struct
import time
from typing import Any, Callable

from rclpy.node import Node
from std_msgs.msg import Float64

from train_dynamics import topics
from train_dynamics.physics.config import check_value, ConfigError, PARAMETERS
from train_dynamics.recording.outputs import time_ns

#: [s wall] at most one warning per this period about rejected targets
WARN_PERIOD = 5.0


def decode_target(data: bytes) -> float:
    """
    Return the target [m] of a raw Float64; raise ValueError with the reason.

    The value is checked as the parameter ``target_stop_position`` is (its ParamSpec).
    """
    if len(data) < 12:
        raise ValueError(f'malformed: {len(data)} bytes')
    value = struct.unpack_from('<d' if data[1] == 1 else '>d', data, 4)[0]
    try:
        check_value(PARAMETERS['target_stop_position'], [value])
    except ConfigError as exc:
        raise ValueError(str(exc)) from None
    return value


class StopTargetInput:
    """
    The subscription that moves the stopping target of the running outputs.

    ``lock``: the simulation lock (held while the target changes and the message is
    recorded); ``run``: returns the running output state (its ``target_stop_position``) and
    the simulation time [s], or None when the run has no target; ``record(topic, msgtype,
    t_ns, data)``: records an accepted message.
    """

    def __init__(self, node: Node, qos: Any, lock: Any,
                 run: Callable[[], tuple[Any, float] | None],
                 record: Callable[[str, str, int, bytes], None]) -> None:
        self._node, self._qos, self._lock = node, qos, lock
        self._run, self._record = run, record
        self._sub = None
        self.accepted = 0
        self.rejected = 0
        self._warned = -WARN_PERIOD

    def start(self, active: bool) -> None:
        """Subscribe (``active``: the run has a target) or unsubscribe, for a new run."""
        if active and self._sub is None:
            self._sub = self._node.create_subscription(
                Float64, topics.TARGET_STOP_TOPIC, self._on_message, self._qos, raw=True)
        elif not active and self._sub is not None:
            self._node.destroy_subscription(self._sub)
            self._sub = None

    def _on_message(self, data: bytes) -> None:
        try:
            value = decode_target(bytes(data))
        except ValueError as exc:
            self.rejected += 1
            now = time.monotonic()
            if now - self._warned >= WARN_PERIOD:
                self._warned = now
                self._node.get_logger().warning(
                    f'{topics.TARGET_STOP_TOPIC}: rejected ({exc}; {self.rejected} so far)')
            return
        with self._lock.held():
            state = self._run()
            if state is None:
                return
            run, t = state
            old, run.target_stop_position = run.target_stop_position, value
            self._record(topics.TARGET_STOP_TOPIC, topics.FLOAT64, time_ns(t), bytes(data))
        self.accepted += 1
        self._node.get_logger().info(
            f't = {t:.3f} s: target stopping point {old:g} m -> {value:g} m')
