"""
The node's per-bogie slide-protection inputs (``wsp: external``, ``bogie_wheelsets``).

``coach_<i>/bogie_<j>/wsp/valve`` reaches that bogie's valves only: vehicle 2's rear bogie
vented, its cylinder falls below a tenth of the cylinder input while the front bogie and
the other vehicles keep the input's pressure; ``bogie_cylinders`` publishes each bogie's
pressure and valve state, ``wheelsets`` each bogie's wheel. A state out of range is rejected.
"""
from __future__ import annotations

import numpy as np

from sim_node_helpers import fluid

ATM = 101325.0
P = 2.0e5


def test_a_bogie_valve_topic_vents_that_bogie_only(harness):
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Int8

    bogies = harness.collect(JointState, 'bogie_cylinders')
    wheels = harness.collect(JointState, 'wheelsets')
    node = harness.start(num_coaches=3, initial_speed=20.0, real_time_factor=1.0,
                         brake_input='cylinder_per_coach', wsp='external',
                         bogie_wheelsets=True)
    cyl = [harness.publisher(f'coach_{i}/brake_cylinder/pressure') for i in (1, 2, 3)]
    valve = harness.probe.create_publisher(Int8, 'coach_2/bogie_2/wsp/valve', 10)
    assert all(harness.wait_for_subscriber(p) for p in cyl)
    assert harness.wait_for_subscriber(valve)

    def feed(state):
        for p in cyl:
            p.publish(fluid(ATM + P))
        valve.publish(Int8(data=state))

    def sending(state, done):
        tick = harness.every(0.05, lambda: feed(state))
        return lambda: (tick(), done())[1]

    assert harness.wait(sending(0, lambda: bogies and abs(bogies[-1].position[3] - P) < 1.0),
                        15.0)
    assert harness.wait(sending(2, lambda: bogies[-1].position[3] < 0.1 * P), 15.0)
    last = bogies[-1]
    assert list(last.name) == [f'coach_{i}/bogie_{j}' for i in (1, 2, 3) for j in (1, 2)]
    np.testing.assert_allclose(np.delete(np.array(last.position), 3), P, rtol=1e-9)
    assert list(last.effort) == [0.0, 0.0, 0.0, 2.0, 0.0, 0.0]
    assert list(wheels[-1].name) == list(last.name)
    bad = harness.probe.create_publisher(Int8, 'coach_1/bogie_1/wsp/valve', 10)
    assert harness.wait_for_subscriber(bad)
    bad.publish(Int8(data=9))               # rejected: not 0, 1, 2
    harness.spin_for(0.5)
    assert node.simulator.wheelset_valves[0] == 0
    harness.stop(node)


def test_the_example_controller_protects_each_bogie(harness):
    """
    ``examples/wsp_controller.py`` on per-bogie wheelsets: it answers each bogie by name.

    Emergency from 25 km/h on 0.05 adhesion (a 0.1 g brake): the controller vents the
    bogies' cylinders on their own topics; no bogie's wheel stands for 0.5 s while its car
    moves (unprotected every wheel would lock for most of the stop).
    """
    import importlib.util
    from pathlib import Path

    from sensor_msgs.msg import JointState

    spec = importlib.util.spec_from_file_location(
        'wsp_controller', Path(__file__).resolve().parents[2] / 'examples' / 'wsp_controller.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    wheels = harness.collect(JointState, 'wheelsets')
    motion = harness.collect(JointState, 'vehicle_motion')
    bogies = harness.collect(JointState, 'bogie_cylinders')
    node = harness.start(num_coaches=3, initial_speed=25 / 3.6, real_time_factor=1.0,
                         wsp='external', bogie_wheelsets=True,
                         track_adhesion_positions=[-1.0e6], track_adhesion=[0.05])
    harness.add(module.WspController())
    brake = harness.publisher('brake_pipe/pressure')
    assert harness.wait_for_subscriber(brake)
    brake.publish(fluid(ATM))                   # emergency: the pipe vented
    assert harness.wait(lambda: np.all(node.simulator.v == 0.0), 120.0)
    assert any(2.0 in m.effort for m in bogies)            # some bogie was vented
    speed = {(m.header.stamp.sec, m.header.stamp.nanosec): np.array(m.velocity)
             for m in motion}
    run = np.zeros(6)
    longest = np.zeros(6)
    for m in wheels:
        v = speed.get((m.header.stamp.sec, m.header.stamp.nanosec))
        if v is None:
            continue
        run = np.where((np.array(m.velocity) == 0.0) & (np.repeat(v, 2) > 0.0), run + 0.01, 0.0)
        longest = np.maximum(longest, run)
    assert len(speed) > 500
    assert np.all(longest <= 0.5), longest
    harness.stop(node)
