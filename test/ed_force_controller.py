"""
A lock-step ED force controller (test support, run as a process of its own).

Answers every ``coaches`` output with ``force`` [N] on ``coach_<i>/ed_brake/force`` of each
of ``motor_cars`` (std_msgs/Float64; ``blending: external``).
"""
import sys

from controller_main import spin
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64


class EdForceController(Node):
    """The same ED force of every motor car, one command per car and output."""

    def __init__(self):
        super().__init__('ed_force_controller')
        self.force = self.declare_parameter('force', 30000.0).value           # [N]
        cars = self.declare_parameter('motor_cars', [1, 4]).value
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pubs = [self.create_publisher(Float64, f'coach_{i}/ed_brake/force', qos)
                     for i in cars]
        self.create_subscription(JointState, 'coaches', self.on_coaches, qos)

    def on_coaches(self, msg):
        for pub in self.pubs:
            pub.publish(Float64(data=float(self.force)))


def main(args=None):
    spin(EdForceController, args)


if __name__ == '__main__':
    sys.exit(main())
