"""
sim_node's slide protection over DDS, real rclpy: ``wheelsets`` out, ``coach_<i>/wsp/valve`` in.

The example controller (``examples/wsp_controller.py``, about 50 lines) drives every
vehicle's valves from ``wheelsets`` and ``vehicle_motion``; on a rail of 0.05 adhesion an
emergency from 40 km/h then never leaves a wheel at rest for more than 0.5 s while its
vehicle moves (without slide protection the wheels lock for most of the stop:
test_wheel_slide_train.py).
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from sim_node_helpers import diag_values, fluid, joint_arrays

EXAMPLE = Path(__file__).resolve().parents[2] / 'examples' / 'wsp_controller.py'
INPUT = 'train_dynamics: brake input'
METRICS = 'train_dynamics: run metrics'
ATM = 101325.0
#: [s wall] bound of a wait on an event: it returns at the event; a loaded machine is slow
WAIT = 60.0


def _controller():
    spec = importlib.util.spec_from_file_location('wsp_controller', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.WspController()


def test_external_wsp_node_keeps_the_wheels_turning(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState

    wheels = harness.collect(JointState, 'wheelsets')
    motion = harness.collect(JointState, 'vehicle_motion')
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    # at real time: the controller has 10 ms of wall time per output to answer, far more
    # than it needs on a loaded machine (at real_time_factor 5 it failed once with two CPU
    # hogs on both cores: 0.94 s of locked wheels). Lock-step would remove the dependence,
    # but the example creates its valve publishers at its first wheelsets message, and
    # lock-step waits at t = 0 for a publisher on every declared input.
    node = harness.start(num_coaches=3, initial_speed=40 / 3.6, real_time_factor=1.0,
                         wsp='external', track_adhesion_positions=[-1.0e6],
                         track_adhesion=[0.05])
    controller = _controller()
    harness.add(controller)
    brake = harness.publisher('brake_pipe/pressure')
    assert harness.wait_for_subscriber(brake)
    brake.publish(fluid(ATM))                   # emergency: the pipe vented
    assert harness.wait(lambda: len(wheels) > 10, WAIT)
    assert harness.wait(lambda: np.all(node.simulator.v == 0.0), 2 * WAIT)
    t_stop = node.simulator.t
    t, adhesion, u, creep = joint_arrays(wheels)
    assert list(wheels[-1].name) == ['coach_1', 'coach_2', 'coach_3']
    assert wheels[-1].header.frame_id == 'track'
    sim = node.simulator
    assert np.all(sim.sliding_time < 0.3 * t_stop)   # unprotected: nearly all of the stop
    assert np.max(creep) > 0.8 * 0.05 * 0.5 * 45000 * 9.81     # the rail was used
    assert np.all(adhesion <= 0.05 * (1.0 + 1e-12))
    # the longest time a wheel stood still while its vehicle moved (samples at 100 Hz)
    speed = {round(ts, 6): vel for ts, vel in zip(*joint_arrays(motion)[::2])}
    run = np.zeros(3)
    longest = np.zeros(3)
    last = t[0]
    for ts, uk in zip(t, u):
        vk = speed.get(round(ts, 6))
        if vk is None:
            continue
        run = np.where((uk == 0.0) & (vk > 0.0), run + (ts - last), 0.0)
        longest = np.maximum(longest, run)
        last = ts
    assert len(speed) > 1000
    assert np.all(longest <= 0.5), longest
    # the run metrics on /diagnostics carry the longest sliding time and distance
    slid = int(np.argmax(sim.sliding_time)) + 1
    assert harness.wait(lambda: (diag_values(diags, METRICS) or {}).get(
        'max_sliding_time') == f'{np.max(sim.sliding_time):.6g}', WAIT)
    values = diag_values(diags, METRICS)
    assert values['max_sliding_time_vehicle'] == str(slid)
    assert float(values['max_sliding_distance']) == pytest.approx(
        np.max(sim.sliding_distance), rel=1e-5)


def test_lockstep_waits_for_every_vehicles_valve_state(harness, tmp_path):
    """
    ``lockstep_inputs: [wsp]``: one valve state per vehicle and output releases each period.

    The probe answers every output (``coaches``) with a state for each vehicle (vehicle 2
    holding); the bag holds one state per vehicle and output, recorded at that output's
    time, and the run reaches its end with vehicle 2's valve on hold.
    """
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Int8
    from train_dynamics.recording.bags import read_topics

    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pubs = [harness.probe.create_publisher(Int8, f'coach_{i}/wsp/valve', qos)
            for i in (1, 2, 3)]

    def answer(msg):
        for i, pub in enumerate(pubs):
            pub.publish(Int8(data=1 if i == 1 else 0))

    harness.probe.create_subscription(JointState, 'coaches', answer, qos)
    bag = tmp_path / 'bag'
    node = harness.start(num_coaches=3, initial_speed=20.0, wsp='external',
                         sync_mode='lockstep', lockstep_inputs=['wsp'], real_time_factor=0.0,
                         duration=0.3, record_bag=str(bag))
    assert harness.wait(lambda: node.finished, WAIT)
    assert list(node.simulator.wsp_valve) == [0, 1, 0]
    harness.stop(node)
    outputs, states = [], {1: [], 2: [], 3: []}
    for topic, t_ns, _ in read_topics(bag, ['wheelsets', 'coach_1/wsp/valve',
                                            'coach_2/wsp/valve', 'coach_3/wsp/valve']):
        if topic == 'wheelsets':
            outputs.append(t_ns)
        else:
            states[int(topic.split('/')[0][len('coach_'):])].append(t_ns)
    assert outputs == [k * 10_000_000 for k in range(31)]
    assert all(times == outputs for times in states.values())


def test_a_valve_state_out_of_range_is_rejected_and_counted(harness):
    """A valve state other than 0, 1, 2 changes nothing and is counted on /diagnostics."""
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Int8

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(num_coaches=3, initial_speed=10.0, real_time_factor=1.0,
                         wsp='external')
    bad = harness.probe.create_publisher(
        Int8, 'coach_2/wsp/valve', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    assert harness.wait_for_subscriber(bad)
    bad.publish(Int8(data=7))
    assert harness.wait(lambda: (diag_values(diags, INPUT) or {}).get(
        'rejected_out_of_range') == '1', WAIT)
    assert list(node.simulator.wsp_valve) == [0, 0, 0]
