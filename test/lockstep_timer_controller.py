"""
A timer-driven brake controller on ``use_sim_time`` (test support, run as a process of its own).

The ordinary ROS 2 way, nothing lock-step specific in it: it keeps the latest ``coaches``
message and, from a timer of ``period`` seconds on the node's clock (``use_sim_time``: the
simulator's ``/clock``), publishes the head brake-pipe pressure stamped with its clock's now,
proportional to the lead vehicle's speed: ``p = release - gain * v`` [Pa gauge], bounded to
0..release. ``sim_node`` with ``lockstep_answer: clock`` waits for it at every period.
"""
import sys

from controller_main import spin
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState

ATM, RELEASE = 101325.0, 5.0e5      # [Pa]: atmosphere; released pipe, gauge


def pipe_pressure(v: float, gain: float) -> float:
    """Return the head pipe pressure [Pa gauge] for the lead vehicle's speed ``v`` [m/s]."""
    return min(max(RELEASE - gain * v, 0.0), RELEASE)


class TimerController(Node):
    """A brake controller whose commands come from a timer on the simulation clock."""

    def __init__(self):
        super().__init__('timer_controller',
                         parameter_overrides=[Parameter('use_sim_time', value=True)])
        self.period = self.declare_parameter('period', 0.02).value     # [s simulated]
        self.gain = self.declare_parameter('gain', 1.0e4).value        # [Pa per m/s]
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
        self.create_subscription(JointState, 'coaches', self.on_coaches, qos)
        self.speed = None
        self.create_timer(self.period, self.on_timer)

    def on_coaches(self, msg):
        self.speed = msg.velocity[0]

    def on_timer(self):
        if self.speed is None:
            return
        out = FluidPressure(fluid_pressure=pipe_pressure(self.speed, self.gain) + ATM)
        out.header.stamp = self.get_clock().now().to_msg()
        self.pub.publish(out)


def main(args=None):
    spin(TimerController, args)


if __name__ == '__main__':
    sys.exit(main())
