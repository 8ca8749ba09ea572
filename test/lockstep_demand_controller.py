"""
A lock-step test script of the brake control unit's inputs (test support, its own process).

Answers every ``coaches`` output with one value on each of ``brake_demand`` (0 before
``demand_time``, then ``demand``), ``brake_emergency`` (0; 1 from ``emergency_time``) and
``ed_brake/trip`` (1 from ``trip_time`` to ``restore_time``), in an order that changes from
output to output and with ``delay`` wall seconds between them: the node must apply a
period's values in one fixed order and wait for all three, or two runs differ.
"""
import sys
import time

from controller_main import spin
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64

TOPICS = ('brake_demand', 'brake_emergency', 'ed_brake/trip')


class DemandScript(Node):
    """Brake demand, emergency and ED trip by the clock of the outputs' stamps."""

    def __init__(self):
        super().__init__('demand_script')
        p = {k: self.declare_parameter(k, v).value for k, v in (
            ('demand_time', 0.5), ('demand', 0.8), ('trip_time', 2.0), ('restore_time', 3.0),
            ('emergency_time', 4.0), ('delay', 0.002))}
        self.p = p
        self.count = 0
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.pubs = {name: self.create_publisher(Float64, name, qos) for name in TOPICS}
        self.create_subscription(JointState, 'coaches', self.on_coaches, qos)

    def on_coaches(self, msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        p = self.p
        values = {'brake_demand': p['demand'] if t >= p['demand_time'] else 0.0,
                  'brake_emergency': 1.0 if t >= p['emergency_time'] else 0.0,
                  'ed_brake/trip': 1.0 if p['trip_time'] <= t < p['restore_time'] else 0.0}
        self.count += 1
        shift = self.count % 3                    # a different order at every output
        for name in TOPICS[shift:] + TOPICS[:shift]:
            self.pubs[name].publish(Float64(data=values[name]))
            time.sleep(p['delay'])


def main(args=None):
    spin(DemandScript, args)


if __name__ == '__main__':
    sys.exit(main())
