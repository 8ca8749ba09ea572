"""
``train-dynamics sweep`` under hostile input: sizes, paths, identity, numbers, the scheduler.

Every refusal is one line on stderr and exit 2, before anything that grows with the input is
built; the runs use the real Dask engine (a LocalCluster on 127.0.0.1), kept short.
"""
from __future__ import annotations

import os
from pathlib import Path
import socket
import time
import urllib.error
import urllib.request

import pandas as pd
import pytest

from train_dynamics.cli import sweep_plan, sweep_run
from train_dynamics.cli.offline import build_parser, main
from train_dynamics.cli.sweep_plan import make_plan, MAX_CASES

ROOT = Path(__file__).resolve().parents[2]
PAPER = str(ROOT / 'config' / 'paper_3coach.yaml')


def write(path: Path, text: str) -> str:
    path.write_text(text)
    return str(path)


def one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    lines = [x for x in err.splitlines() if not x.startswith('usage:')]
    assert len(lines) == 1, err
    assert len(lines[0]) < 400, lines[0]
    return lines[0]


def sweep(*args) -> int:
    return main(['sweep', '--params', PAPER, '--no-figures', '-q', *map(str, args)])


def test_sweep_grid_too_large_refused_before_allocation(tmp_path, capsys):
    """12 axes of 10 values in a small file: 1e12 cases, refused at once (was MemoryError)."""
    axes = '\n'.join(f'  {name}: [{", ".join(str(v + k) for k in range(10))}]' for name, v in (
        ('coach_mass', 40000.0), ('scale_factor', 100.0), ('brake_propagation_speed', 200.0),
        ('buffer_stiffness', 2.8e6), ('buffer_friction', 1.0e6), ('draw_gear_stiffness', 5e6),
        ('draw_gear_friction', 2e6), ('initial_speed', 30.0), ('coach_length', 20.0),
        ('adhesion_coefficient', 0.1), ('gravity', 9.8), ('max_cylinder_pressure', 3e5)))
    path = write(tmp_path / 'huge.yaml', f'duration: 1.0\ngrid:\n{axes}\n')
    assert os.path.getsize(path) < 4096
    t0 = time.process_time()             # CPU s: the work, not the machine's load
    assert sweep('--sweep', path, '--output', tmp_path / 'out') == 2
    assert time.process_time() - t0 < 5.0
    line = one_line_error(capsys)
    assert f'1000000000000 cases (10 x 10 x 10 x 10 x 10 x 10 x 10 x 10 x 10 x 10 x 10 x ' \
           f'10), more than {MAX_CASES}' in line
    assert not (tmp_path / 'out').exists()


def test_sweep_grid_times_lhs_counted_before_sampling(tmp_path, capsys, monkeypatch):
    """1000 grid points x 1000 samples: refused before the hypercube is drawn."""
    monkeypatch.setattr(sweep_plan, 'lhs_points', lambda *a: pytest.fail('sampled'))
    values = ', '.join(str(100.0 + k) for k in range(1000))
    path = write(tmp_path / 's.yaml', f'duration: 1.0\ngrid:\n  scale_factor: [{values}]\n'
                 'lhs: {samples: 1000, ranges: {coach_mass: [40000.0, 50000.0]}}\n')
    assert sweep('--sweep', path, '--output', tmp_path / 'out') == 2
    assert f'1000000 cases (1000 x 1000), more than {MAX_CASES}' in one_line_error(capsys)


def test_sweep_plan_checks_every_case_and_shares_one_base(tmp_path):
    """
    A sweep plan holds each case's swept values over one shared base dict (built on demand).

    500 cases (10 grid values x 50 samples): every case is checked, none carries a copy of
    the base parameters. What planning the largest sweep allowed (MAX_CASES) costs in time
    and memory is measured by bench/sweep_plan_cost.py (make bench).
    """
    path = write(tmp_path / 's.yaml', 'duration: 1.0\ngrid:\n'
                 f'  scale_factor: [{", ".join(str(100.0 + k) for k in range(10))}]\n'
                 'lhs: {samples: 50, ranges: {coach_mass: [4.0e4, 5.0e4]}}\n')
    plan = make_plan(PAPER, path)
    assert len(plan.cases) == 500 <= MAX_CASES
    base = plan.cases[0].base
    assert base['num_coaches'] == 3 and 'scale_factor' in base
    assert all(c.base is base and c.error == '' for c in plan.cases)
    assert all(set(c.swept) == {'scale_factor', 'coach_mass'} for c in plan.cases)
    last = plan.cases[-1].params                       # built when asked for
    assert last['scale_factor'] == 109.0 and 4.0e4 <= last['coach_mass'] <= 5.0e4
    assert last['num_coaches'] == 3 and last is not base


def test_sweep_workers_bounded(tmp_path, capsys):
    """--workers 1000 is refused at once (was 130 processes and 9.2 GB after 60 s)."""
    path = write(tmp_path / 's.yaml', 'duration: 1.0\ngrid: {coach_mass: [4.0e4]}\n')
    n, _ = sweep_run.max_workers()
    t0 = time.process_time()
    assert sweep('--sweep', path, '--output', tmp_path / 'out', '--workers', 1000) == 2
    assert time.process_time() - t0 < 5.0
    line = one_line_error(capsys)
    assert f'--workers 1000: at most {n} on this machine' in line
    assert n <= sweep_run.WORKERS_PER_CORE * (os.cpu_count() or 1)
    assert not (tmp_path / 'out').exists()


CONSIST = 'vehicles:\n  - {type: passenger_coach, count: %d}\n'


def test_sweep_consist_file_relative_to_the_sweep_file(tmp_path, monkeypatch):
    """A grid consist_file is found next to the sweep file, whatever the current directory."""
    study = tmp_path / 'study'
    study.mkdir()
    write(study / 'my_three.yaml', CONSIST % 3)
    write(study / 'my_four.yaml', CONSIST % 4)
    path = write(study / 's.yaml', 'duration: 0.3\n'
                 'grid: {consist_file: [my_three.yaml, my_four.yaml]}\n')
    elsewhere = tmp_path / 'elsewhere'
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    plan = make_plan(PAPER, path)
    assert [c.error for c in plan.cases] == ['', '']
    assert [c.params['consist_file'] for c in plan.cases] == [
        str(study / 'my_three.yaml'), str(study / 'my_four.yaml')]
    out = tmp_path / 'out'
    assert sweep('--sweep', path, '--output', out, '--workers', 1) == 0
    table = pd.read_parquet(out / 'results.parquet')
    assert list(table['error']) == ['', '']
    assert list(table['consist_file']) == ['my_three.yaml', 'my_four.yaml']   # as written
    assert list(table['max_deceleration_vehicle'] <= [3, 4]) == [True, True]


def test_sweep_missing_consist_file_refused(tmp_path, capsys):
    path = write(tmp_path / 's.yaml', 'duration: 0.3\ngrid: {consist_file: [no_such.yaml]}\n')
    assert sweep('--sweep', path, '--output', tmp_path / 'out') == 2
    line = one_line_error(capsys)
    assert "grid: consist_file: 'no_such.yaml' not found" in line and str(tmp_path) in line


def test_sweep_every_case_failing_exits_nonzero(tmp_path, capsys):
    """Every case an invalid combination: the table is written, exit 2 (invalid parameters)."""
    path = write(tmp_path / 's.yaml', 'duration: 0.3\n'
                 'grid: {buffer_friction: [3.0e6, 3.5e6]}\n')      # >= buffer_stiffness
    out = tmp_path / 'out'
    assert sweep('--sweep', path, '--output', out) == 2
    line = one_line_error(capsys)
    assert 'every case failed (2)' in line and 'buffer_friction must be <' in line
    assert len(pd.read_parquet(out / 'results.parquet')) == 2


def test_sweep_resume_identifies_consist_by_content(tmp_path):
    """Editing a consist file (same path) makes another sweep; touching it does not."""
    consist = tmp_path / 'my_train.yaml'
    write(consist, CONSIST % 3)
    base = write(tmp_path / 'base.yaml', 'train_dynamics:\n  ros__parameters:\n'
                 '    consist_file: my_train.yaml\n')
    path = write(tmp_path / 's.yaml', 'duration: 0.3\n'
                 'grid: {scale_factor: [100.0, 1000.0], consist_file: ["", my_train.yaml]}\n')
    first = make_plan(base, path).digest
    os.utime(consist, (1, 1))
    assert make_plan(base, path).digest == first            # same content: same sweep
    write(consist, CONSIST % 30)
    assert make_plan(base, path).digest != first            # was equal: mixed tables


def test_sweep_resume_refuses_an_edited_consist(tmp_path, capsys):
    consist = tmp_path / 'my_train.yaml'
    write(consist, CONSIST % 3)
    path = write(tmp_path / 's.yaml', 'duration: 0.3\ngrid: {consist_file: [my_train.yaml]}\n')
    out = tmp_path / 'out'
    assert sweep('--sweep', path, '--output', out, '--workers', 1) == 0
    write(consist, CONSIST % 30)
    capsys.readouterr()
    assert sweep('--sweep', path, '--output', out, '--workers', 1) == 2
    assert 'holds another sweep' in one_line_error(capsys)


def test_sweep_yaml12_numbers_are_floats(tmp_path):
    """1.0e6 and 4.5e4 (no dot) are numbers, as in parameter files (were strings: YAML 1.1)."""
    path = write(tmp_path / 's.yaml', 'duration: 1.0e0\n'
                 'grid: {buffer_friction: [1.0e6, 1.2e+6], coach_mass: [45e3]}\n'
                 'lhs: {samples: 2, ranges: {scale_factor: [1e2, 1e4]}}\n')
    plan = make_plan(PAPER, path)
    assert plan.duration == 1.0
    assert [c.swept['buffer_friction'] for c in plan.cases] == [1.0e6, 1.0e6, 1.2e6, 1.2e6]
    assert {c.swept['coach_mass'] for c in plan.cases} == {45000.0}
    assert all(not c.error for c in plan.cases)


def test_sweep_duration_inf_names_the_sweep_file_field(tmp_path, capsys):
    for text in ('.inf', '-1.0', '.nan'):
        path = write(tmp_path / 's.yaml', f'duration: {text}\ngrid: {{coach_mass: [4.0e4]}}\n')
        assert sweep('--sweep', path, '--output', tmp_path / 'out') == 2
        line = one_line_error(capsys)
        assert f'sweep file {path}: duration: must be a finite number > 0 s' in line, line
        assert '--duration' not in line


def bomb(levels: int = 9) -> str:
    """Return a YAML alias bomb, inline: 9^levels leaves in a few hundred bytes."""
    text = '&l0 [x, x, x, x, x, x, x, x, x]'
    for k in range(1, levels):
        text = f'&l{k} [{text}' + f', *l{k - 1}' * 8 + ']'
    return text


@pytest.mark.parametrize('where', [
    'duration: BOMB\ngrid: {coach_mass: [4.0e4]}',
    'duration: 1.0\ngrid: {coach_mass: [BOMB]}',
    'duration: 1.0\ngrid: {coach_mass: BOMB}',
    'duration: 1.0\nlhs: {samples: BOMB, ranges: {coach_mass: [4.0e4, 5.0e4]}}',
    'duration: 1.0\nlhs: {samples: 2, seed: BOMB, ranges: {coach_mass: [4.0e4, 5.0e4]}}',
    'duration: 1.0\nlhs: {samples: 2, ranges: {coach_mass: [BOMB, 5.0e4]}}',
])
def test_sweep_error_quotes_a_bounded_prefix(tmp_path, capsys, where):
    """A YAML alias bomb (9^9 leaves in ~500 bytes) in a checked value: one short line."""
    path = write(tmp_path / 's.yaml', where.replace('BOMB', bomb()) + '\n')
    assert os.path.getsize(path) < 1000
    t0 = time.process_time()
    assert sweep('--sweep', path, '--output', tmp_path / 'out') == 2
    assert time.process_time() - t0 < 10.0
    one_line_error(capsys)


def test_sweep_dead_scheduler_fails_fast(tmp_path, capsys):
    path = write(tmp_path / 's.yaml', 'duration: 1.0\ngrid: {coach_mass: [4.0e4]}\n')
    with socket.socket() as s:              # a free port: nothing listens there
        s.bind(('127.0.0.1', 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    assert sweep('--sweep', path, '--output', tmp_path / 'out', '--scheduler',
                 f'tcp://127.0.0.1:{port}') == 2
    assert time.monotonic() - t0 < 5.0                 # was 23.6 s
    line = one_line_error(capsys)
    assert 'cannot reach the Dask scheduler at ' in line and 'refused' in line, line
    t0 = time.monotonic()
    assert sweep('--sweep', path, '--output', tmp_path / 'out', '--scheduler',
                 'tcp://127.0.0.1:99999') == 2
    assert time.monotonic() - t0 < 5.0
    line = one_line_error(capsys)
    assert 'bad address, port 99999 is not in 1..65535' in line and 'timed out' not in line
    assert not (tmp_path / 'out').exists()


def test_sweep_dask_dashboard_off():
    """The LocalCluster serves no dashboard and no route, and never listens on 8787."""
    args = build_parser().parse_args(['sweep', '--params', PAPER, '--sweep', 'x', '--output',
                                      'y', '--workers', '1'])
    with sweep_run.cluster_client(args) as client:
        scheduler = client.cluster.scheduler
        ports = {s.getsockname()[1] for s in scheduler.http_server._sockets.values()}
        hosts = {s.getsockname()[0] for s in scheduler.http_server._sockets.values()}
        assert 8787 not in ports and hosts == {'127.0.0.1'}, (ports, hosts)
        for route in ('status', 'health', 'info/main/workers.html', 'metrics'):
            with pytest.raises(urllib.error.HTTPError) as err:
                urllib.request.urlopen(f'http://127.0.0.1:{min(ports)}/{route}', timeout=5)
            assert err.value.code == 404
