"""
The run control of ``sim_node``, in-process: pause/resume/step, lock-step, input timing.

Also the node's ROS conventions: status names from its full name, per-train ``/clock``,
diagnostics under ``use_sim_time``, a WARN for two publishers on the active input.
"""
from __future__ import annotations

import numpy as np
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure, JointState
from sim_node_helpers import diag_values, fluid, stamp_s
from std_srvs.srv import Trigger
from train_dynamics.ros.sim_node import SimNode

ATM = 101325.0
PERIOD = 0.01     # [s] output period at the default publish_rate
WAIT = 60.0       # [s wall] bound of a wait on an event (it returns at the event)


def _call(harness, name: str, node='train_dynamics'):
    resp = harness.call(Trigger, f'/{node}/{name}', Trigger.Request())
    assert resp.success, resp.message
    return resp.message


def test_pause_stops_time_step_advances_exactly_n_periods_resume_goes_on(harness):
    coaches = harness.collect(JointState, 'coaches')
    node = harness.start(real_time_factor=2.0)
    assert harness.wait(lambda: node.sim_time > 0.3, WAIT)
    assert 'paused at t =' in _call(harness, 'pause')
    t_paused, n_paused = node.sim_time, len(coaches)
    harness.spin_for(0.5)
    assert node.sim_time == t_paused                 # the time does not move while paused
    n_before = len(coaches)
    assert n_before - n_paused <= 1                  # (one in flight at the pause)
    node.set_parameters([Parameter('step_periods', value=7)])
    assert 'stepping 7 output period(s)' in _call(harness, 'step')
    assert harness.wait(lambda: len(coaches) >= n_before + 7, WAIT)
    harness.spin_for(0.4)
    stepped = coaches[n_before:]
    assert len(stepped) == 7                         # exactly N outputs, then paused again
    t = [stamp_s(m) for m in stepped]
    assert all(abs(b - a - PERIOD) < 1e-9 for a, b in zip(t, t[1:]))
    assert node.sim_time == t[-1]
    harness.spin_for(0.3)
    assert node.sim_time == t[-1]
    assert 'resumed' in _call(harness, 'resume')
    assert harness.wait(lambda: node.sim_time > t[-1] + 0.2, WAIT)


def _controller(harness, answer: bool):
    """Return a probe controller on coaches; it answers each with its stamp if ``answer``."""
    pub = harness.probe.create_publisher(
        FluidPressure, 'brake_pipe/pressure',
        QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    seen = []

    def on_coaches(msg):
        seen.append(msg)
        if answer:
            out = fluid(4.5e5 + ATM)
            out.header.stamp = msg.header.stamp
            pub.publish(out)
    harness.probe.create_subscription(
        JointState, 'coaches', on_coaches,
        QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
    return pub, seen


def test_lockstep_waits_for_the_controller_and_advances_one_period_per_answer(harness):
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0, duration=0.5)
    harness.spin_for(0.5)
    assert node.sim_time == 0.0                      # nobody connected: t = 0 holds
    pub, seen = _controller(harness, answer=True)
    assert harness.wait(lambda: node.finished, WAIT)
    t = [stamp_s(m) for m in seen]
    assert t[0] == 0.0                               # the first output is not lost
    assert len(t) == 51 and all(abs(b - a - PERIOD) < 1e-9 for a, b in zip(t, t[1:]))


def test_lockstep_timeout_reports_and_waits(harness):
    from diagnostic_msgs.msg import DiagnosticArray

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    pub, seen = _controller(harness, answer=False)
    node = harness.start(sync_mode='lockstep', real_time_factor=0.0, lockstep_timeout=0.3)
    assert harness.wait(lambda: seen, WAIT)
    assert harness.wait(lambda: (diag_values(diags, 'train_dynamics: simulation') or {})
                        .get('lockstep_timeouts') == '1', WAIT)
    d = diag_values(diags, 'train_dynamics: simulation')
    assert d['_level'] == 1 and 'waiting' in d['_message'] and d['sync_mode'] == 'lockstep'
    assert node.sim_time == 0.0 and not node.finished and len(seen) == 1
    # a late answer lets it go on
    out = fluid(5e5 + ATM)
    out.header.stamp = seen[0].header.stamp
    pub.publish(out)
    assert harness.wait(lambda: len(seen) >= 2, WAIT)
    assert stamp_s(seen[1]) == PERIOD


def test_lockstep_on_traction_commands_waits_for_each_and_names_the_silent_one(harness):
    """
    ``lockstep_inputs: [traction]``: a period goes on per traction command, nothing else.

    The controller answers the first five outputs on ``coach_1/traction/command`` (no brake
    input at all), then falls silent: six outputs (t = 0 .. 0.05 s), then the node waits and
    its timeout names the traction topic.
    """
    from pathlib import Path

    from diagnostic_msgs.msg import DiagnosticArray
    from std_msgs.msg import Float64
    from train_dynamics.physics.kernel.layout import INPUT

    consist = Path(__file__).resolve().parents[2] / 'config' / 'consist_passenger_12.yaml'
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    pub = harness.probe.create_publisher(Float64, 'coach_1/traction/command', qos)
    seen = []

    def on_coaches(msg):
        seen.append(msg)
        if len(seen) <= 5:
            pub.publish(Float64(data=0.5))
    harness.probe.create_subscription(JointState, 'coaches', on_coaches, qos)
    node = harness.start(consist_file=str(consist), initial_speed=10.0, sync_mode='lockstep',
                         lockstep_inputs=['traction'], real_time_factor=0.0,
                         lockstep_timeout=0.3)
    assert harness.wait(lambda: (diag_values(diags, 'train_dynamics: simulation') or {})
                        .get('lockstep_timeouts') == '1', WAIT)
    assert [round(stamp_s(m), 9) for m in seen] == [0.0, 0.01, 0.02, 0.03, 0.04, 0.05]
    assert node.sim_time == 0.05
    d = diag_values(diags, 'train_dynamics: simulation')
    assert d['lockstep_inputs'] == 'traction'
    assert 'on coach_1/traction/command' in d['_message']
    assert node.simulator.coach[INPUT.T_CMD, 0] == 0.5     # the answers acted


def test_input_timing_stamp_applies_a_command_at_its_stamp(harness, tmp_path):
    from train_dynamics.recording.bags import read_topics

    bag = tmp_path / 'bag'
    pub = harness.publisher('brake_pipe/pressure')
    node = harness.start(input_timing='stamp', real_time_factor=1.0, record_bag=str(bag))
    assert harness.wait_for_subscriber(pub)
    assert harness.wait(lambda: node.sim_time > 0.2, WAIT)
    msg = fluid(3.5e5 + ATM)
    msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 700_000_000   # t = 0.7 s
    pub.publish(msg)
    late = fluid(4.0e5 + ATM)                                           # t = 0: late
    pub.publish(late)
    assert harness.wait(lambda: node.sim_time > 1.0, WAIT)
    assert node._inputs.late == 1
    harness.stop(node)
    times = {round(m.fluid_pressure): t
             for topic, t, m in read_topics(bag, ['brake_pipe/pressure'])}
    assert times[round(3.5e5 + ATM)] == 700_000_000                     # exactly at its stamp


def test_input_timing_stamp_acts_between_two_steps_exactly_at_the_stamp(harness, tmp_path):
    """
    A cylinder command stamped 0.7043 s acts from 0.7043 s, not from the next 2 ms step.

    Three equal coaches at 10 m/s without resistance, every cylinder to 190 kPa at t_s: the
    couplers stay unloaded and each coach decelerates at a = mu g p / p_max (eq. 13) from
    t_s on, so v(t) = 10 - a (t - t_s) at every output after it (0.706 s instead of t_s
    would be 8.3e-4 m/s slower at 0.71 s). The offline command replaying the node's bag gives
    the very same outputs.
    """
    from train_dynamics.physics.config import SimConfig
    from train_dynamics.recording.bags import read_topics
    from train_dynamics.recording.inputs import read_input_bag
    from train_dynamics.simulation.runner import run_simulation

    bag = tmp_path / 'bag'
    params = {'brake_input': 'cylinder_per_coach', 'initial_speed': 10.0}
    pubs = [harness.publisher(f'coach_{i}/brake_cylinder/pressure') for i in (1, 2, 3)]
    node = harness.start(input_timing='stamp', real_time_factor=1.0, record_bag=str(bag),
                         **params)
    assert all(harness.wait_for_subscriber(p) for p in pubs)
    assert harness.wait(lambda: node.sim_time > 0.2, WAIT)
    assert node.sim_time < 0.6
    t_s, p = 0.7043, 190e3
    for pub in pubs:
        msg = fluid(p + ATM)
        msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 704_300_000
        pub.publish(msg)
    late = fluid(ATM)                      # stamped t = 0.1 s, long passed: late, at once
    late.header.stamp.nanosec = 100_000_000
    pubs[0].publish(late)
    assert harness.wait(lambda: node.sim_time > 1.0, WAIT)
    assert node._inputs.late == 1
    harness.stop(node)

    recorded = [(topic, t) for topic, t, m in read_topics(bag) if 'cylinder/' in topic
                and m.fluid_pressure > ATM]
    assert sorted(recorded) == [(f'coach_{i}/brake_cylinder/pressure', 704_300_000)
                                for i in (1, 2, 3)]             # recorded where they acted
    coaches = {t: np.array(m.velocity) for _, t, m in read_topics(bag, ['coaches'])}
    cfg = SimConfig.from_dict(params)
    a = cfg.adhesion_coefficient * cfg.gravity * p / cfg.max_cylinder_pressure  # [m/s^2]
    assert np.all(coaches[700_000_000] == 10.0)
    for t_ns in range(710_000_000, 1_000_000_001, 10_000_000):
        np.testing.assert_allclose(coaches[t_ns], 10.0 - a * (t_ns * 1e-9 - t_s),
                                   rtol=0.0, atol=1e-12)
    # the offline command fed the bag's inputs at their bag times: the same outputs
    offline = {}
    run_simulation(cfg, max(coaches) * 1e-9, read_input_bag(str(bag), cfg),
                   on_sample=lambda s: offline.__setitem__(round(s.t * 1e9), s.sim.v))
    assert sorted(offline) == sorted(coaches)
    for t_ns, v in coaches.items():
        assert np.array_equal(offline[t_ns], v), t_ns


def test_namespaced_trains_keep_their_own_clock_and_status_names(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rosgraph_msgs.msg import Clock

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    clocks = {ns: harness.collect(Clock, f'/{ns}/clock') for ns in ('train1', 'train2')}
    nodes = {}
    for ns, rtf in (('train1', 1.0), ('train2', 3.0)):
        nodes[ns] = SimNode(namespace=ns, cli_args=['--ros-args', '-r', '/clock:=clock'],
                            parameter_overrides=[Parameter('publish_clock', value=True),
                                                 Parameter('real_time_factor', value=rtf)])
        harness.add(nodes[ns])
    assert harness.wait(lambda: all(diag_values(diags, f'{ns}/train_dynamics: simulation')
                                    for ns in nodes) and nodes['train2'].sim_time > 1.0, WAIT)
    last = {ns: clocks[ns][-1].clock.sec + clocks[ns][-1].clock.nanosec * 1e-9 for ns in nodes}
    assert last['train2'] > 1.5 * last['train1'] > 0      # each its own time
    assert diag_values(diags, 'train_dynamics: simulation') is None


def test_diagnostics_run_under_use_sim_time_without_a_clock(harness):
    from diagnostic_msgs.msg import DiagnosticArray

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    harness.start(use_sim_time=True)
    assert harness.wait(lambda: diag_values(diags, 'train_dynamics: simulation'), WAIT)


def test_two_publishers_on_the_active_input_raise_a_warn(harness):
    from diagnostic_msgs.msg import DiagnosticArray

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    harness.publisher('brake_pipe/pressure')
    harness.publisher('brake_pipe/pressure')
    harness.start()
    assert harness.wait(lambda: 'brake_pipe/pressure (2 publishers)' in (diag_values(
        diags, 'train_dynamics: brake input') or {}).get('multiple_publishers', ''), WAIT)
    d = diag_values(diags, 'train_dynamics: brake input')
    assert d['_level'] == 1 and 'more than one publisher' in d['_message']


def test_lockstep_bag_files_split_in_simulation_time_not_wall_time(tmp_path):
    """
    A lock-step bag's files do not depend on how fast the machine ran the loop.

    ``sim_time_split``: with a period of 1 s, messages at 0..2.5 s of simulation time written
    slowly (wall gaps beyond the period) and fast give the same files, split at 1 s and 2 s.
    """
    import logging
    import time

    from train_dynamics.recording.bags import BagRecorder, read_topics
    from train_dynamics.recording.messages import typestore
    from train_dynamics.ros.recorder import BagWriter

    types = typestore()
    data = bytes(types.serialize_cdr(types.types['std_msgs/msg/Float64'](data=1.0),
                                     'std_msgs/msg/Float64'))
    files = []
    for name, pause in (('fast', 0.0), ('slow', 0.3)):
        rec = BagRecorder(tmp_path / name)
        writer = BagWriter(rec, logging.getLogger('test'), flush_period=1.0,
                           sim_time_split=True)
        # the slow run takes ~1.5 s of wall time: the wall-clock rule would split it once
        for k in range(11):
            writer.write('x', 'std_msgs/msg/Float64', k * 250_000_000, data)
            time.sleep(pause if k % 2 else 0.0)
        writer.close()
        assert writer.error is None
        assert len(list(read_topics(tmp_path / name, ['x']))) == 11
        files.append([(p.name[len(name):], p.stat().st_size)
                      for p in sorted((tmp_path / name).glob('*.mcap'))])
    assert files[0] == files[1]
    assert len(files[0]) == 3       # [0, 1) s, [1, 2) s, [2, 2.5] s
