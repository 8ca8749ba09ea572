"""
The node's ED force commands under ``input_timeout``: a silent controller's ED falls to 0.

FLIRT, ``blending: external``: a controller commands 30 kN of motor car 1 (below its power
limit, 1300 kW / 22 m/s = 58 kN), then falls silent. Once the command is older than
``input_timeout`` the node sets the car's ED force to 0, whatever ``on_input_timeout`` says
(here ``hold``): the ED fades out at its build-up rate, the friction brakes (the
controller's cylinder commands, or the driver's) brake alone; ``/diagnostics`` names the
topic stale. A command again restores it.
"""
from __future__ import annotations

from pathlib import Path
import time

import pytest

from sim_node_helpers import diag_values

INPUT = 'train_dynamics: brake input'
CONSIST = Path(__file__).resolve().parents[2] / 'config' / 'consist_flirt_4.yaml'
TOPIC = 'coach_1/ed_brake/force'
FORCE = 30.0e3


def test_stale_ed_force_command_releases_the_ed_brake(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    from train_dynamics.physics.blending import ed_forces

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(consist_file=str(CONSIST), initial_speed=22.2, real_time_factor=1.0,
                         brake_input='cylinder_per_coach', blending='external',
                         input_timeout=0.5, on_input_timeout='hold')
    pub = harness.probe.create_publisher(
        Float64, TOPIC, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    assert harness.wait_for_subscriber(pub)

    def feed(seconds, command=None, until=None):
        """Send ``command`` every 20 ms (unless None) until ``until()`` or ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if command is not None:
                pub.publish(Float64(data=command))
            harness.spin_for(0.02)
            if until is not None and until():
                return True
        return until is None

    def ed():
        return float(ed_forces(node.simulator)[0])

    assert feed(20.0, FORCE, lambda: abs(ed() - FORCE) < 0.003 * FORCE)
    d = diag_values(diags, INPUT) or {}
    assert d.get('stale') != 'true'
    # silence: stale, the fail-safe 0 N, the ED built down to nothing
    assert feed(20.0, None, lambda: ed() == 0.0)
    assert feed(5.0, None, lambda: (diag_values(diags, INPUT) or {}).get('stale') == 'true')
    assert TOPIC in (diag_values(diags, INPUT) or {}).get('stale_inputs', '')
    # commanded again: the force again
    assert feed(20.0, FORCE, lambda: abs(ed() - FORCE) < 0.003 * FORCE)
    assert ed() == pytest.approx(FORCE, rel=3e-3)
    harness.stop(node)
