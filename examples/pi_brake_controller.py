"""A PI deceleration controller on ``coaches``: the head-end brake-pipe pressure it commands."""
import sys

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState

ATM, RELEASE, FULL_SERVICE = 101325.0, 5.0e5, 3.4e5   # [Pa]: atmosphere; pipe gauge pressures


class PiBrakeController(Node):
    def __init__(self):
        super().__init__('pi_brake_controller')
        self.target = self.declare_parameter('target_deceleration', 0.6).value   # [m/s^2]
        self.kp = self.declare_parameter('kp', 2.0e5).value     # [Pa per m/s^2]
        self.ki = self.declare_parameter('ki', 1.0e5).value     # [Pa per m/s]
        self.last = None          # (t [s], v [m/s]) of coach_1 at the previous output
        self.integral = 0.0
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
        self.create_subscription(JointState, 'coaches', self.on_coaches, qos)

    def on_coaches(self, msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        v = msg.velocity[0]
        error = 0.0
        if self.last is not None and t > self.last[0]:
            deceleration = (self.last[1] - v) / (t - self.last[0])
            error = self.target - deceleration
            self.integral += error * (t - self.last[0])
        self.last = (t, v)
        drop = self.kp * error + self.ki * self.integral if v > 0.1 else RELEASE - FULL_SERVICE
        gauge = min(max(RELEASE - drop, FULL_SERVICE), RELEASE)
        out = FluidPressure(fluid_pressure=gauge + ATM)
        out.header.stamp = msg.header.stamp      # the answer to this output (lock-step)
        self.pub.publish(out)


def main(args=None):
    rclpy.init(args=args)
    node = PiBrakeController()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
