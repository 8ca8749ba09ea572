"""
sim_node's brake-system states over real rclpy: brake_ep/state, distributed_power/state.

The EP / ECP command received and each cylinder's valve (filling, lapped, venting), the
train line (ECP: its loss is a penalty application), the distributed-power radio link
(lost after 2 s without a message), on their topics and in ``/diagnostics``.
"""
from __future__ import annotations

import numpy as np

from sim_node_helpers import diag_values, joint_arrays

BRAKE_SYSTEM = 'train_dynamics: brake system'
P_MAX = 380000.0      # the uniform train's max_cylinder_pressure [Pa]


def _float64_publisher(harness):
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Float64

    return harness.probe.create_publisher(
        Float64, 'brake_ep/command', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))


def test_ep_command_received_and_valves_on_the_state_topic(harness):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    states = harness.collect(JointState, 'brake_ep/state')
    node = harness.start(num_coaches=4, brake_model='pneumatic', brake_system='ep',
                         initial_speed=20.0, real_time_factor=2.0)
    pub = _float64_publisher(harness)
    assert harness.wait_for_subscriber(pub)
    assert harness.wait(lambda: len(states) > 5, 10.0)
    assert list(states[-1].name) == [f'coach_{i}' for i in range(1, 5)]
    _, pos, vel, eff = joint_arrays(states)
    assert np.all(pos == 0.0) and np.all(eff == 1.0)      # nothing commanded, line healthy
    before = len(states)
    pub.publish(Float64(data=0.5))
    # received after the valve delay: every vehicle follows 0.5, the EP valves fill
    assert harness.wait(lambda: len(states) > before and np.all(
        np.asarray(states[-1].position) == 0.5), 10.0)
    # the EP valves fill, then lap (hold) at the commanded 0.5 p_max

    def filled_then_lapped():
        vel = np.array([list(m.velocity) for m in states[before:]])
        seen = np.nonzero(np.all(vel == 1.0, axis=1))[0] if len(vel) else []
        return len(seen) > 0 and np.all(vel[-1] == 0.0) and len(vel) - 1 > seen[0]
    assert harness.wait(filled_then_lapped, 20.0)
    assert np.all(np.abs(node.simulator.cylinder_pressure - 0.5 * P_MAX) < 0.05e5)
    _, pos, vel, eff = joint_arrays(states[before:])
    filled = np.any(vel == 1.0, axis=0)
    assert np.all(filled), 'every EP valve was seen filling'
    assert np.all(eff == 1.0) and np.all(pos[-1] == 0.5)


def test_ecp_line_loss_is_published_recorded_and_diagnosed(harness, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64

    from train_dynamics.recording.bags import read_topics

    states = harness.collect(JointState, 'brake_ep/state')
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    bag = tmp_path / 'bag'
    node = harness.start(num_coaches=4, brake_model='pneumatic', brake_system='ecp',
                         initial_speed=20.0, real_time_factor=2.0, input_timeout=1.5,
                         record_bag=str(bag))
    pub = _float64_publisher(harness)
    assert harness.wait_for_subscriber(pub)

    send = harness.every(0.02, lambda: pub.publish(Float64(data=0.3)))

    def held():        # the head-end unit keeps sending 0.3 at 50 Hz: the line stays healthy
        send()
        return bool(states) and np.all(np.asarray(states[-1].position) == 0.3) and np.all(
            np.abs(node.simulator.cylinder_pressure - 0.3 * P_MAX) < 0.1e5)
    assert harness.wait(held, 20.0)

    def diagnosed():   # still sending: the line stays healthy until /diagnostics reports
        send()
        return (diag_values(diags, BRAKE_SYSTEM) or {}).get('command_vehicles') == '0.3'
    assert harness.wait(diagnosed, 5.0)
    ok = diag_values(diags, BRAKE_SYSTEM)
    assert ok['train_line'] == 'ok' and ok['_level'] == 0 and ok['brake_system'] == 'ecp'
    # silence for input_timeout: the train line is lost, the cars apply in full (penalty)
    assert harness.wait(lambda: np.all(np.asarray(states[-1].effort) == 0.0), 10.0)
    lost_at = len(states)
    assert np.all(np.asarray(states[-1].position) == 0.0)
    assert harness.wait(lambda: np.all(node.simulator.cylinder_pressure > 0.95 * P_MAX), 20.0)
    _, _, vel, _ = joint_arrays(states[lost_at - 1:])
    assert np.all(np.any(vel == 1.0, axis=0)), 'the penalty filled every cylinder'
    assert harness.wait(lambda: (diag_values(diags, BRAKE_SYSTEM) or {}).get(
        'train_line') == 'lost', 5.0)
    lost = diag_values(diags, BRAKE_SYSTEM)
    assert lost['_level'] == 1 and 'penalty' in lost['_message']
    # the recorder has the published states: one per output, the line lost at the end
    harness.stop(node)
    recorded = [m for _, _, m in read_topics(str(bag), ['brake_ep/state'])]
    cylinders = [m for _, _, m in read_topics(str(bag), ['brake_cylinders'])]
    assert len(recorded) == len(cylinders) > 0
    line = np.array([m.effort[0] for m in recorded])
    assert line[0] == 1.0 and line[-1] == 0.0
    assert 0.3 in {m.position[0] for m in recorded}


DP_CONSIST = """
vehicles:
  - {type: heavy_freight_locomotive}
  - {type: freight_wagon_loaded, count: 4}
  - {type: heavy_freight_locomotive, remote: true}
"""


def test_radio_loss_is_published_and_diagnosed(harness, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState

    (tmp_path / 'dp.yaml').write_text(DP_CONSIST)
    radio = harness.collect(JointState, 'distributed_power/state')
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    harness.start(consist_file=str(tmp_path / 'dp.yaml'), brake_model='pneumatic',
                  initial_speed=10.0, real_time_factor=2.0, radio_loss=1.0)
    # every message lost: up at the start, lost once 2 s passed without one (at a 0.5 s tick)
    assert harness.wait(lambda: len(radio) > 3, 10.0)
    assert list(radio[0].name) == ['coach_6']
    assert radio[0].position[0] == 1.0
    assert harness.wait(lambda: radio[-1].position[0] == 0.0, 20.0)
    t, pos, age, command = joint_arrays(radio)
    k = int(np.argmax(pos[:, 0] == 0.0))
    assert 2.0 < t[k] <= 3.0 + 1e-9          # the first radio period after the 2 s timeout
    assert np.allclose(age[:, 0], t, atol=1e-9)     # no message ever received: age = t
    assert np.all(command[:, 0] == 5.0e5)          # the remote regulates to the nominal pipe
    assert harness.wait(lambda: (diag_values(diags, BRAKE_SYSTEM) or {}).get(
        'radio_link') == 'lost', 10.0)
    d = diag_values(diags, BRAKE_SYSTEM)
    assert d['_level'] == 1 and 'radio lost' in d['_message'] and d['remotes'] == 'coach_6'
    assert int(d['radio_lost']) == int(d['radio_sent']) > 0 and d['radio_received'] == '0'
