"""sim_node's traction input and vehicle_forces output, real rclpy."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sim_node_helpers import diag_values

INPUT = 'train_dynamics: brake input'
CONSIST = Path(__file__).resolve().parents[2] / 'config' / 'consist_passenger_12.yaml'


def test_traction_commands_are_applied_validated_and_forces_published(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    forces = harness.collect(JointState, 'vehicle_forces')
    node = harness.start(consist_file=str(CONSIST), initial_speed=20.0, real_time_factor=2.0)
    pub = harness.probe.create_publisher(
        Float64, 'coach_1/traction/command',
        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    assert harness.wait_for_subscriber(pub)
    for value in (float('nan'), 1.5, -0.5):
        pub.publish(Float64(data=value))
        harness.spin_for(0.05)
    assert harness.wait(lambda: node.simulator.traction_force[0] < -1000.0, 10.0)
    f = node.simulator.traction_force
    assert np.all(f[1:] == 0.0)
    # dynamic brake: -0.5 of min(150 kN, 6.4 MW / v) at v ~ 20 m/s, after the build-up
    assert harness.wait(lambda: abs(node.simulator.traction_force[0] + 75e3) < 1e3, 10.0)
    assert harness.wait(lambda: forces and forces[-1].position[0] < -70e3, 5.0)
    assert len(forces[-1].name) == 13 and forces[-1].velocity[1] < 0.0  # resistance
    assert harness.wait(lambda: (diag_values(diags, INPUT) or {}).get(
        'rejected_out_of_range') == '1', 5.0)
    d = diag_values(diags, INPUT)
    assert int(d['rejected_non_finite']) >= 1
