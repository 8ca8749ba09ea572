"""
Stale traction commands in ``/diagnostics`` (the brake inputs' staleness rule), real rclpy.

A locomotive whose ``coach_<i>/traction/command`` goes silent for ``input_timeout`` is
reported like a silent brake input: ``stale``, ``stale_inputs``, ``input_age_s``, and with
``on_input_timeout: emergency`` ``emergency_applied`` (its command falls to 0), while the brake
input itself stays fresh.
"""
from __future__ import annotations

from pathlib import Path
import time

import pytest

from sim_node_helpers import diag_values, fluid

ATM = 101325.0
INPUT = 'train_dynamics: brake input'
CONSIST = Path(__file__).resolve().parents[2] / 'config' / 'consist_passenger_12.yaml'
TOPIC = 'coach_1/traction/command'


def test_stale_traction_command_in_diagnostics_emergency_then_fresh_then_hold(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(consist_file=str(CONSIST), initial_speed=20.0, real_time_factor=1.0,
                         input_timeout=0.5, on_input_timeout='emergency')
    head = harness.publisher('brake_pipe/pressure')
    traction = harness.probe.create_publisher(
        Float64, TOPIC, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    assert harness.wait_for_subscriber(head) and harness.wait_for_subscriber(traction)

    def feed(seconds, command=None, until=None):
        """Keep the brake pipe charged (fresh); send ``command`` too unless None."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            head.publish(fluid(500000.0 + ATM))
            if command is not None:
                traction.publish(Float64(data=command))
            harness.spin_for(0.02)
            if until is not None and until():
                return True
        return until is None

    def status():
        return diag_values(diags, INPUT) or {}

    # dynamic brake at half the available force: -0.5 min(150 kN, 6.4 MW / v), v ~ 20 m/s
    assert feed(15.0, -0.5, lambda: abs(node.simulator.traction_force[0] + 75e3) < 2e3)
    feed(1.2, -0.5)
    d = status()
    assert d['stale'] == 'false' and d['emergency_applied'] == 'false' and d['_level'] == 0
    assert float(d['input_age_s']) < 0.5
    # the commands stop, the brake input stays fresh: the locomotive alone goes stale
    assert feed(4.0, None, lambda: status().get('emergency_applied') == 'true')
    d = status()
    assert d['stale'] == 'true' and d['_level'] == 2 and 'emergency' in d['_message']
    assert d['stale_inputs'] == TOPIC                            # not the brake input
    assert float(d['input_age_s']) > 0.5
    # the fail-safe: command 0, the dynamic brake force builds down to nothing
    feed(3.0)
    assert abs(node.simulator.traction_force[0]) < 1.0
    # a command again: fresh, the fail-safe lifted
    assert feed(4.0, -0.5, lambda: status().get('stale') == 'false')
    d = status()
    assert d['emergency_applied'] == 'false' and d['stale_inputs'] == ''
    assert feed(10.0, -0.5, lambda: abs(node.simulator.traction_force[0] + 75e3) < 2e3)
    # hold: silence is reported (WARN), the last command stays applied
    assert node.set_parameters([Parameter('on_input_timeout', value='hold')])[0].successful
    assert feed(4.0, None, lambda: status().get('stale') == 'true')
    feed(0.5)
    d = status()
    assert d['emergency_applied'] == 'false' and d['_level'] == 1
    assert d['stale_inputs'] == TOPIC
    assert node.simulator.traction_force[0] == pytest.approx(-75e3, abs=2e3)
    # back to emergency while stale: the fail-safe applies at once
    assert node.set_parameters([Parameter('on_input_timeout', value='emergency')])[0].successful
    assert feed(4.0, None, lambda: status().get('emergency_applied') == 'true')
    harness.stop(node)
