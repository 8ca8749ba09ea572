"""The failing twin of pi_brake_controller.py: it vents the brake pipe at once (emergency)."""
import sys

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState

ATM = 101325.0   # [Pa]


class HarshBrakeController(Node):
    def __init__(self):
        super().__init__('harsh_brake_controller')
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pub = self.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
        self.create_subscription(JointState, 'coaches', self.on_coaches, qos)

    def on_coaches(self, msg):
        out = FluidPressure(fluid_pressure=ATM)      # 0 Pa gauge: emergency from t = 0
        out.header.stamp = msg.header.stamp
        self.pub.publish(out)


def main(args=None):
    rclpy.init(args=args)
    node = HarshBrakeController()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
