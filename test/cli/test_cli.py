"""The offline command: replay of brake inputs from bags, determinism, errors, compare."""
from __future__ import annotations

import io
import json
import math
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from train_dynamics.cli import offline as cli
from train_dynamics.cli.errors import EXIT_FAULT, EXIT_INTERRUPT, EXIT_TERMINATED
from train_dynamics.cli.progress import progress_bar
from train_dynamics.param_files import load_param_file
from train_dynamics.physics import train
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.recording import messages
from train_dynamics.recording.bags import bag_info, BagRecorder, read_topics
from train_dynamics.recording.plots import png_size, SIZE_PX
from train_dynamics.recording.sinks import BagSink
from train_dynamics.simulation import runner

ATM = 101325.0
REPO = Path(__file__).resolve().parents[2]
EPOCH_NS = 1_700_000_000_123_456_789       # the input bag's start: any absolute time

PARAMS = """\
train_dynamics:
  ros__parameters:
    num_coaches: {n}
    coach_mass: 45000.0
    initial_speed: 30.0
    brake_input: {mode}
    integration_step: 0.001
    publish_rate: 100.0
    model_type: tanh
    scale_factor: 1000.0
{extra}"""


def write_params(path: Path, n: int = 3, mode: str = 'cylinder_per_coach',
                 extra: str = '') -> Path:
    path.write_text(PARAMS.format(n=n, mode=mode, extra=extra))
    return path


def cylinder_curve(t: float, delay: float) -> float:
    """Return a known brake-cylinder filling [Pa gauge]: 3.8 bar, tau 1.2 s, from ``delay``."""
    return 0.0 if t < delay else 380000.0 * (1.0 - math.exp(-(t - delay) / 1.2))


def cylinder_bag(path: Path, n: int = 3, t_end: float = 3.0, dt: float = 0.02,
                 odd: float | None = 0.0105) -> list[tuple[int, int, float]]:
    """
    Write a bag with coach_<i>/brake_cylinder/pressure (absolute) every ``dt``.

    And one message at an off-grid time ``odd`` [s]; return the events (t_rel_ns, coach
    index, gauge).
    """
    events = []
    with BagRecorder(path) as rec:
        rec.write_msg('/unrelated/topic', EPOCH_NS, messages.fluid_pressure(0.0, ATM))  # bag start
        times = [k * dt for k in range(int(round(t_end / dt)) + 1)]
        if odd is not None:
            times = sorted(times + [odd])
        for t in times:
            t_ns = int(round(t * 1e9))
            for i in range(n):
                p = cylinder_curve(t, 0.1 * i)
                events.append((t_ns, i, p))
                rec.write_msg(f'/coach_{i + 1}/brake_cylinder/pressure', EPOCH_NS + t_ns,
                              messages.fluid_pressure(t, p + ATM))
    return events


def run(*args: str) -> int:
    return cli.main([str(a) for a in args])


def coupler_arrays(bag: Path):
    msgs = [m for _, _, m in read_topics(bag, ['couplers'])]
    t = np.array([messages.stamp_to_sec(m.header.stamp) for m in msgs])
    return t, np.array([m.position for m in msgs]), np.array([m.velocity for m in msgs]), \
        np.array([m.effort for m in msgs])


def test_replayed_cylinder_bag_gives_the_core_histories(tmp_path):
    params = write_params(tmp_path / 'p.yaml')
    events = cylinder_bag(tmp_path / 'in')
    assert run('simulate', '--params', params, '--input', tmp_path / 'in', '--duration', 2.5,
               '--output', tmp_path / 'out', '-q') == 0
    t, y, ydot, force = coupler_arrays(tmp_path / 'out')

    # the physics core driven directly: a message at bag time tau (relative to the bag's
    # first message) is held from tau itself (the step that spans tau is split there)
    sim = TrainSimulator(load_param_file(str(params)))
    for t_ns, i, p in events:
        sim.schedule(t_ns * 1e-9, lambda i=i, p=p: sim.set_cylinder_pressure(p, i))
    exp_t, exp_y, exp_v, exp_f, exp_cyl = [], [], [], [], []
    for k in range(2501):
        if k % 10 == 0:
            exp_t.append(sim.t)
            exp_y.append(sim.y)
            exp_v.append(sim.ydot)
            exp_f.append(sim.coupler_force)
            exp_cyl.append(sim.cylinder_pressure)
        if k < 2500:
            sim.advance(1)
    assert len(t) == 251
    np.testing.assert_allclose(t, exp_t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(y, exp_y, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(ydot, exp_v, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(force, exp_f, rtol=1e-9, atol=1e-6)
    # not a trivial history: the delayed brakes compress the buffers (F < 0)
    assert force.min() < -1000.0
    # outputs of the contract, and the inputs used, re-stamped from t = 0
    info = bag_info(tmp_path / 'out')
    assert info.topics['coaches'] == ('sensor_msgs/msg/JointState', 251)
    assert info.topics['brake_cylinders'] == ('sensor_msgs/msg/JointState', 251)
    # inputs up to the end of the run: 126 on the 20 ms grid (0..2.5 s) + the odd one
    assert info.topics['coach_2/brake_cylinder/pressure'][1] == 127
    assert 'unrelated/topic' not in info.topics
    cyl = [m for _, _, m in read_topics(tmp_path / 'out', ['brake_cylinders'])]
    assert list(cyl[-1].name) == ['coach_1', 'coach_2', 'coach_3']
    np.testing.assert_allclose([m.position for m in cyl], exp_cyl, rtol=1e-12)
    # the replayed curve arrives: coach 3's cylinder within 1 % of the input at t = 2.5 s
    assert cyl[-1].position[2] == pytest.approx(cylinder_curve(2.5, 0.2), rel=0.01)


def test_sqlite3_input_bag_and_namespace(tmp_path):
    params = write_params(tmp_path / 'p.yaml', n=2, mode='pipe_head')
    with Writer(tmp_path / 'in', version=9, storage_plugin=StoragePlugin.SQLITE3) as w:
        conn = w.add_connection('/train1/brake_pipe/pressure', 'sensor_msgs/msg/FluidPressure',
                                typestore=messages.typestore())
        for t, p in [(0.0, 500000.0), (0.5, 0.0)]:
            w.write(conn, EPOCH_NS + int(t * 1e9),
                    messages.serialize(messages.fluid_pressure(t, p + ATM)))
    assert run('simulate', '--params', params, '--input', tmp_path / 'in', '--namespace',
               '/train1', '--duration', 1.0, '--output', tmp_path / 'out', '-q') == 0
    msgs = list(read_topics(tmp_path / 'out', ['coaches', 'brake_pipe/pressure']))
    assert [m.fluid_pressure for tp, _, m in msgs if tp == 'brake_pipe/pressure'] == \
        [500000.0 + ATM, ATM]
    final = [m for tp, _, m in msgs if tp == 'coaches'][-1]
    assert final.effort[0] > 0.0                  # the vented pipe braked coach 1


def test_brake_valve_schedule_drives_the_head_and_is_recorded(tmp_path):
    params = write_params(tmp_path / 'p.yaml', mode='pipe_head', extra=(
        'brake_valve:\n  ros__parameters:\n    schedule: ["0.0:release", "0.5:emergency"]\n'))
    assert run('simulate', '--params', params, '--duration', 2.0, '--output',
               tmp_path / 'out', '-q') == 0
    head = [(n, m.fluid_pressure)
            for _, n, m in read_topics(tmp_path / 'out', ['brake_pipe/pressure'])]
    assert len(head) == 201
    p = dict(head)
    assert p[0] == pytest.approx(500000.0 + ATM)
    assert p[500_000_000] == pytest.approx(500000.0 + ATM)              # handle moves at 0.5 s
    assert p[1_000_000_000] == pytest.approx(300000.0 + ATM)            # 400 kPa/s vent
    assert p[2_000_000_000] == pytest.approx(ATM)
    coaches = [m for _, _, m in read_topics(tmp_path / 'out', ['coaches'])]
    assert coaches[-1].effort[0] > coaches[-1].effort[2] > 0.0         # brake wave front->rear
    assert bag_info(tmp_path / 'out').custom_data['model_type'] == 'tanh'


def test_same_inputs_give_byte_identical_bags(tmp_path):
    params = write_params(tmp_path / 'p.yaml')
    cylinder_bag(tmp_path / 'in', t_end=1.0)
    for d in ('a', 'b'):
        (tmp_path / d).mkdir()
        assert run('simulate', '--params', params, '--input', tmp_path / 'in', '--duration', 1.0,
                   '--output', tmp_path / d / 'out', '-q') == 0
    files_a = sorted(p.name for p in (tmp_path / 'a' / 'out').iterdir())
    assert files_a == ['metadata.yaml', 'out_0.mcap']
    for name in files_a:
        assert (tmp_path / 'a' / 'out' / name).read_bytes() == \
            (tmp_path / 'b' / 'out' / name).read_bytes()


def _damaged_bag(tmp_path: Path) -> Path:
    cylinder_bag(tmp_path / 'bad', t_end=0.2)
    mcap = next((tmp_path / 'bad').glob('*.mcap'))
    mcap.write_bytes(mcap.read_bytes()[:300])
    return tmp_path / 'bad'


def _bag_without_inputs(tmp_path: Path) -> Path:
    with BagRecorder(tmp_path / 'noin') as rec:
        rec.write_msg('couplers', 0, messages.joint_state(0.0, ['coupler_1'], [0.0], [0.0], [0.0]))
        rec.write_msg('coach_1/brake_pipe/pressure', 0, messages.fluid_pressure(0.0, 6e5))
    return tmp_path / 'noin'


def _params_unknown(tp: Path) -> Path:
    p = tp / 'u.yaml'
    p.write_text(PARAMS.format(n=3, mode='cylinder_per_coach', extra='') +
                 '    coupler_magic: 3.0\n')
    return p


def _params_invalid(tp: Path) -> Path:
    p = tp / 'v.yaml'
    p.write_text(PARAMS.format(n=1, mode='cylinder_per_coach', extra=''))
    return p


def _params_malformed(tp: Path) -> Path:
    p = tp / 'm.yaml'
    p.write_text('train_dynamics: {ros__parameters: [\n')
    return p


def _params_bad_valve(tp: Path) -> Path:
    p = tp / 'bv.yaml'
    p.write_text(PARAMS.format(n=3, mode='pipe_head', extra='brake_valve:\n  ros__parameters:\n'
                               '    schedule: ["1.0:brake_hard"]\n'))
    return p


@pytest.mark.parametrize('case', [
    'missing bag', 'corrupt bag', 'no usable topic', 'not a bag', 'wrong mode for the bag',
    'unknown parameter', 'invalid parameter', 'malformed params', 'missing params',
    'bad brake_valve section', 'cylinder mode without bag', 'duration zero',
    'duration negative', 'duration nan', 'output exists'])
def test_bad_inputs_give_one_line_error_and_leave_nothing(tmp_path, capsys, case):
    work = tmp_path / 'work'
    work.mkdir()
    params = write_params(work / 'p.yaml')
    cylinder_bag(work / 'in', t_end=0.2)
    args = {'--params': params, '--input': work / 'in', '--duration': '1.0'}
    expect = None
    if case == 'missing bag':
        args['--input'], expect = work / 'nope', 'bag not found'
    elif case == 'corrupt bag':
        args['--input'], expect = _damaged_bag(work), 'cannot read bag'
    elif case == 'no usable topic':
        args['--input'], expect = _bag_without_inputs(work), 'no usable input topic'
    elif case == 'not a bag':
        (work / 'plain').mkdir()
        args['--input'], expect = work / 'plain', 'not a rosbag2 bag'
    elif case == 'wrong mode for the bag':
        args['--params'] = write_params(work / 'q.yaml', mode='pipe_per_coach')
        expect = 'no usable input topic'
    elif case == 'unknown parameter':
        args['--params'], expect = _params_unknown(work), 'coupler_magic'
    elif case == 'invalid parameter':
        args['--params'], expect = _params_invalid(work), 'num_coaches'
    elif case == 'malformed params':
        args['--params'], expect = _params_malformed(work), 'm.yaml'
    elif case == 'missing params':
        args['--params'], expect = work / 'none.yaml', 'not found'
    elif case == 'bad brake_valve section':
        args['--params'], expect = _params_bad_valve(work), 'brake_hard'
        del args['--input']
    elif case == 'cylinder mode without bag':
        del args['--input']
        expect = 'needs --input'
    elif case.startswith('duration'):
        args['--duration'] = {'duration zero': '0', 'duration negative': '-2',
                              'duration nan': 'nan'}[case]
        expect = '--duration'
    elif case == 'output exists':
        (tmp_path / 'out').mkdir()
        (tmp_path / 'out' / 'keep.txt').write_text('mine')
        expect = 'exists'
    before = sorted(p.name for p in tmp_path.iterdir())
    argv = ['simulate', '--output', str(tmp_path / 'out'), '-q']
    for k, v in args.items():
        argv += [k, str(v)]
    capsys.readouterr()
    code = cli.main(argv)
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    errors = [line for line in err if line.startswith('train-dynamics: error: ')]
    assert len(errors) == 1, err
    assert expect in errors[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before     # nothing new
    if case == 'output exists':
        assert [p.name for p in (tmp_path / 'out').iterdir()] == ['keep.txt']


def test_interrupt_removes_the_partial_output(tmp_path, monkeypatch):
    params = write_params(tmp_path / 'p.yaml')
    cylinder_bag(tmp_path / 'in', t_end=1.0)
    calls = []
    original = BagSink.sample

    def sample(self, s):
        calls.append(s.t)
        if len(calls) == 50:
            raise KeyboardInterrupt
        original(self, s)

    monkeypatch.setattr(BagSink, 'sample', sample)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert run('simulate', '--params', params, '--input', tmp_path / 'in', '--duration', 1.0,
               '--output', tmp_path / 'out', '-q') == EXIT_INTERRUPT
    assert len(calls) == 50
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_python_dash_m_and_help(tmp_path):
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get('PYTHONPATH', '')]))
    proc = subprocess.run([sys.executable, '-m', 'train_dynamics.cli.offline', 'simulate',
                           '--params', str(tmp_path / 'nope.yaml'), '--duration', '1', '--output',
                           str(tmp_path / 'o')], capture_output=True, text=True, env=env,
                          timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f'train-dynamics: error: parameter file not found: ' \
        f'{tmp_path / "nope.yaml"}'
    assert not (tmp_path / 'o').exists()
    assert cli.main(['--help']) == 0
    assert cli.main(['simulate']) == 2                      # missing required options


#: what ``simulate`` does not use: importing any of it costs start-up time (matplotlib alone
#: ~0.3 s, dask and pandas ~2 s), so neither its argument parsing nor its run may load it;
#: a run without an input bag reads no bag (``rosbags.highlevel``), one without a terminal
#: shows no progress bar (``tqdm``)
NOT_FOR_SIMULATE = ('matplotlib', 'dask', 'distributed', 'pandas', 'rclpy',
                    'train_dynamics.ros', 'train_dynamics.recording.plots',
                    'train_dynamics.recording.metrics_report', 'train_dynamics.cli.compare',
                    'train_dynamics.cli.plot', 'train_dynamics.cli.report',
                    'train_dynamics.cli.sweep', 'rosbags.highlevel', 'tqdm')

#: run in a fresh interpreter: parse a command line, then run it; print the modules loaded
#: after each as JSON
_MODULES_OF_A_RUN = """
import json, sys
from train_dynamics.cli import offline
argv = sys.argv[1:]
offline.build_parser(offline.command_of(argv)).parse_args(argv)
parsed = sorted(sys.modules)
code = offline.main(argv)
print(json.dumps({'code': code, 'parsed': parsed, 'ran': sorted(sys.modules)}))
"""


def test_simulate_imports_only_what_it_uses(tmp_path):
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get('PYTHONPATH', '')]))
    proc = subprocess.run([sys.executable, '-c', _MODULES_OF_A_RUN, 'simulate', '--params',
                           str(REPO / 'config' / 'paper_3coach.yaml'), '--duration', '0.05',
                           '--output', str(tmp_path / 'o'), '-q'],
                          capture_output=True, text=True, env=env, timeout=600)
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stdout.strip().splitlines()[-1])
    assert seen['code'] == 0 and (tmp_path / 'o' / 'metadata.yaml').exists()
    assert 'train_dynamics.cli.simulate' in seen['parsed']      # the parse did load simulate
    for stage in ('parsed', 'ran'):
        unused = [m for m in seen[stage] if any(m == n or m.startswith(n + '.')
                                                for n in NOT_FOR_SIMULATE)]
        assert unused == [], f'{stage}: {unused}'


def test_output_steps_and_input_steps():
    assert runner.output_steps(1.0, 100.0, 0.001) == list(range(0, 1001, 10))
    assert runner.output_steps(0.05, 30.0, 0.001) == [0, 33]           # nearest step
    assert runner.step_of(0, 0.001) == 0
    assert runner.step_of(1_000_000, 0.001) == 1                       # exactly on a step
    assert runner.step_of(1_000_001, 0.001) == 2                       # just after: next step
    assert runner.step_of(10_500_000, 0.001) == 11


def test_compare_prints_table_and_writes_figures(tmp_path, capsys):
    params = write_params(tmp_path / 'p.yaml', n=3, mode='pipe_head', extra=(
        'brake_valve:\n  ros__parameters:\n    schedule: ["0.2:emergency"]\n'))
    assert run('compare', '--params', params, '--duration', 1.2, '--output', tmp_path / 'cmp',
               '--scale-factors', '100,10000', '--steps', '0.001,0.0002', '-q') == 0
    out = capsys.readouterr().out.splitlines()
    rows = [line.split() for line in out[1:] if line.strip()]
    assert len(rows) == 4 * 2                                # 4 runs x 2 couplers
    labels = {' '.join(r[:-5]) for r in rows}
    assert labels == {'sign, h = 1 ms', 'sign, h = 0.2 ms', 'tanh, u = 100 s/m, h = 1 ms',
                      'tanh, u = 10000 s/m, h = 1 ms'}
    flips = {(' '.join(r[:-5]), r[-5]): float(r[-2]) for r in rows}
    # the sign model chatters, and more so with the smaller step; tanh does not
    assert flips[('sign, h = 0.2 ms', 'coupler_2')] > flips[('sign, h = 1 ms', 'coupler_2')]
    assert flips[('sign, h = 1 ms', 'coupler_2')] > 2 * flips[('tanh, u = 10000 s/m, h = 1 ms',
                                                               'coupler_2')]
    for name, kind in [('compare_displacement', 'compare'), ('compare_velocity', 'compare'),
                       ('compare_force', 'compare'), ('compare_zoom', 'zoom')]:
        assert png_size(tmp_path / 'cmp' / f'{name}.png') == SIZE_PX[kind]


def test_sigterm_cleans_up_and_stale_partials_are_removed(tmp_path):
    params = write_params(tmp_path / 'p.yaml', mode='pipe_head')
    # leftovers of a writer killed with SIGKILL (pid 2^22 + 1 > pid_max: not running)
    stale = tmp_path / f'.out.partial-{2 ** 22 + 1}'
    stale.mkdir()
    env = dict(os.environ,
               PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get('PYTHONPATH', '')]))
    # 30000 s: runs until the signal, and its bag estimate stays under the large-bag guard
    proc = subprocess.Popen([sys.executable, '-m', 'train_dynamics.cli.offline', 'simulate',
                             '--params', str(params), '--duration', '30000', '--output',
                             str(tmp_path / 'out'), '-q'], env=env, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob(f'.out.partial-{proc.pid}/.staging')):
            assert time.monotonic() < deadline and proc.poll() is None
            time.sleep(0.05)
        assert not stale.exists()               # removed by the new writer
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(30) == EXIT_TERMINATED
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert 'terminated' in proc.stderr.read()
    # the samples so far are kept, as a closed bag; no partial directory is left
    assert sorted(p.name for p in tmp_path.iterdir()) == ['out', 'p.yaml']
    assert bag_info(tmp_path / 'out').custom_data['interrupted'].startswith('SIGTERM')


def test_simulation_fault_keeps_the_valid_bag_and_exits_3(tmp_path, monkeypatch, capsys):
    original = train.TrainSimulator.advance

    def advance(self, n_steps):
        if self.t >= 0.5:                     # a diverging state, as the integrator reports it
            self.fault = f'coupler displacement out of range at t = {self.t:.3f} s'
            return 0
        return original(self, n_steps)

    monkeypatch.setattr(train.TrainSimulator, 'advance', advance)
    params = write_params(tmp_path / 'p.yaml', mode='pipe_head')
    assert run('simulate', '--params', params, '--duration', 2.0, '--output', tmp_path / 'out',
               '-q') == EXIT_FAULT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'simulation fault' in err[0] and 'out of range' in err[0]
    t, y, _, _ = coupler_arrays(tmp_path / 'out')
    assert t[-1] == pytest.approx(0.5) and len(t) == 51


def test_input_bag_warnings_name_ignored_topics_and_missing_coaches(tmp_path, capsys):
    params = write_params(tmp_path / 'p.yaml')
    with BagRecorder(tmp_path / 'in') as rec:
        for topic in ('coach_1/brake_cylinder/pressure', 'coach_5/brake_cylinder/pressure'):
            rec.write_msg(topic, EPOCH_NS, messages.fluid_pressure(0.0, 3e5 + ATM))
        rec.write_msg('coach_1/brake_cylinder/pressure', EPOCH_NS + 1000,
                      messages.fluid_pressure(0.0, -1.0))
    capsys.readouterr()
    assert run('simulate', '--params', params, '--input', tmp_path / 'in', '--duration', 0.1,
               '--output', tmp_path / 'out', '-q') == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert all(line.startswith('train-dynamics: warning: input bag: ') for line in err), err
    assert len(err) == 3
    assert 'coach_5/brake_cylinder/pressure names coach 5' in err[0]
    assert 'no input for coach(es) 2-3; held at 0 Pa' in err[1]
    assert '1 message(s) with a non-finite or negative absolute pressure rejected' in err[2]


class _Terminal(io.StringIO):

    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize('quiet, terminal', [(False, True), (True, True), (False, False)])
def test_progress_bar_only_on_a_terminal_without_quiet(monkeypatch, quiet, terminal):
    stream = _Terminal() if terminal else io.StringIO()
    monkeypatch.setattr(sys, 'stderr', stream)
    show = progress_bar('simulate', 60.0, quiet)
    for k in range(11):
        show(k / 10)
    text = stream.getvalue()
    if quiet or not terminal:
        assert text == ''
    else:
        last = text.split('\r')[-1]
        assert last.startswith('simulate [' + '#' * 30 + '] 100.0 % t =   60.00/60 s')
        assert text.endswith('\n') and text.count('\n') == 1
