"""
A stopping controller as a downstream team writes it: ROS 2 as usual, the typed messages.

A node on ``use_sim_time`` keeps the latest ``train_state``
(``train_dynamics_msgs/TrainState``) and, from a timer of ``period`` seconds on its clock,
publishes the head brake-pipe pressure (``sensor_msgs/FluidPressure``, ABSOLUTE [Pa]) stamped
with its clock's now, computed from the state of that instant (a sampled controller: when the
timer fires before that state has arrived, it answers on its arrival).

The law brakes the lead vehicle to a stop at ``target`` [m, track position]: the deceleration
that stops it there, a = v^2 / (2 d) (uniform deceleration over the distance to go d),
feed-forward as a pipe-pressure reduction of ``full_service_drop`` [Pa] per
``full_service_deceleration`` [m/s^2], bounded to 0..full_service_drop.
"""
import sys

import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.time import Time
from sensor_msgs.msg import FluidPressure
from train_dynamics_msgs.msg import TrainState

ATM, RELEASE = 101325.0, 5.0e5      # [Pa]: atmosphere; released pipe, gauge


def pipe_pressure(position: float, speed: float, target: float, drop: float,
                  full: float) -> float:
    """Return the head pipe pressure [Pa gauge] for the lead vehicle at ``position``, ``speed``."""
    to_go = target - position
    if to_go <= 0.0:
        return RELEASE - drop                     # at or past the target: full service
    needed = speed * speed / (2.0 * to_go)        # [m/s^2] stops it at the target
    return RELEASE - min(max(drop * needed / full, 0.0), drop)


class StopController(Node):
    """Stop the train at a target from a timer on the simulation clock."""

    def __init__(self):
        super().__init__('stop_controller',
                         parameter_overrides=[Parameter('use_sim_time', value=True)])
        self.period = self.declare_parameter('period', 0.1).value          # [s simulated]
        self.target = self.declare_parameter('target', 0.0).value          # [m]
        self.drop = self.declare_parameter('full_service_drop', 1.5e5).value  # [Pa]
        self.full = self.declare_parameter('full_service_deceleration', 0.9).value  # [m/s^2]
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
        self.create_subscription(TrainState, 'train_state', self.on_state, qos)
        self.state = None       # (stamp [ns], position [m], speed [m/s]) of the latest
        self.pending = None     # [ns] a sampling instant whose state has not arrived yet
        self.create_timer(self.period, self.on_timer)

    def on_state(self, msg):
        stamp = Time.from_msg(msg.header.stamp).nanoseconds
        self.state = (stamp, msg.position[0], msg.speed[0])
        if self.pending is not None and stamp >= self.pending:
            self.answer(self.pending)

    def on_timer(self):
        now = self.get_clock().now()
        if self.state is not None and self.state[0] >= now.nanoseconds:
            self.answer(now.nanoseconds)
        else:
            self.pending = now.nanoseconds

    def answer(self, stamp):
        """Publish the pipe pressure of the present state, stamped ``stamp`` [ns]."""
        self.pending = None
        _, position, speed = self.state
        p = pipe_pressure(position, speed, self.target, self.drop, self.full)
        out = FluidPressure(fluid_pressure=p + ATM)
        out.header.stamp = Time(nanoseconds=stamp).to_msg()
        self.pub.publish(out)


def main(args=None):
    rclpy.init(args=args)
    node = StopController()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
