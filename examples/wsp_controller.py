"""A wheel-slide protection controller: valves from ``wheelsets`` (and the ground speed)."""
import sys

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Int8

NORMAL, HOLD, VENT = 0, 1, 2


class WspController(Node):
    """Vent on a large slip or a fast wheel deceleration, hold on a small slip (EN 15595)."""

    def __init__(self):
        super().__init__('wsp_controller')
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.speed = None           # ground speed of each vehicle [m/s] (vehicle_motion)
        self.last = None            # (t [s], wheel speeds [m/s]) of the previous wheelsets
        self.pubs = {}
        self.create_subscription(JointState, 'vehicle_motion', self.on_motion, qos)
        self.create_subscription(JointState, 'wheelsets', self.on_wheelsets, qos)
        self.qos = qos

    def on_motion(self, msg):
        self.speed = list(msg.velocity)

    def on_wheelsets(self, msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        u = list(msg.velocity)
        dt = t - self.last[0] if self.last is not None and t > self.last[0] else None
        for i, name in enumerate(msg.name):
            # coach_<i> or, with bogie_wheelsets, coach_<i>/bogie_<j>: its vehicle's speed
            k = int(name.split('/')[0].split('_')[1]) - 1
            v = self.speed[k] if self.speed is not None else u[i]
            slip = v - u[i]
            decel = (self.last[1][i] - u[i]) / dt if dt else 0.0
            if v < 0.05:            # (nearly) at rest: leave the brake alone
                state = NORMAL
            elif slip > min(0.5 + 0.03 * v, 0.5 * v) or decel > 2.0:
                state = VENT
            elif slip > min(0.2 + 0.01 * v, 0.25 * v) or -decel > 3.0:
                state = HOLD
            else:
                state = NORMAL
            if name not in self.pubs:
                self.pubs[name] = self.create_publisher(Int8, f'{name}/wsp/valve', self.qos)
            self.pubs[name].publish(Int8(data=state))
        self.last = (t, u)


def main(args=None):
    rclpy.init(args=args)
    node = WspController()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
