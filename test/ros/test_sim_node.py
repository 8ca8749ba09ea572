"""
sim_node with real rclpy, in-process, DDS on loopback.

Parameters (contract names, defaults, descriptors, rejection of invalid values), the node's
output against the physics core run offline on the same inputs, brake_valve -> sim_node over
topics, live model switches, /clock and the reset service.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from sim_node_helpers import diag_values, first_time, fluid, joint_arrays, stamp_s

ATM = 101325.0
CONTRACT_ONLY_NAMED = ('scale_factor', 'adhesion_coefficient', 'integration_step')


def _invalid_values(spec):
    """Values of every wrong kind for one parameter spec."""
    from train_dynamics.physics.config import BOOL, DOUBLE, DOUBLE_ARRAY, INTEGER, STRING

    nan, inf = float('nan'), float('inf')
    k = spec.kind
    bad: list = []
    if k == DOUBLE:
        bad += ['text', True, [1.0], nan, inf, -inf]
        if spec.low is not None:
            bad.append(float(spec.low) if spec.low_exclusive
                       else float(spec.low) - max(1.0, abs(spec.low)))
        if spec.high is not None:
            bad.append(float(spec.high) * 2 + 1.0)
    elif k == INTEGER:
        bad += [2.5, 'text', True, [3]]
        if spec.low is not None:
            bad.append(int(spec.low) - 1)
        if spec.high is not None:
            bad.append(int(spec.high) + 1)
    elif k == STRING:
        bad += [3, 1.5, True, ['a']]
        if spec.choices:
            bad += ['bogus', spec.choices[0].upper() + '_']
    elif k == BOOL:
        bad += ['true', 1, 0.0]
    elif k == DOUBLE_ARRAY:
        bad += ['text', 1.0, [nan, 1.0], [1.0, inf], ['a', 'b'], [True, False]]
        if spec.low is not None:
            m = float(spec.low)
            bad.append([m if spec.low_exclusive else m - max(1.0, abs(m)), 1.0])
        if spec.high is not None:
            bad.append([float(spec.high) * 2 + 1.0])
    return bad


def test_parameters_declared_with_contract_defaults_and_descriptors(harness, contract_defaults):
    from rcl_interfaces.msg import ParameterType

    from train_dynamics.physics.config import DOUBLE, DOUBLE_ARRAY, INTEGER, PARAMETERS

    node = harness.start()
    assert node.get_name() == 'train_dynamics'
    for name, value in contract_defaults.items():
        got = node.get_parameter(name).value
        assert (list(got) if isinstance(value, list) else got) == value, name
    for name in CONTRACT_ONLY_NAMED:
        assert node.has_parameter(name)
    assert node.get_parameter('scale_factor').value > 0
    types = {DOUBLE: ParameterType.PARAMETER_DOUBLE, INTEGER: ParameterType.PARAMETER_INTEGER,
             DOUBLE_ARRAY: ParameterType.PARAMETER_DOUBLE_ARRAY}
    for name, spec in PARAMETERS.items():
        d = node.describe_parameter(name)
        assert d.description and not d.read_only, name
        if spec.kind in types:
            assert d.type == types[spec.kind], name
        if spec.kind == DOUBLE and spec.low is not None and spec.high is not None:
            (r,) = d.floating_point_range
            assert (r.from_value, r.to_value) == (spec.low, spec.high), name
        if spec.kind == INTEGER and spec.low is not None:
            (r,) = d.integer_range
            assert (r.from_value, r.to_value) == (spec.low, spec.high), name
        if spec.choices:
            assert all(c in d.additional_constraints for c in spec.choices), name
    assert node.has_parameter('duration')
    # The reset service exists and the node publishes its outputs.
    couplers = harness.collect(__import__('sensor_msgs.msg', fromlist=['JointState']).JointState,
                               'couplers')
    assert harness.wait(lambda: len(couplers) >= 3, 10.0)
    assert list(couplers[-1].name) == ['coupler_1', 'coupler_2']


def test_every_kind_of_invalid_parameter_is_rejected_and_changes_nothing(harness):
    from rclpy.parameter import Parameter

    from train_dynamics.physics.config import PARAMETERS

    node = harness.start(real_time_factor=5.0)
    assert harness.wait(lambda: node.sim_time > 0.2, 10.0)
    before = {n: node.get_parameter(n).value for n in PARAMETERS}
    model_before = (node.simulator.model_type, node.simulator.u)
    cases = [(name, v) for name, spec in PARAMETERS.items() for v in _invalid_values(spec)]
    # Whole-configuration checks (each value valid on its own).
    cases += [('masses', [45000.0]), ('buffer_friction', 2.8e6), ('draw_gear_friction', 6.0e6),
              ('full_service_pressure', 490000.0), ('cylinder_fill_time', [0.0, 2.0]),
              ('record_bag', str(__import__('pathlib').Path(__file__)))]   # existing path
    assert len(cases) > 150
    t0 = node.sim_time
    for name, value in cases:
        (res,) = node.set_parameters([Parameter(name, value=value)])
        assert not res.successful, (name, value)
        assert res.reason, (name, value)
        got = node.get_parameter(name).value
        assert (list(got) if isinstance(before[name], list) else got) == \
            (list(before[name]) if isinstance(before[name], list) else before[name]), name
    # Atomic batches: one bad value rejects the whole batch.
    res = node.set_parameters_atomically([Parameter('cylinder_fill_time', value=[0.0, 1.0]),
                                          Parameter('cylinder_fill_fraction', value=[0.5, 1.0])])
    assert not res.successful and 'cylinder_fill_fraction' in res.reason
    res = node.set_parameters_atomically([Parameter('model_type', value='sign'),
                                          Parameter('scale_factor', value=-1.0)])
    assert not res.successful
    # Nothing changed: parameters, model, nothing pending, the run continued (no restart).
    for name in PARAMETERS:
        got = node.get_parameter(name).value
        assert (list(got) if isinstance(before[name], list) else got) == \
            (list(before[name]) if isinstance(before[name], list) else before[name]), name
    assert (node.simulator.model_type, node.simulator.u) == model_before
    assert node.pending_changes() == ''
    assert node.sim_time > t0 and node.fault is None

    # An empty array that breaks a pair: valid pair first, then emptying one side.
    res = node.set_parameters_atomically([Parameter('cylinder_fill_time', value=[0.0, 2.0]),
                                          Parameter('cylinder_fill_fraction', value=[0.0, 1.0])])
    assert res.successful                # accepted as pending (rclpy drops a success reason)
    assert 'cylinder_fill_time: [] -> [0, 2]' in node.pending_changes()
    (res,) = node.set_parameters([Parameter('cylinder_fill_fraction', value=[])])
    assert not res.successful and 'same length' in res.reason

    # Over the parameter service, as `ros2 param set` does.
    results = harness.set_remote('train_dynamics', {'scale_factor': 0.0})
    assert not results[0].successful and '> 0' in results[0].reason
    results = harness.set_remote('train_dynamics', {'model_type': 'Tanh'})
    assert not results[0].successful and 'tanh' in results[0].reason
    results = harness.set_remote('train_dynamics', {'coach_mass': -45000.0})
    assert not results[0].successful
    results = harness.set_remote('train_dynamics', {'scale_factor': 'fast'})
    assert not results[0].successful
    assert node.simulator.u == model_before[1]
    # Valid live values are taken (an integer for a double is converted).
    results = harness.set_remote('train_dynamics', {'model_type': 'sign', 'scale_factor': 200})
    assert all(r.successful for r in results)
    assert node.simulator.model_type == 'sign' and node.simulator.u == 200.0
    assert node.get_parameter('scale_factor').value == 200.0


def _offline_replay(cfg, inputs, outputs):
    """Run the core on the recorded inputs; return (y, ydot, F) at the output times."""
    from train_dynamics.physics.train import TrainSimulator

    sim = TrainSimulator(cfg)
    events = [(t, 0, x) for t, x in inputs] + [(t, 1, None) for t in outputs]
    events.sort(key=lambda e: (e[0], e[1]))
    res = {}
    for t_ns, kind, payload in events:
        sim.advance_to(t_ns * 1e-9)
        if kind == 0:
            index, gauge = payload
            sim.set_cylinder_pressure(gauge, index)
        else:
            res[t_ns] = (sim.y, sim.ydot, sim.coupler_force)
    assert sim.fault is None
    return res


def test_cylinder_inputs_over_topics_match_the_core_run_offline(harness, tmp_path):
    """
    Match the node's couplers with TrainSimulator replayed on the recorded inputs.

    cylinder_per_coach from a test publisher: the node's couplers == TrainSimulator replayed
    on the inputs as recorded (bag time = the step at which each one took effect).
    """
    from sensor_msgs.msg import JointState

    from train_dynamics.recording.bags import read_topics
    from train_dynamics.physics.config import SimConfig

    bag = tmp_path / 'run'
    params = {'brake_input': 'cylinder_per_coach', 'real_time_factor': 2.0, 'duration': 4.0,
              'record_bag': str(bag)}
    node = harness.start(**params)
    couplers = harness.collect(JointState, 'couplers')
    # Coach 2 through a best-effort publisher: both kinds connect.
    pubs = [harness.publisher(f'coach_{i}/brake_cylinder/pressure', reliable=(i != 2))
            for i in (1, 2, 3)]
    for p in pubs:
        assert harness.wait_for_subscriber(p)
    levels = [(0.0, (0.0, 0.0, 0.0)), (0.25, (380e3, 0.0, 0.0)), (0.5, (380e3, 200e3, 0.0)),
              (0.75, (380e3, 200e3, 380e3)), (1.1, (0.0, 200e3, 380e3)),
              (1.4, (0.0, 0.0, 100e3)), (1.7, (250e3, 0.0, 0.0))]
    import time
    t_start = time.monotonic()
    while not node.finished and time.monotonic() - t_start < 20.0:
        age = time.monotonic() - t_start
        level = [lv for t, lv in levels if t <= age][-1]
        for p, gauge in zip(pubs, level):
            p.publish(fluid(gauge + ATM))
        harness.spin_for(0.02)
    assert node.finished
    harness.spin_for(0.2)
    harness.stop(node)       # finishes the bag

    inputs, outputs = [], {}
    for topic, t_ns, msg in read_topics(bag):
        if topic.endswith('brake_cylinder/pressure'):
            inputs.append((t_ns, (int(topic.split('/')[0][6:]) - 1, msg.fluid_pressure - ATM)))
        elif topic == 'couplers':
            outputs[t_ns] = msg
    assert len(outputs) == 401                      # t = 0 .. 4 s at 100 Hz, exactly
    assert sorted(outputs) == [round(k * 0.01 * 1e9) for k in range(401)]
    assert len(inputs) > 100
    cfg = SimConfig.from_dict({k: v for k, v in params.items() if k != 'duration'})
    replay = _offline_replay(cfg, inputs, sorted(outputs))
    f_max = 0.0
    for t_ns, msg in outputs.items():
        y, ydot, f = replay[t_ns]
        np.testing.assert_allclose(msg.position, y, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(msg.velocity, ydot, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(msg.effort, f, rtol=1e-12, atol=1e-6)
        f_max = max(f_max, float(np.max(np.abs(f))))
    assert f_max > 5e3          # the inputs did act on the couplers
    # What subscribers received is what was recorded.
    received = {round(stamp_s(m) * 1e9): m for m in couplers}
    assert len(received) > 300
    for t_ns, m in received.items():
        np.testing.assert_array_equal(m.effort, outputs[t_ns].effort)


def test_brake_valve_emergency_over_topics(harness):
    """
    Brake the train through brake_valve -> sim_node over topics.

    brake_valve (emergency at t = 1 s on /clock) -> sim_node: brakes apply coach after coach
    (25 m / 250 m/s = 0.1 s apart) and the couplers stay in compression while braking.
    """
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from train_dynamics.ros.brake_valve_node import BrakeValveNode

    valve = BrakeValveNode(parameter_overrides=[
        Parameter('use_sim_time', value=True),
        Parameter('schedule', value=['0.0:release', '1.0:emergency'])])
    harness.add(valve)
    coaches = harness.collect(JointState, 'coaches')
    couplers = harness.collect(JointState, 'couplers')
    # at real time (not faster): the valve answers the node's /clock through DDS, and under
    # load its answer's lag in simulation time is the wall lag times the real-time factor
    node = harness.start(publish_clock=True, real_time_factor=1.0, duration=5.0)
    assert harness.wait(lambda: node.finished, 60.0)
    harness.spin_for(0.1)
    t, x, v, fb = joint_arrays(coaches)
    onset = [first_time(t, fb[:, i] > 1.0) for i in range(3)]
    assert 1.0 < onset[0] < 1.6, onset
    assert onset[1] - onset[0] == pytest.approx(0.1, abs=0.025), onset
    assert onset[2] - onset[1] == pytest.approx(0.1, abs=0.025), onset
    tc, y, ydot, force = joint_arrays(couplers)
    assert force.min() < -2e3                        # compression (F < 0), kN
    braking = tc > onset[2] + 0.1
    assert np.all(force[braking] < 0.0)              # the rear pushes on the braked front
    assert np.all(force[tc < onset[0]] == pytest.approx(0.0, abs=1e-6))
    assert v[-1].max() < v[0].min() - 2.0            # the train is braking


def test_live_model_switches_take_effect_with_continuous_state(harness):
    """
    Switch scale_factor and model_type while running.

    The published coupler forces follow the new law from the switch on, and x, v, y do not
    jump.
    """
    from sensor_msgs.msg import JointState

    from train_dynamics.physics.config import PARAMETERS
    from train_dynamics.physics.kernel import couplers as C

    node = harness.start(brake_input='cylinder_per_coach', real_time_factor=2.0, duration=4.0)
    couplers = harness.collect(JointState, 'couplers')
    coaches = harness.collect(JointState, 'coaches')
    pubs = [harness.publisher(f'coach_{i}/brake_cylinder/pressure') for i in (1, 2, 3)]
    for p in pubs:
        assert harness.wait_for_subscriber(p)
    laws = [('tanh', 1000.0), ('tanh', 5.0), ('sign', 5.0)]
    switches = [(1.0, {'scale_factor': 5.0}), (2.0, {'model_type': 'sign'}),
                (3.0, {'model_type': 'tanh', 'scale_factor': 1000.0})]
    k = 0
    from rclpy.parameter import Parameter
    while not node.finished:
        t = node.sim_time
        # Coach 2 pulses so that the couplers keep moving.
        p2 = 380e3 if int(t / 0.4) % 2 else 0.0
        for p, g in zip(pubs, (380e3, p2, 150e3)):
            p.publish(fluid(g + ATM))
        if k < len(switches) and t >= switches[k][0]:
            params = [Parameter(n, value=v) for n, v in switches[k][1].items()]
            assert node.set_parameters_atomically(params).successful
            k += 1
        harness.spin_for(0.01)
    harness.spin_for(0.1)
    assert k == 3
    spec = {n: PARAMETERS[n].default for n in ('buffer_stiffness', 'buffer_friction',
                                               'draw_gear_stiffness', 'draw_gear_friction')}
    ones = np.ones(2)
    phases = []
    for m in couplers:
        y, ydot, f = (np.array(a) for a in (m.position, m.velocity, m.effort))
        match = []
        for j, (model, u) in enumerate(laws):
            ref = C.coupler_force(y, ydot, spec['buffer_stiffness'] * ones,
                                  spec['buffer_friction'] * ones,
                                  spec['draw_gear_stiffness'] * ones,
                                  spec['draw_gear_friction'] * ones, C.MODEL_CODES[model], u)
            if np.allclose(f, ref, rtol=1e-9, atol=1e-6):
                match.append(j)
        assert match, f'force at t = {stamp_s(m):.3f} s matches no law'
        phases.append(match)
    # Unambiguous messages go through the laws in order (A, B, C, A), each seen many times.
    order = [m[0] for m in phases if len(m) == 1]
    seen = [j for i, j in enumerate(order) if i == 0 or order[i - 1] != j]
    assert seen == [0, 1, 2, 0], seen
    for j in (1, 2):
        assert order.count(j) > 20, (j, order.count(j))
    # Continuous state: stamps regular, no jumps in x, v, y across the switches.
    t, x, v, fb = joint_arrays(coaches)
    assert np.all(np.diff(t) > 0)
    dt = np.diff(t)[:, None]
    assert np.all(np.abs(np.diff(v, axis=0)) <= 10.0 * dt)            # |a| < 10 m/s^2
    assert np.all(np.abs(np.diff(x, axis=0) - v[:-1] * dt) <= 0.05 * dt + 1e-9)
    tc, y, ydot, f = joint_arrays(couplers)
    assert np.all(np.abs(np.diff(y, axis=0)) <= 1.0 * np.diff(tc)[:, None] + 1e-9)


def test_clock_monotonic_and_reset_restarts_with_pending_changes(harness):
    from rclpy.parameter import Parameter
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    from diagnostic_msgs.msg import DiagnosticArray

    clocks = harness.collect(Clock, '/clock')
    couplers = harness.collect(JointState, 'couplers')
    coaches = harness.collect(JointState, 'coaches')
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(publish_clock=True, real_time_factor=3.0)
    assert harness.wait(lambda: node.sim_time > 1.5, 10.0)
    # A structural change is accepted as pending: nothing changes until reset.
    (res,) = node.set_parameters([Parameter('num_coaches', value=4)])
    assert res.successful
    assert harness.wait(lambda: diag_values(diags, 'train_dynamics: simulation') is not None
                        and 'num_coaches: 3 -> 4' in diag_values(
                            diags, 'train_dynamics: simulation')['pending_changes'], 5.0)
    # The standstill counters in both stepping modes; not error control's.
    simulation = diag_values(diags, 'train_dynamics: simulation')
    assert simulation['hold_capped'] == '0' and int(simulation['hold_solves']) >= 0
    assert 'fallback_periods' not in simulation
    n_before = len(couplers)
    assert len(couplers[-1].name) == 2
    t_before = node.sim_time
    resp = harness.reset()
    assert resp.success
    assert 't = 0' in resp.message and 'num_coaches: 3 -> 4' in resp.message
    assert harness.wait(lambda: len(couplers) > n_before and len(couplers[-1].name) == 3
                        and node.sim_time > 0.5, 10.0)
    after = [m for m in couplers[n_before:] if len(m.name) == 3]
    assert stamp_s(after[0]) < 0.2
    first = [m for m in coaches if len(m.name) == 4][0]
    assert max(abs(p) for p in first.position) < 2.0      # back at the start
    # /clock: strictly increasing, except one jump back to ~0 at the reset.
    c = np.array([m.clock.sec + m.clock.nanosec * 1e-9 for m in clocks])
    jumps = np.nonzero(np.diff(c) <= 0)[0]
    assert len(jumps) == 1, c[jumps[0] - 2:jumps[0] + 3] if len(jumps) else None
    j = jumps[0]
    assert c[j] >= t_before - 0.1 and c[j + 1] < 0.2
    assert len(c[:j + 1]) > 100 and np.all(np.diff(c[j + 1:]) > 0)
    # A second reset with nothing pending says so.
    resp = harness.reset()
    assert resp.success and 'no pending' in resp.message
    assert math.isfinite(node.sim_time)


def test_wait_for_input_holds_t0_until_a_publisher_connects(harness):
    node = harness.start(wait_for_input=10.0, real_time_factor=2.0)
    harness.spin_for(1.0)
    assert node.sim_time == 0.0                      # nobody publishes brake_pipe/pressure
    pub = harness.publisher('brake_pipe/pressure', reliable=False)
    assert harness.wait(lambda: node.sim_time > 0.2, 5.0)
    pub.publish(fluid(500000.0 + ATM))
    # Without a publisher, the wait ends at the limit.
    harness.stop(node)
    harness.probe.destroy_publisher(pub)
    node = harness.start(wait_for_input=0.5, real_time_factor=2.0)
    assert harness.wait(lambda: node.sim_time > 0.2, 5.0)


def test_set_callback_validates_only_and_the_post_set_callback_applies(harness):
    """ROS 2 parameter design: the set callback has no side effects; post-set applies."""
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.parameter import Parameter

    node = harness.start(real_time_factor=2.0)
    assert harness.wait(lambda: node.sim_time > 0.1, 10.0)
    live = [Parameter('model_type', value='sign'), Parameter('scale_factor', value=50.0)]
    for callback in node._on_set_parameters_callbacks:      # rclpy's list of set callbacks
        assert callback(live).successful
    assert (node.simulator.model_type, node.simulator.u) == ('tanh', 1000.0)   # untouched

    def veto(params):
        return SetParametersResult(successful=False, reason='vetoed')
    node.add_on_set_parameters_callback(veto)
    assert not node.set_parameters_atomically(live).successful
    assert (node.simulator.model_type, node.simulator.u) == ('tanh', 1000.0)
    node.remove_on_set_parameters_callback(veto)
    assert node.set_parameters_atomically(live).successful
    assert (node.simulator.model_type, node.simulator.u) == ('sign', 50.0)


def test_a_deleted_consist_file_leaves_the_running_node_alone(harness, tmp_path):
    """Sets, pending changes and diagnostics use the consist read at start: no file access."""
    from rclpy.parameter import Parameter

    path = tmp_path / 'train.yaml'
    path.write_text('vehicles: [{type: paper_coach, count: 4}]\n')
    node = harness.start(consist_file=str(path), real_time_factor=2.0)
    assert harness.wait(lambda: node.sim_time > 0.1, 10.0)
    path.unlink()
    for p in (Parameter('scale_factor', value=50.0), Parameter('initial_speed', value=10.0)):
        assert node.set_parameters([p])[0].successful
    assert node.pending_changes() == 'initial_speed: 44.444 -> 10'
    t = node.sim_time
    assert harness.wait(lambda: node.sim_time > t + 1.5, 10.0)      # diagnostics ticked
    assert node.simulator.n == 4 and node.fault is None
    assert not node.set_parameters([Parameter('davis_a', value=10.0)])[0].successful


def test_duration_changes_after_the_end_resume_the_run(harness):
    from rclpy.parameter import Parameter

    node = harness.start(real_time_factor=0.0, duration=0.5)
    assert harness.wait(lambda: node.finished, 10.0)
    assert node.sim_time == pytest.approx(0.5)
    (res,) = node.set_parameters([Parameter('duration', value=0.8)])
    assert res.successful and not node.finished
    assert harness.wait(lambda: node.finished, 10.0)
    assert node.sim_time == pytest.approx(0.8)
    (res,) = node.set_parameters([Parameter('duration', value=0.0)])     # 0 = forever
    assert res.successful and not node.finished
    assert harness.wait(lambda: node.sim_time > 1.0, 10.0)
    (res,) = node.set_parameters([Parameter('duration', value=-1.0)])
    assert not res.successful and 'duration' in res.reason
