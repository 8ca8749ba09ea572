"""
A lock-step brake controller for the harness tests (test support, run as a process of its own).

Answers every ``coaches`` output with the head brake pipe released (5 bar gauge, stamped with
the output's stamp). At start it prints its ROS parameters (every one given to it: the node
declares the overrides) as one line ``parameters: {json}``. Environment:
``ECHO_PID_FILE``: write this process's id there once it is subscribed (a test then knows the
grandchild of a shell wrapper); ``ECHO_SILENT=1``: never answer (the node waits).
"""
import json
import os
import sys

from controller_main import spin
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState

ATM, RELEASE = 101325.0, 5.0e5      # [Pa]: atmosphere; released pipe, gauge


def _node():
    node = Node('echo_controller', automatically_declare_parameters_from_overrides=True)
    given = {name: p.value for name, p in node.get_parameters_by_prefix('').items()
             if name not in ('use_sim_time', 'start_type_description_service')}
    print('parameters: ' + json.dumps(given, sort_keys=True), flush=True)
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pub = node.create_publisher(FluidPressure, 'brake_pipe/pressure', qos)
    silent = os.environ.get('ECHO_SILENT') == '1'

    def answer(msg):
        if not silent:
            out = FluidPressure(fluid_pressure=RELEASE + ATM)
            out.header.stamp = msg.header.stamp
            pub.publish(out)

    node.create_subscription(JointState, 'coaches', answer, qos)
    pid_file = os.environ.get('ECHO_PID_FILE')
    if pid_file:
        with open(pid_file + '.tmp', 'w') as fh:
            fh.write(str(os.getpid()))
        os.replace(pid_file + '.tmp', pid_file)
    return node


def main():
    spin(_node, sys.argv)


if __name__ == '__main__':
    sys.exit(main())
