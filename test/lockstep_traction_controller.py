"""
A lock-step controller of traction and brake (test support, run as a process of its own).

Answers every ``coaches`` output: the head brake pipe released (5 bar gauge, stamped with the
output's stamp), then, ``delay`` wall seconds later, the locomotive's traction command
``clip(gain * (target - v_1), -1, 1)`` on ``coach_1/traction/command`` (std_msgs/Float64:
no stamp; it answers the output published before it arrives). The delay makes a traction
command that the node did not wait for land in a later period.
"""
import sys
import time

from controller_main import spin
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64

ATM, RELEASE = 101325.0, 5.0e5      # [Pa]: atmosphere; released pipe, gauge


def command(v: float, target: float, gain: float) -> float:
    """Return the traction command for the speed ``v`` [m/s] (target [m/s], gain [s/m])."""
    return min(max(gain * (target - v), -1.0), 1.0)


class TractionController(Node):
    """Speed control by traction, brake released; one answer per output on each input."""

    def __init__(self):
        super().__init__('traction_controller')
        self.target = self.declare_parameter('target_speed', 15.0).value   # [m/s]
        self.gain = self.declare_parameter('gain', 0.5).value               # [1 per m/s]
        self.delay = self.declare_parameter('delay', 0.005).value           # [s wall]
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.brake = self.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
        self.traction = self.create_publisher(Float64, 'coach_1/traction/command', qos)
        self.create_subscription(JointState, 'coaches', self.on_coaches, qos)

    def on_coaches(self, msg):
        out = FluidPressure(fluid_pressure=RELEASE + ATM)
        out.header.stamp = msg.header.stamp
        self.brake.publish(out)
        time.sleep(self.delay)
        self.traction.publish(Float64(data=command(msg.velocity[0], self.target, self.gain)))


def main(args=None):
    spin(TractionController, args)


if __name__ == '__main__':
    sys.exit(main())
