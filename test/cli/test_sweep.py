"""
``train-dynamics sweep`` on Dask: the plan, the clusters, resume, a killed worker.

A LocalCluster, a ``dask scheduler`` with two ``dask worker`` processes, resume after an
interruption, and a worker killed mid-sweep. Every table is compared with sequential runs
of the same cases: ``simulate`` + ``report`` (the commands a user would run by hand) for
the first, the case function in this process for the others.
"""
from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time

from distributed import Client
import numpy as np
import pandas as pd
import pytest
from train_dynamics.cli.offline import main
from train_dynamics.cli.sweep_case import run_case
from train_dynamics.cli.sweep_plan import make_plan
from train_dynamics.physics.metrics import FLAT_KEYS
import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
PAPER = os.path.join(ROOT, 'config', 'paper_3coach.yaml')
DASK = os.path.join(os.path.dirname(sys.executable), 'dask')

#: 2 models x 2 fault bounds x 2 buffer frictions from a seeded hypercube = 8 cases: the
#: 1e-5 m bound faults at once (error rows), a friction above the stiffness (2.8e6) is an
#: invalid combination (error row, not run)
SWEEP = {'duration': 6.0,
         'grid': {'model_type': ['sign', 'tanh'], 'max_coupler_displacement': [5.0, 1e-5]},
         'lhs': {'samples': 2, 'seed': 3, 'ranges': {'buffer_friction': [2.0e6, 3.4e6]}}}


def write_sweep(tmp_path, doc, name='sweep.yaml'):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return str(path)


def comparable(table: pd.DataFrame) -> pd.DataFrame:
    """Return the table without timings, sorted by case."""
    return table.drop(columns=['wall_s']).sort_values('case').reset_index(drop=True)


_REFERENCE_ROWS: dict = {}


def reference_rows(base, sweep_file):
    """
    Run the plan's cases one after the other in this process (the same case function).

    Once per module for a base file and sweep text (the resume and the killed-worker tests
    share SLOW's six 2.5 s cases); the plan is made from each test's own file.
    """
    plan = make_plan(base, sweep_file)
    key = (str(base), open(sweep_file).read())
    if key not in _REFERENCE_ROWS:
        _REFERENCE_ROWS[key] = {c.index: (c.error if c.error else
                                          run_case(c.index, c.params, plan.duration, c.inputs))
                                for c in plan.cases}
    return plan, _REFERENCE_ROWS[key]


def check_against(table, plan, rows):
    """Assert the table has every case once and the reference values."""
    assert list(table['case']) == list(range(len(plan.cases)))
    for c in plan.cases:
        got = table.iloc[c.index]
        ref = rows[c.index]
        for name, value in c.swept.items():
            assert got[name] == value
        if isinstance(ref, str):
            assert got['error'] == ref
            continue
        assert got['error'] == ref['error']
        for k in FLAT_KEYS:
            if ref[k] is None:
                assert pd.isna(got[k]), k
            else:
                assert got[k] == pytest.approx(ref[k], rel=1e-12), k


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def dask_cluster(n_workers=2):
    """Start ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1; yield (addr, ps)."""
    port = free_port()
    addr = f'tcp://127.0.0.1:{port}'
    procs = [subprocess.Popen([DASK, 'scheduler', '--host', '127.0.0.1', '--port', str(port),
                               '--no-dashboard'], stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)]
    try:
        for _ in range(n_workers):
            procs.append(subprocess.Popen(
                [DASK, 'worker', addr, '--nthreads', '1', '--no-nanny', '--no-dashboard',
                 '--host', '127.0.0.1', '--death-timeout', '60'],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        with Client(addr, timeout='60s') as client:
            client.wait_for_workers(n_workers, timeout=120)
        yield addr, procs
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


# -- the plan ------------------------------------------------------------------------------

@pytest.mark.parametrize('doc, message', [
    ({'grid': {'model_type': ['sign']}}, 'duration [s] is required'),
    ({'duration': 5, 'grid': {'no_such': [1.0]}}, "unknown parameter 'no_such'"),
    ({'duration': 5, 'grid': {'coach_mass': [-1.0]}}, 'coach_mass: must be >= 500'),
    ({'duration': 5, 'grid': {'model_type': ['cosh']}}, "'cosh' is not one of"),
    ({'duration': 5, 'lhs': {'samples': 4, 'ranges': {'coach_mass': [5e4, 4e4]}}},
     'must be < max'),
    ({'duration': 5, 'lhs': {'samples': 4, 'ranges': {'model_type': ['a', 'b']}}},
     'give it in grid'),
    ({'duration': 5, 'lhs': {'samples': 0, 'ranges': {'coach_mass': [4e4, 5e4]}}},
     'samples must be'),
    ({'duration': 5, 'grid': {'record_bag': ['x']}}, 'cannot be swept'),
    ({'duration': 5, 'grid': {'coach_mass': [4e4]}, 'extra': 1}, "unknown key 'extra'"),
    ({'duration': 5}, 'nothing to sweep'),
    ({'duration': 5, 'input': 'missing_bag', 'grid': {'coach_mass': [4e4]}},
     'input bag not found'),
])
def test_an_invalid_sweep_file_fails_before_any_case_runs(tmp_path, capsys, doc, message):
    out = tmp_path / 'out'
    code = main(['sweep', '--params', PAPER, '--sweep', write_sweep(tmp_path, doc),
                 '--output', str(out), '-q'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()


def test_the_plan_is_a_full_grid_times_a_seeded_latin_hypercube(tmp_path):
    doc = {'duration': 5.0, 'grid': {'model_type': ['sign', 'tanh']},
           'lhs': {'samples': 5, 'seed': 11, 'ranges': {
               'brake_propagation_speed': [100.0, 300.0],
               'scale_factor': {'min': 100.0, 'max': 1.0e4, 'log': True},
               'num_coaches': [3, 7]}}}
    a = make_plan(PAPER, write_sweep(tmp_path, doc))
    b = make_plan(PAPER, write_sweep(tmp_path, doc, 'again.yaml'))
    assert [c.swept for c in a.cases] == [c.swept for c in b.cases]
    assert a.digest == b.digest and len(a.cases) == 10
    assert [c.swept['model_type'] for c in a.cases] == ['sign'] * 5 + ['tanh'] * 5
    lhs = a.cases[:5]
    assert [c.swept['brake_propagation_speed'] for c in lhs] == [
        c.swept['brake_propagation_speed'] for c in a.cases[5:]]
    # Latin: each of the 5 equal strata of every range holds exactly one sample
    speeds = [c.swept['brake_propagation_speed'] for c in lhs]
    assert sorted(int((s - 100.0) / 40.0) for s in speeds) == [0, 1, 2, 3, 4]
    logs = [np.log10(c.swept['scale_factor']) for c in lhs]
    assert sorted(int((v - 2.0) / 0.4) for v in logs) == [0, 1, 2, 3, 4]
    assert all(isinstance(c.swept['num_coaches'], int) and 3 <= c.swept['num_coaches'] <= 7
               for c in lhs)
    doc['lhs']['seed'] = 12
    assert make_plan(PAPER, write_sweep(tmp_path, doc, 'c.yaml')).digest != a.digest


# -- LocalCluster and dask scheduler/workers --------------------------------------------

def simulate_and_report(tmp_path, plan, case):
    """Return the train metrics of ``simulate`` + ``report`` of one case, or None."""
    params = tmp_path / f'case{case.index}.yaml'
    valve = yaml.safe_load(open(PAPER))['/**/brake_valve']
    params.write_text(yaml.safe_dump({'train_dynamics': {'ros__parameters': case.params},
                                      'brake_valve': valve}))
    bag, rep = tmp_path / f'bag{case.index}', tmp_path / f'rep{case.index}'
    code = main(['simulate', '--params', str(params), '--duration', str(plan.duration),
                 '--output', str(bag), '-q'])
    if code != 0:
        return code
    assert main(['report', str(bag), '--output', str(rep), '--params', str(params),
                 '-q']) == 0
    return json.loads((rep / 'summary.json').read_text())['train']


def test_sweep_on_a_local_cluster_and_on_dask_workers_equals_sequential_runs(tmp_path):
    sweep = write_sweep(tmp_path, SWEEP)
    out = tmp_path / 'local'
    assert main(['sweep', '--params', PAPER, '--sweep', sweep, '--output', str(out),
                 '--workers', '2', '-q']) == 0
    table = pd.read_parquet(out / 'results.parquet')
    plan = make_plan(PAPER, sweep)
    assert len(table) == 8 and list(table['case']) == list(range(8))
    errors = dict(zip(table['case'], table['error']))
    for c in plan.cases:
        if c.error:                                   # invalid combination: not run
            assert 'buffer_friction must be < buffer_stiffness' in errors[c.index]
            assert 'buffer_friction must be < buffer_stiffness' in c.error
            continue
        seq = simulate_and_report(tmp_path, plan, c)
        if c.swept['max_coupler_displacement'] < 1e-3:  # the fault: simulate exits 3
            assert seq == 3
            assert errors[c.index].startswith('simulation fault')
            assert pd.isna(table.loc[c.index, 'max_compression'])
            continue
        assert errors[c.index] == ''
        row = table.loc[c.index]
        for k in FLAT_KEYS:
            if k.endswith('_every_step'):   # the simulator's envelope; a bag has only samples
                assert seq[k] is None
                sampled = seq[k.replace('_every_step', '')]
                assert sampled <= row[k] <= 1.05 * sampled, k   # paper: peaks 0.2 % apart
            elif seq[k] is None:
                assert pd.isna(row[k]), k
            else:
                assert row[k] == pytest.approx(seq[k], rel=1e-9, abs=1e-6), k
    assert (table['error'] == '').sum() == 2                 # 2 valid, 2 faults, 4 invalid
    assert table['error'].str.startswith('simulation fault').sum() == 2
    assert (out / 'figures' / 'max_compression__vs__buffer_friction.png').exists()
    assert (out / 'figures' / 'max_compression__vs__model_type.png').exists()

    # the same sweep through a dask scheduler and two dask worker processes
    out2 = tmp_path / 'remote'
    with dask_cluster(2) as (addr, _):
        assert main(['sweep', '--params', PAPER, '--sweep', sweep, '--output', str(out2),
                     '--scheduler', addr, '--keep-bags', '--no-figures', '-q']) == 0
    pd.testing.assert_frame_equal(comparable(pd.read_parquet(out2 / 'results.parquet')),
                                  comparable(table))
    good = int(table.index[table['error'] == ''][0])
    assert main(['report', str(out2 / 'bags' / f'case_{good:05d}'), '--output',
                 str(tmp_path / 'kept'), '-q']) == 0     # a kept bag reports on its own
    # rerun on a finished sweep: nothing to run, same table; another plan is refused
    assert main(['sweep', '--params', PAPER, '--sweep', sweep, '--output', str(out2),
                 '--no-figures', '-q']) == 0
    other = write_sweep(tmp_path, {**SWEEP, 'duration': 7.0}, 'other.yaml')
    assert main(['sweep', '--params', PAPER, '--sweep', other, '--output', str(out2),
                 '-q']) == 2


# -- robustness -----------------------------------------------------------------------

#: slow cases (0.1 ms steps: ~0.5 s each on a quiet 2-core machine, ~2.5 s loaded), so that a
#: case is running when the sweep is interrupted or its worker is killed
SLOW = {'duration': 40.0, 'grid': {'integration_step': [1e-4]},
        'lhs': {'samples': 6, 'seed': 5, 'ranges': {'brake_propagation_speed': [150.0, 300.0]}}}


def sweep_process(sweep, out, *extra):
    return subprocess.Popen([sys.executable, '-m', 'train_dynamics.cli.offline', 'sweep',
                             '--params', PAPER, '--sweep', sweep, '--output', str(out),
                             '--no-figures', '-q', *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def wait_for(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f'timed out waiting for {what}'
        time.sleep(0.05)


def case_files(out):
    folder = out / 'cases'
    return sorted(folder.glob('case_*.json')) if folder.exists() else []


def test_resume_after_an_interrupted_sweep_runs_only_the_missing_cases(tmp_path, capsys):
    sweep = write_sweep(tmp_path, SLOW)
    out = tmp_path / 'out'
    proc = sweep_process(sweep, out, '--workers', '1')
    try:
        wait_for(lambda: len(case_files(out)) >= 2, 240, 'two finished cases')
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert not (out / 'results.parquet').exists()
    before = {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in case_files(out)}
    assert 2 <= len(before) < 6
    assert main(['sweep', '--params', PAPER, '--sweep', sweep, '--output', str(out),
                 '--workers', '1', '--no-figures']) == 0
    summary = capsys.readouterr().out
    assert f'({6 - len(before)} run now, {len(before)} done before, 0 with errors)' in summary
    for p in case_files(out):
        if p.name in before:
            assert (p.stat().st_mtime_ns, p.read_bytes()) == before[p.name]
    plan, rows = reference_rows(PAPER, sweep)
    check_against(pd.read_parquet(out / 'results.parquet'), plan, rows)


def test_a_killed_worker_s_case_is_rescheduled(tmp_path):
    sweep = write_sweep(tmp_path, SLOW)
    out = tmp_path / 'out'
    with dask_cluster(2) as (addr, procs):
        with Client(addr, timeout='30s') as client:
            pids = client.run(os.getpid)
            proc = sweep_process(sweep, out, '--scheduler', addr)
            try:
                def busy():
                    return {w: keys for w, keys in client.processing().items() if keys}

                wait_for(lambda: len(case_files(out)) >= 1 and busy(), 240, 'a busy worker')
                victim, keys = next(iter(busy().items()))
                running = [k for k in keys if 'train-dynamics-case' in str(k)]
                os.kill(pids[victim], signal.SIGKILL)        # kill -9 mid-case
                _, err = proc.communicate(timeout=300)
            finally:
                if proc.poll() is None:
                    proc.kill()
        assert proc.returncode == 0, err
        assert sum(p.poll() is not None for p in procs[1:]) == 1     # one worker is dead
    assert running
    table = pd.read_parquet(out / 'results.parquet')
    assert not table['case'].duplicated().any() and len(table) == 6
    assert (table['error'] == '').all(), table['error'].tolist()
    plan, rows = reference_rows(PAPER, sweep)
    check_against(table, plan, rows)
