"""
The nodes under hostile input: no traceback, no leftovers, bounded recorder, complete diagnostics.

Items 2 (live set + reset), 3 (failed start), 6/7 (parameter files), 9 (valve schedule),
10 (recorder bounded in bytes), 11 (wrong-type publisher), 12 (timers at shutdown).
"""
from __future__ import annotations

import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

import pytest

from sim_node_helpers import diag_values
from train_dynamics.ros import executor as ros_executor
from train_dynamics.ros import recorder as ros_recorder
from train_dynamics.ros import sim_node as sim_node_mod

REPO = Path(__file__).resolve().parents[2]
INPUT = 'train_dynamics: brake input'


# -- item 7 (and 6): parameter files before rclpy ----------------------------------------------
@pytest.mark.parametrize('content, words', [(None, 'not found'), ('a: [\n', 'cannot read'),
                                            ('- 1\n- 2\n', 'not a ROS 2 parameter file'),
                                            ('x:\n  y: 1\n', 'no ros__parameters')])
@pytest.mark.parametrize('main, prog', [(sim_node_mod.main, 'sim_node'), (None, 'brake_valve')])
def test_bad_params_file_is_one_line_and_exit_2_not_an_rclerror(tmp_path, capsys, content, words,
                                                                main, prog):
    from train_dynamics.ros import brake_valve_node

    main = main or brake_valve_node.main
    path = tmp_path / 'p.yaml'
    if content is not None:
        path.write_text(content)
    assert main([prog, '--ros-args', '--params-file', str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'{prog}: error: ') and words in err[0], err


def test_params_file_typo_section_and_undeclared_keys_are_warned_about(tmp_path, capsys):
    path = tmp_path / 'p.yaml'
    path.write_text('train_dynamic:\n  ros__parameters:\n    num_coaches: 4\n'
                    'train_dynamics:\n  ros__parameters:\n    coach_mas: 4.0\n'
                    '/**:\n  ros__parameters:\n    schedule: ["1.0:emergency"]\n')
    args = ['sim_node', '--ros-args', '--params-file', str(path)]
    assert ros_executor.check_params_files('sim_node', args, 'train_dynamics',
                                           sim_node_mod.SPECS) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 2 and all(line.startswith('sim_node: warning: ') for line in err)
    assert "'train_dynamic'" in err[0] and 'train_dynamics, brake_valve, /**' in err[0]
    assert 'coach_mas' in err[1] and 'schedule' not in err[1]      # /**: the valve's, ignored


def test_node_ignores_wildcard_keys_of_the_other_node(tmp_path, rclpy_context):
    from rclpy.parameter import Parameter

    node = sim_node_mod.SimNode(parameter_overrides=[Parameter('num_coaches', value=4)])
    try:
        assert node.simulator.n == 4
    finally:
        node.destroy_node()


def test_node_takes_a_relative_consist_file_from_its_parameter_files_folder(tmp_path):
    """The path rule as offline: next to the parameter file, not the cwd's same-named file."""
    folder, cwd = tmp_path / 'params', tmp_path / 'cwd'
    folder.mkdir()
    cwd.mkdir()
    (folder / 'mine.yaml').write_text('vehicles: [{type: paper_coach, count: 2}]\n')
    (cwd / 'mine.yaml').write_text('vehicles: [{type: paper_coach, count: 3}]\n')
    params = folder / 'p.yaml'
    params.write_text('train_dynamics:\n  ros__parameters:\n    consist_file: mine.yaml\n'
                      '    coach_mass: 45000\n    duration: 0.1\n    real_time_factor: 0.0\n')
    cmd = [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args',
           '--params-file', str(params)]        # coach_mass: an integer for a double
    proc = subprocess.run(cmd, cwd=str(cwd), capture_output=True, text=True, timeout=120,
                          env={**os.environ, 'PYTHONPATH': str(REPO)})
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert 'started: 2 coaches' in proc.stderr, proc.stderr[-2000:]


# -- item 9: the valve node applies the validator ----------------------------------------------
def test_valve_node_rejects_a_schedule_time_of_1e300(rclpy_context):
    from rclpy.parameter import Parameter

    from train_dynamics.ros.brake_valve_node import BrakeValveNode

    with pytest.raises(ValueError, match='1e\\+09'):
        BrakeValveNode(parameter_overrides=[Parameter('schedule', value=['1e300:emergency'])])
    node = BrakeValveNode()
    try:
        result = node.set_parameters([Parameter('schedule', value=['1e300:emergency'])])[0]
        assert not result.successful and '1e+09' in result.reason
    finally:
        node.destroy_node()


# -- items 2 and 3: nothing left behind --------------------------------------------------------
class Broken:
    """A simulator that cannot be built (what an unforeseen bad value would do)."""

    def __init__(self, cfg, *args, **kwargs):
        raise ZeroDivisionError('division by zero')


def test_failed_start_with_record_bag_leaves_no_bag_and_the_path_stays_usable(
        tmp_path, rclpy_context, monkeypatch):
    from rclpy.parameter import Parameter

    bag = tmp_path / 'rec'
    real = sim_node_mod.TrainSimulator
    monkeypatch.setattr(sim_node_mod, 'TrainSimulator', Broken)
    with pytest.raises(ZeroDivisionError):
        sim_node_mod.SimNode(parameter_overrides=[Parameter('record_bag', value=str(bag))])
    assert not bag.exists() and list(tmp_path.iterdir()) == []
    monkeypatch.setattr(sim_node_mod, 'TrainSimulator', real)
    node = sim_node_mod.SimNode(parameter_overrides=[Parameter('record_bag', value=str(bag)),
                                                     Parameter('real_time_factor', value=0.0)])
    node.destroy_node()
    assert (bag / 'metadata.yaml').is_file()


def test_live_tiny_mass_is_rejected_and_a_reset_that_cannot_run_leaves_no_bag(
        tmp_path, harness, monkeypatch):
    bag = tmp_path / 'rec'
    node = harness.start(record_bag=str(bag), real_time_factor=0.0, duration=0.5)
    results = harness.set_remote('train_dynamics', {'coach_mass': 1e-300})
    assert not results[0].successful and 'coach_mass' in results[0].reason
    assert harness.set_remote('train_dynamics', {'num_coaches': 5})[0].successful
    monkeypatch.setattr(sim_node_mod, 'TrainSimulator', Broken)
    response = harness.reset()
    assert not response.success and 'nothing changed' in response.message
    assert not Path(f'{bag}_reset1').exists()
    assert node.simulator.n == 3 and node.bag_path == bag


# -- item 10: the recorder's backlog in bytes --------------------------------------------------
class SlowRecorder:
    """A BagRecorder stand-in whose disk is stuck until ``release`` is set."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.release = threading.Event()
        self.written = 0

    def add_topic(self, topic, msgtype):
        pass

    def write(self, topic, t_ns, data):
        self.release.wait()
        self.written += 1

    @property
    def saved(self):
        return self.written               # what the bag holds once closed

    def flush(self):
        pass

    def close(self):
        pass

    def abort(self):
        pass


class Log:

    def error(self, text):
        pass


def test_recorder_backlog_is_bounded_in_bytes_and_the_writer_waits(tmp_path, monkeypatch):
    monkeypatch.setattr(ros_recorder, 'MAX_RECORD_BACKLOG_BYTES', 4 << 20)
    rec = SlowRecorder(tmp_path)
    writer = ros_recorder.BagWriter(rec, Log(), 10.0)
    msg = bytes(1 << 20)                     # 1 MiB: far fewer than the message bound
    done = threading.Event()
    peak = []

    def produce():
        for k in range(20):
            writer.write('couplers', 'sensor_msgs/msg/JointState', k, msg)
            peak.append(writer.backlog_bytes)
        done.set()

    threading.Thread(target=produce, daemon=True).start()
    time.sleep(0.5)
    assert not done.is_set()                             # waiting: the disk is stuck
    assert writer.backlog_bytes <= 4 << 20 and writer.backlog <= 5
    rec.release.set()
    assert done.wait(10.0)
    writer.close()
    assert rec.written == 20 and max(peak) <= 4 << 20


# -- item 11: a publisher of the wrong type on an input topic ---------------------------------
STRING_PUBLISHER = r"""
import time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node('wrong_type_publisher')
pub = node.create_publisher(String, 'brake_pipe/pressure', 10)
end = time.monotonic() + 30.0
while time.monotonic() < end:
    pub.publish(String(data='5 bar'))
    time.sleep(0.05)
"""


def test_wrong_type_publisher_on_an_input_topic_is_reported_in_diagnostics(harness):
    from diagnostic_msgs.msg import DiagnosticArray

    diags = harness.collect(DiagnosticArray, '/diagnostics')
    harness.start(real_time_factor=1.0)
    # another process: one DDS participant cannot hold two types on one topic
    proc = subprocess.Popen([sys.executable, '-c', STRING_PUBLISHER])
    try:
        def reported():
            values = diag_values(diags, INPUT) if diags else None
            return values is not None and values.get('wrong_type') == '1'

        assert harness.wait(reported, timeout=20.0)
        values = diag_values(diags, INPUT)
        assert values['wrong_type_topics'] == '/brake_pipe/pressure (std_msgs/msg/String)'
        assert values['_level'] == 1
    finally:
        proc.kill()
        proc.wait()


# -- item 12: timers at shutdown ----------------------------------------------------------------
class FakeContext:

    def __init__(self) -> None:
        self.up = True

    def ok(self) -> bool:
        return self.up


class FakeNode:

    def __init__(self) -> None:
        self.context = FakeContext()


def test_timer_callbacks_are_quiet_when_the_context_goes_down_under_them():
    node = FakeNode()

    def callback():
        node.context.up = False             # a signal shuts the context down meanwhile
        raise RuntimeError("publisher's context is invalid")

    assert ros_executor.shutdown_safe(node, callback)() is None

    def failing():
        raise RuntimeError('a real bug')

    node.context.up = True
    assert ros_executor.shutdown_safe(node, callback)() is None

    def later():
        threading.Timer(0.05, lambda: setattr(node.context, 'up', False)).start()
        raise RuntimeError('Failed to publish log message to rosout')   # before ok() is False

    node.context.up = True
    assert ros_executor.shutdown_safe(node, later)() is None
    node.context.up = True
    with pytest.raises(RuntimeError, match='real bug'):
        ros_executor.shutdown_safe(node, failing)()


def test_sigint_during_the_run_never_reports_a_timer_exception(tmp_path):
    """
    SIGINT 0, 0.93, 1.0 and 2.02 s after the start, around the 1 Hz diagnostics: clean exits.

    The four nodes run at once (each under its own namespace), each signalled by its own
    thread that many seconds after its ``started:`` line.
    """
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    delays = (0.0, 0.93, 1.0, 2.02)
    procs = [subprocess.Popen(
        [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args', '-r',
         f'__ns:=/sigint{k}', '-p', 'real_time_factor:=1.0', '-p',
         f'record_bag:={tmp_path / f"b{k}"}'],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env, cwd=REPO)
        for k in range(len(delays))]
    outs = [''] * len(procs)

    def signal_after_start(k):
        proc, lines = procs[k], []
        for line in proc.stdout:
            lines.append(line)
            if 'started:' in line:
                break
        time.sleep(delays[k])
        proc.send_signal(signal.SIGINT)
        outs[k] = ''.join(lines) + proc.communicate(timeout=60)[0]

    threads = [threading.Thread(target=signal_after_start, args=(k,)) for k in range(len(procs))]
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join(timeout=180)
    finally:
        for proc in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    for proc, out in zip(procs, outs):
        assert 'started:' in out, out
        assert proc.returncode == 0, out
        assert 'Exception in' not in out and 'Traceback' not in out, out
