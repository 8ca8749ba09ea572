"""
A lock-step slide-protection controller per bogie (test support, run as a process of its own).

Answers every output once both its ``coaches`` and ``wheelsets`` (``bogie_wheelsets``: names
``coach_<i>/bogie_<j>``) are in: the head brake pipe vented (0 bar gauge, stamped with the
output's stamp: an emergency brake), and on ``coach_<i>/bogie_<j>/wsp/valve`` of every bogie
a valve state from the bogie's slip v_i - u_ij: vent above ``vent`` [m/s], hold above
``hold`` [m/s], else normal.
"""
import sys

from controller_main import spin
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from std_msgs.msg import Int8

ATM = 101325.0      # [Pa]


class BogieWsp(Node):
    """One valve state per bogie and one brake-pipe pressure per output."""

    def __init__(self):
        super().__init__('bogie_wsp_controller')
        self.vent = self.declare_parameter('vent', 1.0).value      # [m/s]
        self.hold = self.declare_parameter('hold', 0.4).value      # [m/s]
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.brake = self.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
        cars = self.declare_parameter('cars', 3).value
        # every topic at once: lock-step waits for a publisher on each before it starts
        self.valves = {f'coach_{i}/bogie_{j}/wsp/valve': self.create_publisher(
            Int8, f'coach_{i}/bogie_{j}/wsp/valve', qos)
            for i in range(1, cars + 1) for j in (1, 2)}
        self.latest = {}
        self.create_subscription(JointState, 'coaches', lambda m: self.take('v', m), qos)
        self.create_subscription(JointState, 'wheelsets', lambda m: self.take('u', m), qos)

    def take(self, kind, msg):
        stamp = (msg.header.stamp.sec, msg.header.stamp.nanosec)
        got = self.latest.setdefault(stamp, {})
        got[kind] = msg
        if len(got) < 2:
            return
        del self.latest[stamp]
        for old in [s for s in self.latest if s < stamp]:
            del self.latest[old]
        out = FluidPressure(fluid_pressure=ATM)
        out.header.stamp = msg.header.stamp
        self.brake.publish(out)
        v, wheels = got['v'].velocity, got['u']
        for k, name in enumerate(wheels.name):
            car = int(name.split('/')[0].split('_')[1]) - 1      # coach_<i>/bogie_<j>
            slip = v[car] - wheels.velocity[k]
            state = 2 if slip > self.vent else (1 if slip > self.hold else 0)
            self.valves[f'{name}/wsp/valve'].publish(Int8(data=state))


def main(args=None):
    spin(BogieWsp, args)


if __name__ == '__main__':
    sys.exit(main())
