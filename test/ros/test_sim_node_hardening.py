"""
sim_node hardening (faults, stale inputs, recording), real rclpy and real bags.

Bad and flooding inputs, stale inputs, numerical faults, SIGINT/SIGTERM/SIGKILL during a
recorded run, a long free run, rapid live model switching.
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from sim_node_helpers import all_finite, diag_values, fluid, joint_arrays, stamp_s

ATM = 101325.0
SIM = 'train_dynamics: simulation'
INPUT = 'train_dynamics: brake input'
REPO = Path(__file__).resolve().parents[2]


FLOODER = r"""
import sys, time, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure
rclpy.init()
node = rclpy.create_node('flooder')
pub = node.create_publisher(FluidPressure, 'brake_pipe/pressure',
                            QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT))
wait = time.monotonic() + 20.0
while pub.get_subscription_count() == 0 and time.monotonic() < wait:
    time.sleep(0.01)
print('ready', flush=True)
end = time.monotonic() + float(sys.argv[1])
n = 0
while time.monotonic() < end:
    pub.publish(FluidPressure(fluid_pressure=float('nan')))
    n += 1
    if n % 50 == 0:
        time.sleep(0.001)
print(n, flush=True)
node.destroy_node()
rclpy.try_shutdown()
"""


def test_bad_inputs_are_rejected_counted_and_a_flood_does_not_slow_the_node(harness, capfd):
    from diagnostic_msgs.msg import DiagnosticArray
    from sensor_msgs.msg import JointState

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    couplers = harness.collect(JointState, 'couplers')
    node = harness.start(real_time_factor=1.0)
    head = harness.publisher('brake_pipe/pressure')
    head_be = harness.publisher('brake_pipe/pressure', reliable=False)
    wrong = harness.publisher('coach_1/brake_cylinder/pressure')     # cylinder_per_coach topic
    wrong2 = harness.publisher('coach_2/brake_pipe/pressure')        # pipe_per_coach topic
    unknown = harness.publisher('coach_7/brake_pipe/pressure')       # the train has 3 coaches
    assert harness.wait_for_subscriber(head)
    for value in (float('nan'), float('inf'), float('-inf'), -1.0, 3.0e6):
        head.publish(fluid(value))
    head_be.publish(fluid(600000.0))                                  # valid, best effort
    head.publish(fluid(600000.0))
    # The graph scan finds the other modes' and the unknown coach's topics within 2 s.
    end = time.monotonic() + 3.0
    while time.monotonic() < end:
        for p in (wrong, wrong2, unknown):
            p.publish(fluid(500000.0))
        harness.spin_for(0.05)

    def counts():
        d = diag_values(diags, INPUT)
        return {} if d is None else d
    assert harness.wait(lambda: int(counts().get('rejected_unknown_coach', 0)) > 0
                        and int(counts().get('rejected_wrong_mode', 0)) > 0, 5.0), counts()
    d = counts()
    assert int(d['rejected_non_finite']) == 3
    assert int(d['rejected_negative']) == 1
    assert int(d['rejected_too_high']) == 1
    assert int(d['accepted']) >= 1
    assert d['_level'] == 1 and 'rejected' in d['_message']

    # A flood of NaN from another process (thousands per second) for 3 s: the node keeps its
    # pace and its outputs, counts them, and warns only a few times (throttled).
    env = dict(os.environ)
    flood = subprocess.Popen([sys.executable, '-c', FLOODER, '3.0'], env=env,
                             stdout=subprocess.PIPE, text=True)
    out: list[str] = []
    threading.Thread(target=lambda: out.extend(flood.stdout), daemon=True).start()
    assert harness.wait(lambda: out or flood.poll() is not None, 30.0)   # connected
    t_wall0, t_sim0, n0 = time.monotonic(), node.sim_time, len(couplers)
    non_finite0 = int(counts()['rejected_non_finite'])
    while flood.poll() is None:
        harness.spin_for(0.05)
    harness.spin_for(0.1)
    assert out[0].strip() == 'ready', out
    sent = int(out[1].strip())
    harness.spin_for(1.5)
    wall, sim = time.monotonic() - t_wall0, node.sim_time - t_sim0
    assert sent > 3000, sent
    assert sim / wall == pytest.approx(1.0, abs=0.1)
    assert len(couplers) - n0 == pytest.approx(100 * sim, rel=0.1)
    d = counts()
    assert int(d['rejected_non_finite']) - non_finite0 > 500
    _, y, ydot, f = joint_arrays(couplers[-50:])
    assert all_finite(y, ydot, f) and node.fault is None
    err = capfd.readouterr().err
    warnings = [ln for ln in err.splitlines() if 'rejected input on /brake_pipe/pressure' in ln
                and 'non_finite' in ln]
    assert 1 <= len(warnings) <= 4, warnings
    assert any('/coach_7/brake_pipe/pressure' in ln and 'unknown_coach' in ln
               for ln in err.splitlines())
    assert any('/coach_1/brake_cylinder/pressure' in ln and 'wrong_mode' in ln
               for ln in err.splitlines())


def test_stale_input_emergency_then_fresh_then_hold(harness, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from train_dynamics.recording.bags import read_topics

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    coaches = harness.collect(JointState, 'coaches')
    cylinders = harness.collect(JointState, 'brake_cylinders')
    node = harness.start(real_time_factor=2.0, input_timeout=0.5,
                         on_input_timeout='emergency')
    head = harness.publisher('brake_pipe/pressure')
    assert harness.wait_for_subscriber(head)

    deadline = time.monotonic() + 5.0

    def feed(seconds):
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            head.publish(fluid(500000.0 + ATM))
            harness.spin_for(0.02)
    feed(1.0)
    while diag_values(diags, INPUT) is None and time.monotonic() < deadline:
        feed(0.1)                  # /diagnostics comes at ~1 Hz wall: wait for the first one
    d = diag_values(diags, INPUT)
    assert d is not None and d['stale'] == 'false' and d['_level'] == 0
    assert max(max(m.effort) for m in coaches) == 0.0              # released
    # Silence: after 0.5 s (wall) the fail-safe vents the head of the pipe.
    t_silence = node.sim_time
    assert harness.wait(lambda: (diag_values(diags, INPUT) or {}).get('emergency_applied')
                        == 'true', 3.0)
    d = diag_values(diags, INPUT)
    assert d['stale'] == 'true' and d['_level'] == 2 and 'emergency' in d['_message']
    assert harness.wait(lambda: max(coaches[-1].effort) > 1000.0, 5.0)   # brakes applied
    onset = min(stamp_s(m) for m in coaches if max(m.effort) > 0.0)
    assert onset - t_silence == pytest.approx(2.0 * 0.5, abs=0.5)       # rtf 2 x 0.5 s
    # Fresh input again: back to the held values (release), the cylinders empty.
    feed(1.5)
    d = diag_values(diags, INPUT)
    assert d['stale'] == 'false' and d['emergency_applied'] == 'false'
    p_cyl = [max(m.position) for m in cylinders[-100:]]
    assert p_cyl[-1] < p_cyl[0]                                        # releasing
    # hold: silence is reported (WARN) but the pipe keeps the last value.
    assert node.set_parameters([Parameter('on_input_timeout', value='hold')])[0].successful
    assert harness.wait(lambda: (diag_values(diags, INPUT) or {}).get('stale') == 'true', 3.0)
    harness.spin_for(1.2)
    d = diag_values(diags, INPUT)
    assert d['emergency_applied'] == 'false' and d['_level'] == 1
    assert min(cylinders[-1].effort) == pytest.approx(500000.0, abs=1.0)   # pipe charged
    harness.stop(node)

    # cylinder_per_coach: the fail-safe fills every cylinder, and the bag says so.
    bag = tmp_path / 'stale'
    cylinders.clear()
    node = harness.start(brake_input='cylinder_per_coach', real_time_factor=2.0,
                         input_timeout=0.3, on_input_timeout='emergency', record_bag=str(bag))
    assert harness.wait(lambda: cylinders and min(cylinders[-1].position) == 380000.0, 5.0)
    harness.spin_for(0.2)
    harness.stop(node)
    failsafe = [(topic, msg) for topic, _, msg in read_topics(bag)
                if topic.endswith('brake_cylinder/pressure')]
    assert sorted(t for t, _ in failsafe) == [f'coach_{i}/brake_cylinder/pressure'
                                              for i in (1, 2, 3)]
    assert all(m.header.frame_id == 'train_dynamics/input_timeout'
               and m.fluid_pressure == 380000.0 + ATM for _, m in failsafe)


def test_numerical_fault_stops_reports_keeps_the_bag_and_reset_recovers(harness, tmp_path,
                                                                        capfd):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from train_dynamics.recording.bags import read_topics

    bag = tmp_path / 'fault'
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    couplers = harness.collect(JointState, 'couplers')
    # A fault bound of 0.1 mm: the first braking compresses the couplers beyond it.
    node = harness.start(brake_input='cylinder_per_coach', real_time_factor=2.0,
                         max_coupler_displacement=1e-4, record_bag=str(bag))
    pub = harness.publisher('coach_1/brake_cylinder/pressure')
    assert harness.wait_for_subscriber(pub)
    send = harness.every(0.02, lambda: pub.publish(fluid(380000.0 + ATM)))
    assert harness.wait(lambda: (send(), node.fault)[1] is not None, 5.0)
    t_fault = node.sim_time
    harness.spin_for(1.2)
    n = len(couplers)
    harness.spin_for(0.5)
    assert len(couplers) == n                       # integration (and output) stopped
    assert node.sim_time == t_fault                 # the last good state is kept
    last = couplers[-1]
    assert stamp_s(last) <= t_fault + 1e-9 and all_finite(np.array(last.effort))
    d = diag_values(diags, SIM)
    assert d['_level'] == 2 and d['integrator'] == 'fault' and 'fault' in d['_message']
    assert 'NUMERICAL FAULT' in capfd.readouterr().err
    # Fix the bound (pending) and reset: running again from t = 0, diagnostics OK.
    assert node.set_parameters([Parameter('max_coupler_displacement', value=5.0)])[0].successful
    resp = harness.reset()
    assert resp.success and 'max_coupler_displacement' in resp.message
    assert harness.wait(lambda: node.sim_time > 0.5 and len(couplers) > n + 20, 5.0)
    assert node.fault is None
    assert harness.wait(lambda: diag_values(diags, SIM)['_level'] == 0, 3.0)
    harness.stop(node)
    # The faulted run's bag is complete up to the fault; the reset started a new one.
    stamps = [t for topic, t, _ in read_topics(bag, ['couplers'])]
    assert stamps[0] == 0 and stamps[-1] == round(stamp_s(last) * 1e9)
    assert np.all(np.diff(stamps) == 10_000_000)
    after = [t for _, t, _ in read_topics(tmp_path / 'fault_reset1', ['couplers'])]
    assert after[0] == 0 and len(after) > 20


def _start_node(args, tmp_path):
    """sim_node in a subprocess; returns (process, stderr lines list)."""
    proc = subprocess.Popen([sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args']
                            + args, cwd=str(tmp_path), stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    lines: list[str] = []
    threading.Thread(target=lambda: lines.extend(proc.stderr), daemon=True).start()
    return proc, lines


def _wait_started(lines, timeout=30.0):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if any('started:' in ln for ln in lines):
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize('sig', [signal.SIGINT, signal.SIGTERM])
def test_signal_during_recorded_run_leaves_a_complete_bag(tmp_path, sig):
    from train_dynamics.recording.bags import bag_info, read_topics

    bag = tmp_path / 'bag'
    proc, lines = _start_node(['-p', f'record_bag:={bag}', '-p', 'real_time_factor:=2.0',
                               '-p', 'publish_clock:=true'], tmp_path)
    try:
        assert _wait_started(lines), lines
        time.sleep(1.5)
        proc.send_signal(sig)
        assert proc.wait(15) == 0, lines
    finally:
        if proc.poll() is None:
            proc.kill()
    assert any('bag closed' in ln for ln in lines), lines
    info = bag_info(bag)
    counts = {t: info.topics[t][1] for t in ('couplers', 'coaches', 'brake_cylinders', 'clock')}
    assert len(set(counts.values())) == 1 and counts['couplers'] > 100, counts
    stamps = [t for _, t, _ in read_topics(bag, ['couplers'])]     # reads to the last message
    assert stamps == [k * 10_000_000 for k in range(len(stamps))]


def test_sigkill_loses_at_most_the_unflushed_part(tmp_path):
    from train_dynamics.recording.bags import read_topics

    bag = tmp_path / 'bag'
    proc, lines = _start_node(['-p', f'record_bag:={bag}', '-p', 'real_time_factor:=1.0',
                               '-p', 'record_flush_period:=0.5'], tmp_path)
    try:
        assert _wait_started(lines), lines
        time.sleep(2.5)
        proc.kill()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    stamps = [t for _, t, _ in read_topics(bag, ['couplers'])]
    assert stamps == [k * 10_000_000 for k in range(len(stamps))]
    # 2.5 s ran; at most one flush period (0.5 s) plus the last file's slack is lost.
    assert stamps[-1] * 1e-9 >= 2.5 - 0.5 - 0.6, stamps[-1]


def _rss_mb() -> float:
    with open('/proc/self/status') as fh:
        for line in fh:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    return float('nan')


def test_long_free_run_memory_flat_stamps_monotonic_exact_counts(harness, tmp_path):
    """
    Run a shortened soak (the hour is in bench/soak).

    30 coaches as fast as possible for 120 s of simulated time, recorded.
    """
    from train_dynamics.recording.bags import bag_info, read_topics

    duration = 120.0
    bag = tmp_path / 'soak'
    node = harness.start(num_coaches=30, real_time_factor=0.0, duration=duration,
                         record_bag=str(bag), publish_clock=True)
    rss = []
    t0 = time.monotonic()
    while not node.finished and time.monotonic() - t0 < 80.0:
        harness.spin_for(0.25)
        rss.append((node.sim_time, _rss_mb()))
    assert node.finished, node.sim_time
    harness.stop(node)
    info = bag_info(bag)
    n = int(duration * 100) + 1
    for topic in ('couplers', 'coaches', 'brake_cylinders', 'clock'):
        assert info.topics[topic][1] == n, (topic, info.topics[topic])
    stamps = np.array([t for _, t, _ in read_topics(bag, ['coaches'])])
    assert np.all(np.diff(stamps) == 10_000_000) and stamps[0] == 0
    # Memory: after the first quarter, RSS grows by less than 25 MB.
    base = [m for t, m in rss if t >= duration * 0.25]
    assert base and max(base) - base[0] < 25.0, rss


def test_rapid_live_model_switching_keeps_the_state_continuous(harness):
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    coaches = harness.collect(JointState, 'coaches')
    couplers = harness.collect(JointState, 'couplers')
    node = harness.start(brake_input='cylinder_per_coach', real_time_factor=2.0)
    pubs = [harness.publisher(f'coach_{i}/brake_cylinder/pressure') for i in (1, 2, 3)]
    for p in pubs:
        assert harness.wait_for_subscriber(p)
    rng = np.random.default_rng(1)
    for k in range(300):
        for p, g in zip(pubs, (380e3, 380e3 * (k // 40 % 2), 100e3)):
            p.publish(fluid(g + ATM))
        model = 'sign' if k % 2 else 'tanh'
        u = float(rng.uniform(50.0, 5000.0))
        res = node.set_parameters_atomically([Parameter('model_type', value=model),
                                              Parameter('scale_factor', value=u)])
        assert res.successful
        harness.spin_for(0.005)
    harness.spin_for(0.2)
    assert (node.simulator.model_type, node.simulator.u) == (model, u)
    assert node.fault is None
    t, x, v, fb = joint_arrays(coaches)
    assert all_finite(x, v, fb) and np.all(np.diff(t) > 0) and t[-1] > 2.0
    dt = np.diff(t)[:, None]
    assert np.all(np.abs(np.diff(v, axis=0)) <= 10.0 * dt)
    assert np.all(np.abs(np.diff(x, axis=0) - v[:-1] * dt) <= 0.05 * dt + 1e-9)
    tc, y, ydot, f = joint_arrays(couplers)
    assert all_finite(y, ydot, f)
    assert np.all(np.abs(np.diff(y, axis=0)) <= 1.0 * np.diff(tc)[:, None] + 1e-9)
    assert np.abs(f).max() < 1e6
