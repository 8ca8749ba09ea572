"""
``sim_node``'s simulation clock output: ``/clock``, or ``clock`` in the node's namespace.

ROS 2 nodes on ``use_sim_time`` read the global ``/clock`` (``rosgraph_msgs/Clock``; the ROS 2
design article "Clock and Time"). One graph with two simulated trains that both publish it
gives every reader two interleaved clocks, running backwards at every other message. So:

- the publisher exists only while ``publish_clock`` is true (no unused advertisement);
- ``namespaced_clock``: publish on ``clock`` relative to the node's namespace instead
  (``/train1/clock`` for a node in ``/train1``); the nodes of that train then read it with
  ``--ros-args -r /clock:=/train1/clock``;
- :meth:`ClockOutput.check_publishers` (a periodic graph query) warns once while another
  publisher shares the clock topic, and again after it has gone and come back.
"""
from __future__ import annotations

from typing import Any

from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from train_dynamics import topics


class ClockOutput:
    """
    The clock publisher of a node: created while publishing, on the global or the namespaced topic.

    Executor thread only for :meth:`configure` and :meth:`check_publishers` (entity creation
    and graph queries); :meth:`publish` from the thread that publishes the outputs, which
    the caller serialises with :meth:`configure` (``sim_node``: the simulation lock).
    """

    def __init__(self, node: Node, qos: Any) -> None:
        self._node = node
        self._qos = qos
        self._pub = None
        self.topic = topics.CLOCK_TOPIC      # as published (relative when namespaced)
        #: other publishers on the clock topic seen by the last check (0: none)
        self.others = 0

    @property
    def active(self) -> bool:
        """Return True while the clock is published (a publisher exists)."""
        return self._pub is not None

    def configure(self, publish: bool, namespaced: bool = False) -> None:
        """Publish the clock (on ``clock`` in the namespace if ``namespaced``) or not."""
        topic = topics.NAMESPACED_CLOCK_TOPIC if namespaced else topics.CLOCK_TOPIC
        if self._pub is not None and (not publish or topic != self.topic):
            self._node.destroy_publisher(self._pub)
            self._pub = None
        self.topic = topic
        if publish and self._pub is None:
            self._pub = self._node.create_publisher(Clock, topic, self._qos)

    def publish(self, stamp: Any) -> Clock | None:
        """Publish ``stamp`` (``builtin_interfaces/Time``) if active; return the message."""
        if self._pub is None:
            return None
        msg = Clock(clock=stamp)
        self._pub.publish(msg)
        return msg

    def subscription_count(self) -> int:
        """Return the subscriptions matched on the clock (0 while not publishing)."""
        return 0 if self._pub is None else self._pub.get_subscription_count()

    def check_publishers(self) -> int:
        """
        Count the other publishers on the clock topic while active; warn when they appear.

        Returns their number (0 while not publishing).
        """
        if self._pub is None:
            self.others = 0
            return 0
        name = self._pub.topic_name
        others = max(self._node.count_publishers(name) - 1, 0)
        if others and not self.others:
            self._node.get_logger().warning(
                f'{others} other publisher(s) on {name}: nodes on use_sim_time see the '
                'simulation times of both, interleaved (time jumps back). Give each train its '
                'own clock: namespaced_clock:=true, or publish_clock:=false on all but one')
        self.others = others
        return others
