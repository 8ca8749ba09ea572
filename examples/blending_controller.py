"""An external blending controller (``blending: external``): ED first, friction the rest."""
import sys

import rclpy
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Float64

ATM, G = 101325.0, 9.81                       # [Pa], [m/s^2]


class BlendingController(Node):
    def __init__(self):
        super().__init__('blending_controller')
        p = {k: self.declare_parameter(k, v).value for k, v in (
            ('target_deceleration', 0.8), ('jerk_limit', 0.8), ('motor_cars', [1, 4]),
            ('masses', [34000.0, 26000.0, 26000.0, 34000.0]), ('brake_ratio', 0.16),
            ('rotating_mass_factors', [0.08, 0.04, 0.04, 0.08]),
            ('max_cylinder_pressure', 380000.0))}
        self.p = p
        self.inertia = [m * (1 + f) for m, f in zip(p['masses'], p['rotating_mass_factors'])]
        self.a_ref, self.ed_cmd, self.t_last = 0.0, 0.0, None
        self.inbox = {}                       # stamp -> {topic: message}: one period's outputs
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.cyl = [self.create_publisher(FluidPressure, f'coach_{i}/brake_cylinder/pressure',
                                          qos) for i in range(1, len(p['masses']) + 1)]
        self.ed = {i: self.create_publisher(Float64, f'coach_{i}/traction/command', qos)
                   for i in p['motor_cars']}
        for topic in ('coaches', 'brake_blending'):
            self.create_subscription(JointState, topic, lambda m, k=topic: self.take(k, m), qos)

    def take(self, topic, msg):
        """Answer an output period once both of its messages are in (deterministic)."""
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        period = self.inbox.setdefault(t, {})
        period[topic] = msg
        if len(period) == 2:
            del self.inbox[t]
            self.answer(t, period['coaches'], period['brake_blending'])

    def answer(self, t, coaches, blending):
        dt = 0.0 if self.t_last is None else t - self.t_last
        self.t_last = t
        target = self.p['target_deceleration']
        self.a_ref = min(target, self.a_ref + self.p['jerk_limit'] * dt)
        demand = self.a_ref * sum(self.inertia)               # [N]
        ed = sum(blending.position)                           # achieved ED force [N]
        if demand <= 0.0:                                     # ED command: a fraction of
            self.ed_cmd = 0.0                                 # the ED available now,
        elif self.ed_cmd > 0.05 and ed > 0.0:                 # scaled to give the demand
            self.ed_cmd = min(1.0, demand * self.ed_cmd / ed)
        else:
            self.ed_cmd = 1.0
        rest = max(demand - ed, 0.0) / sum(self.inertia)      # friction, per kg, load-weighed
        for i, pub in enumerate(self.cyl):
            force = rest * self.inertia[i]
            gauge = force / (self.p['brake_ratio'] * self.p['masses'][i] * G)
            out = FluidPressure(fluid_pressure=min(gauge, 1.0) *
                                self.p['max_cylinder_pressure'] + ATM)
            out.header.stamp = coaches.header.stamp           # the answer to this output
            pub.publish(out)
        for pub in self.ed.values():
            pub.publish(Float64(data=-self.ed_cmd))


def main(args=None):
    rclpy.init(args=args)
    node = BlendingController()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
