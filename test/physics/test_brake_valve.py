"""brake_valve: the pure valve model, and the node in-process with real rclpy (DDS on loopback)."""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import pytest

from train_dynamics.param_files import load_valve_model, section_node
from train_dynamics.physics.brake_valve import (BrakeValveModel, parse_schedule,
                                                target_pressure, validate_settings,
                                                VALVE_PARAMETERS)

DEFAULTS = {name: spec.default for name, spec in VALVE_PARAMETERS.items()}

ATM = 101325.0
NOMINAL = 500000.0
FULL = 350000.0
REPO = Path(__file__).resolve().parents[2]


# ---------------------------------------------------------------------------------------
# Pure model
# ---------------------------------------------------------------------------------------
def test_handle_targets_are_graduated_between_first_stage_and_full_service():
    m = BrakeValveModel()
    assert m.target_of('release') == NOMINAL
    assert m.target_of('running') == NOMINAL
    assert m.target_of('full_service') == FULL
    assert m.target_of('emergency') == 0.0
    steps = [m.target_of(f'service_{k}') for k in range(1, DEFAULTS['service_steps'] + 1)]
    assert steps[0] == pytest.approx(NOMINAL - 50000.0)          # first stage: 0.5 bar
    assert steps[-1] == pytest.approx(FULL)                      # last step = full service
    diffs = [a - b for a, b in zip(steps, steps[1:])]
    assert all(d > 0 for d in diffs)                             # strictly graduated
    assert max(diffs) == pytest.approx(min(diffs))               # evenly spaced
    with pytest.raises(ValueError, match='service_8'):
        m.target_of('service_8')
    for bad in ('service_0', 'service_01', 'Release', 'lap', ''):
        with pytest.raises(ValueError):
            m.target_of(bad)


def test_single_service_step_is_the_first_stage():
    m = BrakeValveModel(service_steps=1)
    assert m.target_of('service_1') == pytest.approx(NOMINAL - 50000.0)
    assert m.positions() == ['release', 'running', 'service_1', 'full_service', 'emergency']


def test_schedule_parsing():
    entries = parse_schedule(['0.0:release', ' 1.5 : emergency', '3:service_2'])
    assert [(e.time, e.position) for e in entries] == [
        (0.0, 'release'), (1.5, 'emergency'), (3.0, 'service_2')]
    assert parse_schedule([]) == []


@pytest.mark.parametrize('schedule, message', [
    (['1.0 emergency'], 'TIME:POSITION'),
    (['x:emergency'], 'not a number'),
    (['-1:emergency'], '>= 0'),
    (['nan:emergency'], 'finite'),
    (['inf:emergency'], 'finite'),
    (['1:release', '1:emergency'], 'strictly increase'),
    (['2:release', '1:emergency'], 'strictly increase'),
    (['1:brake'], 'unknown handle position'),
    (['1:service_8'], 'service_8'),
    ([1.0], 'TIME:POSITION'),
    ('1.0:emergency', 'list'),
])
def test_schedule_errors_name_the_problem(schedule, message):
    with pytest.raises(ValueError, match=message):
        parse_schedule(schedule)
    with pytest.raises(ValueError, match=message):
        BrakeValveModel(schedule=schedule)


@pytest.mark.parametrize('settings, message', [
    ({'full_service_pressure': 600000.0}, 'below pipe_nominal_pressure'),
    ({'first_service_drop': 200000.0}, 'first_service_drop'),
    ({'service_rate': 0.0}, 'service_rate'),
    ({'emergency_rate': float('nan')}, 'finite'),
    ({'release_rate': -1.0}, 'release_rate'),
    ({'service_steps': 0}, 'service_steps'),
    ({'service_steps': 2.0}, 'integer'),
    ({'pipe_nominal_pressure': True}, 'number'),
    ({'pipe_nominal_pressure': '5 bar'}, 'number'),
])
def test_invalid_settings_rejected(settings, message):
    with pytest.raises(ValueError, match=message):
        validate_settings(settings)
    with pytest.raises(ValueError, match=message):
        BrakeValveModel(**settings)


def test_output_starts_charged_and_holds_in_release():
    m = BrakeValveModel()
    assert m.pressure == NOMINAL
    assert m.advance(10.0) == NOMINAL


def test_full_service_application_takes_five_to_six_seconds():
    m = BrakeValveModel(schedule=['0:full_service'])
    assert m.position == 'full_service'          # due at t = 0: applied at once
    times = [k * 0.01 for k in range(0, 801)]
    p = m.pressures(times)
    assert all(b <= a for a, b in zip(p, p[1:]))               # monotonic fall
    t_full = next(t for t, x in zip(times, p) if x <= FULL + 1e-6)
    assert 5.0 <= t_full <= 6.0
    assert min(p) == pytest.approx(FULL)                        # never undershoots
    assert p[100] == pytest.approx(NOMINAL - DEFAULTS['service_rate'] * 1.0)


def test_emergency_vents_to_zero_in_documented_time():
    m = BrakeValveModel(schedule=['1.0:emergency'])
    assert m.pressure_at(1.0) == NOMINAL                     # nothing before the handle moves
    assert m.pressure_at(1.0 + 1.0) > 0.0                    # still venting after 1 s
    t_zero = 1.0 + NOMINAL / DEFAULTS['emergency_rate']      # documented: 1.25 s
    assert 1.0 <= t_zero - 1.0 <= 1.5
    assert m.pressure_at(t_zero) == pytest.approx(0.0, abs=1e-6)
    assert m.pressure_at(t_zero + 5.0) == 0.0                # no negative gauge pressure


def test_release_recharges_at_release_rate():
    m = BrakeValveModel(schedule=['0:full_service', '10:release'])
    assert m.pressure_at(10.0) == pytest.approx(FULL)
    assert m.pressure_at(11.0) == pytest.approx(FULL + DEFAULTS['release_rate'])
    t_full = 10.0 + (NOMINAL - FULL) / DEFAULTS['release_rate']
    assert m.pressure_at(t_full) == pytest.approx(NOMINAL)
    assert m.pressure_at(30.0) == NOMINAL                    # no overcharge


def test_result_independent_of_step_size():
    sched = ['0.37:service_2', '2.0:emergency', '2.5:service_4', '9.0:release']
    t_end = 14.0
    fine = BrakeValveModel(schedule=sched)
    for _ in range(int(round(t_end / 1e-3))):
        fine.advance(1e-3)
    coarse = BrakeValveModel(schedule=sched)
    while coarse.t < t_end - 1e-12:
        coarse.advance(min(0.77, t_end - coarse.t))
    ref = BrakeValveModel(schedule=sched).pressure_at(t_end)
    assert fine.pressure == pytest.approx(ref, abs=1e-3)
    assert coarse.pressure == pytest.approx(ref, abs=1e-6)
    assert fine.position == coarse.position == 'release'


def test_live_position_cancels_schedule_and_schedule_is_relative_to_when_set():
    m = BrakeValveModel(schedule=['1:emergency', '5:release'])
    m.advance_to(0.5)
    m.set_position('service_1')
    assert m.pending == []
    m.advance_to(3.0)
    assert m.position == 'service_1'                         # the 1 s emergency never came
    assert m.pressure == pytest.approx(NOMINAL - 50000.0)
    m.set_schedule(['0.5:emergency'])
    assert m.pending[0].time == pytest.approx(3.5)
    m.advance_to(3.4)
    assert m.position == 'service_1'
    m.advance_to(3.6)
    assert m.position == 'emergency'


def test_live_settings_change_cannot_strand_the_handle():
    m = BrakeValveModel(position='service_6')
    with pytest.raises(ValueError, match='service_6'):
        m.update_settings(service_steps=5)
    assert m.settings['service_steps'] == 7
    m.update_settings(service_steps=9)
    assert m.target == pytest.approx(NOMINAL - 50000.0 - 5 / 8 * 100000.0)


def test_from_params_and_param_file(tmp_path):
    params = {'schedule': ['1.0:emergency'], 'publish_rate': 20.0, 'use_sim_time': True,
              'atmospheric_pressure': 100000.0, 'emergency_rate': 500000.0}
    m = BrakeValveModel.from_params(params)
    assert m.pressure_at(2.0) == 0.0 and m.pressure_at(1.5) == pytest.approx(250000.0)
    with pytest.raises(ValueError, match='shedule'):
        BrakeValveModel.from_params({'shedule': []}, strict=True)
    f = tmp_path / 'p.yaml'
    f.write_text('train_dynamics:\n  ros__parameters:\n    num_coaches: 4\n'
                 'brake_valve:\n  ros__parameters:\n    schedule: ["0.5:full_service"]\n'
                 '    service_rate: 30000.0\n')
    m = load_valve_model(str(f))
    assert m.pressure_at(1.5) == pytest.approx(NOMINAL - 30000.0)
    f.write_text('brake_valve:\n  ros__parameters:\n    schedule: ["0.5:bogus"]\n')
    with pytest.raises(ValueError, match='bogus'):
        load_valve_model(str(f))


def test_target_pressure_function_matches_model():
    settings = validate_settings({})
    assert target_pressure('service_4', settings) == BrakeValveModel().target_of('service_4')


# ---------------------------------------------------------------------------------------
# Node, in-process, real rclpy
# ---------------------------------------------------------------------------------------
def _make_nodes(overrides):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import FluidPressure

    from train_dynamics.ros.brake_valve_node import OUTPUT_QOS, BrakeValveNode

    valve = BrakeValveNode(parameter_overrides=overrides)
    listener = Node('brake_valve_listener')
    received = []
    listener.create_subscription(FluidPressure, 'brake_pipe/pressure',
                                 lambda msg: received.append(msg), OUTPUT_QOS)
    ex = SingleThreadedExecutor()
    ex.add_node(valve)
    ex.add_node(listener)
    return valve, listener, ex, received


def _cleanup(ex, *nodes):
    ex.shutdown()
    for n in nodes:
        n.destroy_node()


def test_node_publishes_absolute_pressure_following_schedule(rclpy_context, spin_until):
    from rclpy.parameter import Parameter

    valve, listener, ex, received = _make_nodes([
        Parameter('schedule', Parameter.Type.STRING_ARRAY, ['0.8:emergency'])])
    try:
        assert spin_until(ex, lambda: len(received) >= 5, timeout=10.0)
        first = received[0]
        assert first.fluid_pressure == pytest.approx(NOMINAL + ATM)      # absolute Pa
        assert first.header.frame_id == 'brake_valve'
        assert first.header.stamp.sec > 0                                # node clock (wall)
        assert spin_until(ex, lambda: received[-1].fluid_pressure <= ATM + 1.0, timeout=10.0)
        values = [m.fluid_pressure for m in received]
        assert all(b <= a + 1e-6 for a, b in zip(values, values[1:]))   # monotonic venting
        assert min(values) == pytest.approx(ATM)                         # 0 gauge, not below
        assert any(ATM + 1.0 < v < NOMINAL + ATM - 1.0 for v in values)  # not a jump
        assert valve.get_parameter('position').value == 'emergency'      # shows the handle
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in received]
        assert all(b > a for a, b in zip(stamps, stamps[1:]))
        rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
        assert 25.0 < rate < 75.0                                        # 50 Hz default
    finally:
        _cleanup(ex, valve, listener)


def test_node_live_position_change_and_invalid_values(rclpy_context, spin_until):
    from rclpy.parameter import Parameter

    valve, listener, ex, received = _make_nodes([
        Parameter('schedule', Parameter.Type.STRING_ARRAY, ['30.0:emergency'])])
    try:
        assert spin_until(ex, lambda: len(received) >= 2, timeout=10.0)

        # invalid values: rejected with a reason, nothing changed
        before = {n: valve.get_parameter(n).value for n in
                  ('position', 'schedule', 'service_steps', 'publish_rate',
                   'full_service_pressure')}
        bad = [
            Parameter('position', value='bogus'),
            Parameter('position', value='service_9'),
            Parameter('position', value=3),
            Parameter('schedule', value=['1.0:emergency', '0.5:release']),
            Parameter('schedule', value=['soon:emergency']),
            Parameter('service_steps', value=0),
            Parameter('publish_rate', value=float('nan')),
            Parameter('publish_rate', value=-5.0),
            Parameter('full_service_pressure', value=600000.0),
        ]
        for p in bad:
            result = valve.set_parameters([p])[0]
            assert not result.successful, p.name
            assert result.reason, p.name
        result = valve.set_parameters([Parameter('position', value='bogus')])[0]
        assert 'bogus' in result.reason
        result = valve.set_parameters_atomically([Parameter('position', value='full_service'),
                                                  Parameter('service_steps', value=0)])
        assert not result.successful
        after = {n: valve.get_parameter(n).value for n in before}
        assert after == before
        assert valve.model.position == 'release'
        assert len(valve.model.pending) == 1                             # schedule untouched

        # the set callbacks only validate; the post-set callback moves the handle
        for callback in valve._on_set_parameters_callbacks:   # rclpy's list of set callbacks
            assert callback([Parameter('position', value='emergency')]).successful
        assert valve.model.position == 'release' and len(valve.model.pending) == 1
        # one description format: the descriptors come from the ParamSpec tables
        d = valve.describe_parameter('service_steps')
        assert (d.integer_range[0].from_value, d.integer_range[0].to_value) == (1, 50)
        d = valve.describe_parameter('publish_rate')
        assert d.floating_point_range[0].from_value == 0.1 and '<= 1000' in \
            d.additional_constraints

        # a live position change takes effect immediately and cancels the schedule
        n0 = len(received)
        result = valve.set_parameters([Parameter('position', value='full_service')])[0]
        assert result.successful, result.reason
        assert valve.model.position == 'full_service'
        assert valve.model.pending == []
        assert spin_until(ex, lambda: len(received) > n0 + 2, timeout=5.0)
        assert received[-1].fluid_pressure < NOMINAL + ATM - 1.0          # falling already
        assert spin_until(ex, lambda: received[-1].fluid_pressure <= FULL + ATM + 1.0,
                          timeout=10.0)
        assert received[-1].fluid_pressure == pytest.approx(FULL + ATM)

        # atmospheric_pressure and publish_rate live (an integer for a double is converted)
        result = valve.set_parameters([Parameter('atmospheric_pressure', value=100000.0),
                                       Parameter('publish_rate', value=100)])[0]
        assert result.successful, result.reason
        assert valve.get_parameter('publish_rate').value == 100.0
        n1 = len(received)
        assert spin_until(ex, lambda: len(received) > n1 + 3, timeout=5.0)
        assert received[-1].fluid_pressure == pytest.approx(FULL + 100000.0)
    finally:
        _cleanup(ex, valve, listener)


def test_node_schedule_runs_on_sim_time(rclpy_context, spin_until):
    """With use_sim_time the schedule counts simulation seconds from /clock."""
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rosgraph_msgs.msg import Clock

    valve, listener, ex, received = _make_nodes([
        Parameter('use_sim_time', value=True),
        Parameter('schedule', Parameter.Type.STRING_ARRAY, ['1.0:emergency'])])
    clock_node = Node('fake_clock')
    clock_pub = clock_node.create_publisher(Clock, '/clock', QoSProfile(
        depth=10, reliability=ReliabilityPolicy.RELIABLE))
    ex.add_node(clock_node)
    try:
        assert spin_until(ex, lambda: clock_pub.get_subscription_count() > 0, timeout=10.0)
        t_sim = 0.0
        while t_sim < 2.0:
            t_sim = round(t_sim + 0.01, 6)
            msg = Clock()
            msg.clock.sec = int(t_sim)
            msg.clock.nanosec = int(round((t_sim - int(t_sim)) * 1e9))
            clock_pub.publish(msg)
            ex.spin_once(timeout_sec=0.005)
            ex.spin_once(timeout_sec=0.0)
        assert spin_until(ex, lambda: received and received[-1].header.stamp.sec >= 1,
                          timeout=5.0)
        by_time = [(m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec, m.fluid_pressure - ATM)
                   for m in received]
        assert all(t < 2.5 for t, _ in by_time)                         # simulated stamps
        before = [p for t, p in by_time if t <= 0.99]
        after = [(t, p) for t, p in by_time if t >= 1.2]
        assert before and all(p == pytest.approx(NOMINAL) for p in before)
        assert after
        for t, p in after:                                               # vented at 400 kPa/s
            assert p == pytest.approx(max(0.0, NOMINAL - DEFAULTS['emergency_rate'] * (t - 1.0)),
                                      abs=2.0 * 0.02 * DEFAULTS['emergency_rate'])
    finally:
        _cleanup(ex, valve, listener, clock_node)


def test_executable_stops_cleanly_on_sigterm_and_rejects_bad_startup_parameters():
    env = dict(os.environ)
    env['PYTHONPATH'] = str(REPO) + os.pathsep + env.get('PYTHONPATH', '')
    proc = subprocess.Popen([sys.executable, '-m', 'train_dynamics.ros.brake_valve_node',
                             '--ros-args', '-p', 'publish_rate:=20.0'], env=env, cwd=str(REPO),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 30.0
        lines = []
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            lines.append(line)
            if 'publishing' in line:
                break
        assert any('publishing' in line for line in lines), lines
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=15.0) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()

    bad = subprocess.run([sys.executable, '-m', 'train_dynamics.ros.brake_valve_node',
                          '--ros-args', '-p', 'position:=bogus'], env=env, cwd=str(REPO),
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2
    assert 'bogus' in bad.stderr


def test_shipped_parameter_files_drive_a_valid_valve():
    """Every config/*.yaml with a brake_valve section builds a valve (the offline input)."""
    import yaml

    files = sorted((REPO / 'config').glob('*.yaml'))
    checked = 0
    for f in files:
        doc = yaml.safe_load(f.read_text()) or {}
        if not any(section_node(key) == 'brake_valve' for key in doc):
            continue
        m = load_valve_model(str(f))
        assert m.pressure_at(0.0) == pytest.approx(m.settings['pipe_nominal_pressure'])
        checked += 1
    assert checked >= 3, 'the shipped scenarios have brake_valve sections'
