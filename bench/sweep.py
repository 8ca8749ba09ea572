"""
The sweep benchmark: cases per minute on 1 and 2 Dask workers, and the per-case overhead.

- Throughput: the same 12 cases (100 coaches, 60 s, tanh u = 1000, brake propagation speed
  from a Latin hypercube) through ``sweep_run.execute`` on a ``LocalCluster`` of 1 and of 2
  worker processes (one thread each), after a warm-up case per worker (numba's cached
  kernels load once per process); cluster start-up is timed apart. Speed-up = 2-worker /
  1-worker cases per minute (target >= 1.7 on this 2-core machine).
- Per-case overhead: the wall time per case of that 1-worker sweep against a bare
  ``train-dynamics simulate`` call of the same case (in-process, median of 3; it writes the
  bag, the sweep case computes the metrics instead), target <= 5 %; and, for what the
  metrics themselves cost, against ``run_simulation`` with no sink at all.

``python bench/sweep.py`` writes ``bench/results/sweep_results.md`` and its section of
``bench/RESULTS.md``; ``bench/run_all.py`` (``make bench``) runs it too.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
from pathlib import Path
import shutil
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

from distributed import Client, LocalCluster  # noqa: E402
from results_md import saved_section, splice_section  # noqa: E402
from train_dynamics import topics  # noqa: E402
from train_dynamics.cli.offline import main as cli_main  # noqa: E402
from train_dynamics.cli.sweep_case import run_case  # noqa: E402
from train_dynamics.cli.sweep_plan import make_plan  # noqa: E402
from train_dynamics.cli.sweep_run import execute, prepare_output  # noqa: E402
from train_dynamics.physics.config import SimConfig  # noqa: E402
from train_dynamics.simulation.runner import run_simulation  # noqa: E402
import yaml  # noqa: E402

RESULTS = os.path.join(HERE, 'RESULTS.md')
SWEEP_MD = os.path.join(HERE, 'results', 'sweep_results.md')
SWEEP_JSON = os.path.join(HERE, 'results', 'sweep_last.json')
SWEEP_BEGIN = '<!-- sweep:begin (written by bench/sweep.py) -->'
SWEEP_END = '<!-- sweep:end -->'
PAPER = os.path.join(os.path.dirname(HERE), 'config', 'paper_3coach.yaml')
N_CASES = 12


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def _files(tmp: str) -> tuple[str, str]:
    doc = yaml.safe_load(open(PAPER))
    doc['/**/train_dynamics']['ros__parameters']['num_coaches'] = 100
    base = os.path.join(tmp, 'base100.yaml')
    with open(base, 'w') as fh:
        yaml.safe_dump(doc, fh)
    sweep = os.path.join(tmp, 'sweep.yaml')
    with open(sweep, 'w') as fh:
        yaml.safe_dump({'duration': 60.0, 'lhs': {'samples': N_CASES, 'seed': 1, 'ranges': {
            'brake_propagation_speed': [200.0, 300.0]}}}, fh)
    return base, sweep


def throughput(base: str, sweep: str, workers: int, tmp: str) -> dict:
    """Run the cases on a LocalCluster of ``workers`` processes; return the timings."""
    plan = make_plan(base, sweep)
    out = os.path.join(tmp, f'out{workers}')
    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=logging.ERROR)
    client = Client(cluster)
    try:
        startup = time.perf_counter() - t0
        warm = [client.submit(run_case, -1, plan.cases[0].params, 1.0, plan.cases[0].inputs,
                              None, pure=False, workers=[w])
                for w in client.scheduler_info()['workers']]
        client.gather(warm)
        prepare_output(Path(out), plan)
        args = argparse.Namespace(keep_bags=False, quiet=True)
        t1 = time.perf_counter()
        execute(client, plan, plan.cases, Path(out), args)
        wall = time.perf_counter() - t1
    finally:
        client.close()
        cluster.close()
    walls = []
    for c in plan.cases:
        with open(os.path.join(out, 'cases', f'case_{c.index:05d}.json')) as fh:
            walls.append(json.load(fh)['row']['wall_s'])
    return {'workers': workers, 'cases': len(plan.cases), 'wall_s': wall,
            'cases_per_min': 60.0 * len(plan.cases) / wall, 'startup_s': startup,
            'per_case_s': wall * workers / len(plan.cases),
            'case_wall_in_worker_s': statistics.median(walls)}


def bare(base: str, sweep: str, tmp: str) -> dict:
    """Time ``simulate`` (in-process, median of 3) and ``run_simulation`` without a sink."""
    plan = make_plan(base, sweep)
    c = plan.cases[0]
    params = os.path.join(tmp, 'case0.yaml')
    doc = yaml.safe_load(open(base))
    doc['/**/train_dynamics']['ros__parameters'] = c.params
    with open(params, 'w') as fh:
        yaml.safe_dump(doc, fh)
    sims = []
    for k in range(3):
        bag = os.path.join(tmp, f'bag{k}')
        t0 = time.perf_counter()
        assert cli_main(['simulate', '--params', params, '--duration', '60', '--output', bag,
                         '-q']) == 0
        sims.append(time.perf_counter() - t0)
        shutil.rmtree(bag)
    cfg = SimConfig.from_dict(c.params)
    loops, cases = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        run_simulation(cfg, 60.0, c.inputs, on_sample=lambda s: None)
        loops.append(time.perf_counter() - t0)
        cases.append(run_case(0, c.params, 60.0, c.inputs)['wall_s'])
    assert c.inputs.mode == topics.PIPE_HEAD
    return {'simulate_s': statistics.median(sims), 'run_loop_s': statistics.median(loops),
            'case_in_process_s': statistics.median(cases)}


def run(log=log) -> dict:
    tmp = tempfile.mkdtemp(prefix='td_sweep_bench_')
    try:
        base, sweep = _files(tmp)
        log('sweep: bare simulate / run loop / case, 100 coaches, 60 s')
        res = {'bare': bare(base, sweep, tmp), 'cores': os.cpu_count()}
        for w in (1, 2):
            log(f'sweep: {N_CASES} cases on {w} worker(s)')
            res[f'w{w}'] = throughput(base, sweep, w, tmp)
        res['speedup'] = res['w2']['cases_per_min'] / res['w1']['cases_per_min']
        res['overhead_vs_simulate'] = res['w1']['per_case_s'] / res['bare']['simulate_s'] - 1
        res['overhead_vs_run_loop'] = res['w1']['per_case_s'] / res['bare']['run_loop_s'] - 1
        res['load'] = os.getloadavg()
        return res
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def render(res: dict) -> str:
    b, w1, w2 = res['bare'], res['w1'], res['w2']
    sp, ov = res['speedup'], res['overhead_vs_simulate']
    lines = ['## Sweep on Dask (bench/sweep.py)', '',
             f'{N_CASES} cases of 100 coaches, 60 s (tanh u = 1000, h = 2 ms, 100 Hz samples), '
             f'LocalCluster processes with one thread each, {res["cores"]} cores; load average '
             f'at the end {res["load"][0]:.2f}.', '',
             '| workers | cases/min | wall for the cases [s] | wall per case x workers [s] | '
             'median case wall inside the worker [s] | cluster start-up [s] |',
             '| ---: | ---: | ---: | ---: | ---: | ---: |']
    for w in (w1, w2):
        lines.append(f"| {w['workers']} | {w['cases_per_min']:.1f} | {w['wall_s']:.2f} | "
                     f"{w['per_case_s']:.3f} | {w['case_wall_in_worker_s']:.3f} | "
                     f"{w['startup_s']:.1f} |")
    lines += ['', '| target | measured | result |', '| --- | ---: | --- |',
              f'| speed-up 2 workers / 1 worker >= 1.7 | {sp:.2f} | '
              f"{'PASS' if sp >= 1.7 else 'FAIL'} |",
              '| per-case overhead vs bare `simulate` (100 coaches, 60 s) <= 5 % | '
              f"{100 * ov:+.1f} % | {'PASS' if ov <= 0.05 else 'FAIL'} |", '',
              f"Bare `simulate` (writes the bag) {b['simulate_s']:.3f} s; the run loop with no "
              f"output at all {b['run_loop_s']:.3f} s; one sweep case in-process (run loop + "
              f"metrics) {b['case_in_process_s']:.3f} s. Against the bare run loop the 1-worker "
              f"sweep case costs {100 * res['overhead_vs_run_loop']:+.1f} % (the metrics of "
              '6001 samples x 100 vehicles and the Dask round trip).']
    return '\n'.join(lines)


def splice_results(section: str) -> None:
    """Write the sweep section into RESULTS.md."""
    splice_section(RESULTS, SWEEP_BEGIN, SWEEP_END, section)


def sweep_section() -> str:
    """Return the sweep section for RESULTS.md (the last ``bench/sweep.py`` run)."""
    return saved_section(SWEEP_MD, SWEEP_BEGIN, SWEEP_END, '## Sweep on Dask (bench/sweep.py)')


def run_and_write(log=log, write: bool = True) -> str:
    res = run(log=log)
    text = render(res)
    if write:
        with open(SWEEP_MD, 'w') as fh:
            fh.write(text + '\n')
        with open(SWEEP_JSON, 'w') as fh:
            json.dump(res, fh, indent=1, default=str)
    return text


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    ap.add_argument('--no-write', action='store_true', help='print only')
    args = ap.parse_args(argv)
    text = run_and_write(write=not args.no_write)
    print(text)
    if not args.no_write:
        splice_results(text)
        log(f'wrote {SWEEP_MD}, {SWEEP_JSON} and the sweep section of {RESULTS}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
