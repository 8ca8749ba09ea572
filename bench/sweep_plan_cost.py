"""
What planning the largest sweep allowed costs: wall time and peak memory of ``make_plan``.

The sweep of ``MAX_CASES`` cases (100 grid values x ``MAX_CASES / 100`` Latin-hypercube
samples on the paper's base parameters) is planned in a fresh process: every case is checked
(``SimConfig.replace``) but its parameters are built on demand, the base dict shared. Prints
the case count, the seconds and the peak resident memory [MB]; the figures were a test's
bounds (60 s, 1024 MB) until speed left the tests (``test_sweep_refusals.py`` keeps the
sharing of the base and the count). ``python bench/sweep_plan_cost.py``; ``bench/run_all.py``
(``make bench``) runs it too.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PAPER = os.path.join(ROOT, 'config', 'paper_3coach.yaml')

_CODE = ('import resource, sys, time; from train_dynamics.cli.sweep_plan import make_plan; '
         't = time.monotonic(); p = make_plan(sys.argv[1], sys.argv[2]); '
         'print(len(p.cases), time.monotonic() - t, '
         'resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)')


def run(log=print) -> dict:
    """Plan the largest sweep in a subprocess; return {cases, seconds, peak_mb}."""
    from train_dynamics.cli.sweep_plan import MAX_CASES

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, 's.yaml')
        with open(path, 'w') as fh:
            fh.write('duration: 1.0\ngrid:\n'
                     f'  scale_factor: [{", ".join(str(100.0 + k) for k in range(100))}]\n'
                     f'lhs: {{samples: {MAX_CASES // 100}, '
                     'ranges: {coach_mass: [4.0e4, 5.0e4]}}\n')
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [ROOT] + [p for p in os.environ.get('PYTHONPATH', '').split(os.pathsep) if p]))
        out = subprocess.run([sys.executable, '-c', _CODE, PAPER, path], capture_output=True,
                             text=True, timeout=1800, check=True, cwd=ROOT, env=env)
    cases, seconds, peak = out.stdout.split()
    res = {'cases': int(cases), 'seconds': float(seconds), 'peak_mb': float(peak)}
    log(f"sweep plan: {res['cases']} cases planned in {res['seconds']:.1f} s, "
        f"peak memory {res['peak_mb']:.0f} MB")
    return res


if __name__ == '__main__':
    run()
