"""
sim_node's slide protection over DDS, real rclpy: ``wheelsets`` out, ``coach_<i>/wsp/valve`` in.

The example controller (``examples/wsp_controller.py``, about 50 lines) drives every
vehicle's valves from ``wheelsets`` and ``vehicle_motion``; on a rail of 0.05 adhesion an
emergency from 60 km/h then never leaves a wheel at rest for more than 0.5 s while its
vehicle moves (without slide protection the wheels lock for most of the stop:
test_wheel_slide_train.py).
"""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from sim_node_helpers import diag_values, fluid, joint_arrays

EXAMPLE = Path(__file__).resolve().parents[1] / 'examples' / 'wsp_controller.py'
INPUT = 'train_dynamics: brake input'
ATM = 101325.0


def _controller():
    spec = importlib.util.spec_from_file_location('wsp_controller', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.WspController()


def test_external_wsp_node_keeps_the_wheels_turning(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Int8

    wheels = harness.collect(JointState, 'wheelsets')
    motion = harness.collect(JointState, 'vehicle_motion')
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(num_coaches=3, initial_speed=60 / 3.6, real_time_factor=4.0,
                         wsp='external', track_adhesion_positions=[-1.0e6],
                         track_adhesion=[0.05])
    controller = _controller()
    harness.add(controller)
    brake = harness.publisher('brake_pipe/pressure')
    assert harness.wait_for_subscriber(brake)
    brake.publish(fluid(ATM))                   # emergency: the pipe vented
    bad = harness.probe.create_publisher(
        Int8, 'coach_2/wsp/valve', QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    bad.publish(Int8(data=7))                   # rejected, counted
    assert harness.wait(lambda: len(wheels) > 10, 10.0)
    assert harness.wait(lambda: np.all(node.simulator.v == 0.0), 60.0)
    t, adhesion, u, creep = joint_arrays(wheels)
    assert list(wheels[-1].name) == ['coach_1', 'coach_2', 'coach_3']
    assert wheels[-1].header.frame_id == 'track'
    sim = node.simulator
    assert np.all(sim.sliding_time < 25.0)       # unprotected: all of the ~95 s stop
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
    assert harness.wait(lambda: (diag_values(diags, INPUT) or {}).get(
        'rejected_out_of_range') == '1', 5.0)
