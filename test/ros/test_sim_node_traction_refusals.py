"""
sim_node: traction commands that no locomotive takes are counted and logged, as offline warns.

A command on ``coach_<i>/traction/command`` for a wagon or coach (no traction, no dynamic
brake) is ``rejected_not_locomotive``, one for a vehicle outside the train
``rejected_unknown_coach`` in ``/diagnostics`` (found by the graph scan like the brake
inputs of another mode), with a throttled warning naming the topic; a locomotive's command
is still applied. Real rclpy.
"""
from __future__ import annotations

from pathlib import Path
import time

from sim_node_helpers import diag_values

INPUT = 'train_dynamics: brake input'
CONSIST = Path(__file__).resolve().parents[2] / 'config' / 'consist_passenger_12.yaml'


def test_node_traction_for_non_locomotive_counted(harness, capfd):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(consist_file=str(CONSIST), initial_speed=20.0, real_time_factor=2.0)
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    loco = harness.probe.create_publisher(Float64, 'coach_1/traction/command', qos)
    wagon = harness.probe.create_publisher(Float64, 'coach_5/traction/command', qos)
    beyond = harness.probe.create_publisher(Float64, 'coach_40/traction/command', qos)
    assert harness.wait_for_subscriber(loco)
    end = time.monotonic() + 5.0                 # the graph scan runs every 2 s

    def counts():
        return diag_values(diags, INPUT) or {}

    while time.monotonic() < end and not (int(counts().get('rejected_not_locomotive', 0))
                                          and int(counts().get('rejected_unknown_coach', 0))):
        for pub in (wagon, beyond):
            pub.publish(Float64(data=0.5))
        harness.spin_for(0.05)
    loco.publish(Float64(data=0.5))
    assert harness.wait(lambda: int(counts().get('rejected_not_locomotive', 0)) > 0
                        and int(counts().get('rejected_unknown_coach', 0)) > 0, 5.0), counts()
    assert harness.wait(lambda: node.simulator.traction_force[0] > 1000.0, 10.0)
    assert all(f == 0.0 for f in node.simulator.traction_force[1:])
    assert harness.wait(lambda: int(counts().get('accepted', 0)) >= 1, 5.0), counts()
    d = counts()
    assert int(d['rejected_out_of_range']) == 0
    assert d['_level'] == 1 and 'rejected' in d['_message']
    err = capfd.readouterr().err.splitlines()
    wagon_warn = [ln for ln in err if '/coach_5/traction/command' in ln and 'not_locomotive'
                  in ln]
    beyond_warn = [ln for ln in err if '/coach_40/traction/command' in ln and 'unknown_coach'
                   in ln]
    assert 1 <= len(wagon_warn) <= 2 and 1 <= len(beyond_warn) <= 2, err   # throttled
