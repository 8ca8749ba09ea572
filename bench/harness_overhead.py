"""
What the controller-test harness costs beyond the simulated loop itself, and where it goes.

The case (``bench/harness_overhead.yaml``): 60 s of the 12-coach passenger train (13
vehicles) against ``examples/pi_brake_controller.py`` in lock-step, no figures: what a CI job
of a brake-controller team runs. Each run is a fresh process that imports the harness and
calls :func:`train_dynamics.testing.run_scenario` (as ``python -m train_dynamics.testing``
does), timed from ``Popen`` to its exit in wall-clock seconds (``time.time()``):

- the loop: from the node's ``lockstep: controller connected; starting`` to its ``duration
  reached`` (the stamps of ``sim_node.log``, wall clock): the simulation and the controller
  answering, which no harness can take away;
- the overhead: the harness process's whole wall time minus the loop;

and the phases of the overhead, from the same clock: the interpreter and the harness's
imports, checking the scenario, the node's start to its ``started`` line (interpreter,
rclpy, the model and its compiled kernels), from there to the controller connected (the
controller's own start, DDS discovery), from ``duration reached`` to the node's exit (closing
the bag, the node's shutdown), the metrics from the bag, ending the processes, and the
process's own exit. Figures: the best of ``--repeats`` runs (the overhead's best, each
phase's best), with the load average of the machine beside them.

``--baseline DIR`` runs the harness of another checkout (e.g. a ``git worktree`` of the
commit before a change) in the same rounds, interleaved (A B A B ...): before and after under
the same load.

``python bench/harness_overhead.py [--repeats 5] [--baseline DIR] [--json]``
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import nodeutil as U  # noqa: E402

REPO = os.path.dirname(HERE)
SCENARIO = os.path.join(HERE, 'harness_overhead.yaml')
CONTROLLER = os.path.join(REPO, 'examples', 'pi_brake_controller.py')

#: the harness process of one run: its stamps (time.time()) and the run's timings, as JSON
CHILD = r"""
import json, resource, sys, time
t0 = time.time()
from train_dynamics.testing import run_scenario
t_import = time.time()
r = run_scenario(sys.argv[1], [sys.executable, sys.argv[2]], sys.argv[3])
t_return = time.time()
ru = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({'t0': t0, 't_import': t_import, 't_call': t_import,
                  't_return': t_return, 'timings': r.timings, 'passed': r.passed,
                  'error': r.error, 'cpu_self': ru.ru_utime + ru.ru_stime}))
"""

#: (key, the phase's label) in the order they happen
PHASES = (
    ('interpreter_imports', 'interpreter and harness imports'),
    ('check', 'checking the scenario'),
    ('node_start', "node start to its 'started' (imports, model, kernels)"),
    ('connect', "'started' to controller connected (controller start, discovery)"),
    ('node_end', "'duration reached' to the node's exit (bag closed, shutdown)"),
    ('metrics', 'metrics from the bag'),
    ('stop', 'ending the processes'),
    ('exit', "the harness process's exit"),
)


def one_run(repo: str, env: dict) -> dict:
    """Run the harness of ``repo`` once in a fresh process; return its figures [s]."""
    out = tempfile.mkdtemp(prefix='harness_overhead_')
    run_dir = os.path.join(out, 'run')
    child_env = {**env, 'PYTHONPATH': os.pathsep.join(
        [repo] + [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p])}
    try:
        t_popen = time.time()
        proc = subprocess.run([sys.executable, '-c', CHILD, SCENARIO, CONTROLLER, run_dir],
                              env=child_env, cwd=out, capture_output=True, text=True)
        t_exit = time.time()
        if proc.returncode != 0:
            raise RuntimeError(f'harness run failed ({proc.returncode}): '
                               f'{proc.stderr.strip()[-2000:]}')
        child = json.loads(proc.stdout.strip().splitlines()[-1])
        log = os.path.join(run_dir, 'sim_node.log')
        stamps = {key: U.first_log_time(log, needle) for key, needle in (
            ('started', ']: started: '), ('connected', 'controller connected'),
            ('reached', 'duration reached'))}
        if None in stamps.values():
            raise RuntimeError(f'missing node log lines in {log}: {stamps}')
        timings = child['timings']
        node_exit = child['t_call'] + timings['check'] + timings['loop']
        loop = stamps['reached'] - stamps['connected']
        started_at = child['t_call'] + timings['check']
        return {
            'wall': t_exit - t_popen,
            'loop': loop,
            'overhead': (t_exit - t_popen) - loop,
            'interpreter_imports': child['t_import'] - t_popen,
            'check': timings['check'],
            'node_start': stamps['started'] - started_at,
            'connect': stamps['connected'] - stamps['started'],
            'node_end': node_exit - stamps['reached'],
            'metrics': timings.get('metrics', 0.0),
            'stop': timings['stop'],
            'exit': t_exit - child['t_return'],
            'harness_cpu': child['cpu_self'],
            'passed': child['passed'],
        }
    finally:
        shutil.rmtree(out, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    p.add_argument('--repeats', type=int, default=5)
    p.add_argument('--baseline', metavar='DIR', help='another checkout, run interleaved')
    p.add_argument('--json', action='store_true', help='print every run as JSON too')
    args = p.parse_args(argv)
    env = dict(os.environ)
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    env.setdefault('ROS_DOMAIN_ID', str(70 + os.getpid() % 31))
    env.setdefault('MPLBACKEND', 'Agg')
    repos = [('now', REPO)] + ([('baseline', os.path.abspath(args.baseline))]
                               if args.baseline else [])
    runs: dict[str, list[dict]] = {name: [] for name, _ in repos}
    loads = []
    for k in range(args.repeats):
        for name, repo in repos:
            loads.append(os.getloadavg()[0])
            r = one_run(repo, env)
            runs[name].append(r)
            print(f'{name} #{k + 1}: overhead {r["overhead"]:.2f} s (wall {r["wall"]:.2f} s, '
                  f'loop {r["loop"]:.2f} s, load {loads[-1]:.1f})', file=sys.stderr)
    print(f'\nHarness overhead, best of {args.repeats} (load average '
          f'{min(loads):.1f}-{max(loads):.1f}, {os.cpu_count()} cores)\n')
    names = [name for name, _ in repos]
    print('| phase [s wall] | ' + ' | '.join(names) + ' |')
    print('| --- |' + ' --- |' * len(names))
    rows = [('loop (not overhead)', 'loop')] + [(label, key) for key, label in PHASES] + [
        ('**overhead** (wall - loop)', 'overhead'), ('harness process CPU', 'harness_cpu')]
    for label, key in rows:
        print(f'| {label} | ' + ' | '.join(
            f'{min(r[key] for r in runs[n]):.2f}' for n in names) + ' |')
    if args.json:
        print(json.dumps({'loads': loads, 'runs': runs}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
