"""
Stopping distance and peak coupler forces of the shipped scenarios, for a before/after table.

    python bench/shipped_figures.py --repo CHECKOUT --output FILE.json [--only NAME ...]
    python bench/shipped_figures.py --table BEFORE.json AFTER.json

Runs each scenario of :data:`SCENARIOS` through the offline command (``simulate``, then
``report``) of the checkout ``--repo`` (its own ``train_dynamics`` first on the path) and
keeps, from the report's ``summary.json``, the train's stopping distance (from the first
sample and from the brake application), the largest tension and compression [kN] and the
final speed. ``--table`` prints the markdown table of two such files side by side.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile

#: (name, parameter file, duration [s]): the shipped scenarios with a train of the library
SCENARIOS = (
    ('paper_3coach', 'config/paper_3coach.yaml', 60.0),
    ('passenger_loco_12', 'config/passenger_loco_12.yaml', 60.0),
    ('passenger_low_adhesion_12', 'config/passenger_low_adhesion_12.yaml', 150.0),
    ('passenger_low_adhesion_12_wsp', 'config/passenger_low_adhesion_12_wsp.yaml', 150.0),
    ('passenger_pneumatic_40', 'config/passenger_pneumatic_40.yaml', 60.0),
    ('freight_750m', 'config/freight_750m.yaml', 150.0),
    ('freight_1500m', 'config/freight_1500m.yaml', 80.0),
    ('freight_1500m_dp', 'config/freight_1500m_dp.yaml', 80.0),
    ('slack_runin', 'config/slack_runin.yaml', 40.0),
    ('shunting_impact', 'config/shunting_impact.yaml', 4.0),
)

OFFLINE = 'import sys; from train_dynamics.cli.offline import main; sys.exit(main())'
KEYS = ('stopping_distance', 'stopping_distance_from_brake', 'max_tension', 'max_compression',
        'final_speed', 'stopping_time')


def run(repo: Path, params: str, duration: float) -> dict:
    """Return the train's figures of one scenario run with the checkout ``repo``."""
    env = {**os.environ, 'PYTHONPATH': str(repo)}
    with tempfile.TemporaryDirectory() as tmp:
        bag, rep = Path(tmp) / 'bag', Path(tmp) / 'report'
        for args in (['simulate', '--params', str(repo / params), '--duration', str(duration),
                      '--output', str(bag)], ['report', str(bag), '--output', str(rep)]):
            subprocess.run([sys.executable, '-c', OFFLINE, *args], check=True, cwd=repo,
                           env=env, stdout=subprocess.DEVNULL)
        train = json.loads((rep / 'summary.json').read_text())['train']
    return {k: train.get(k) for k in KEYS}


def table(before: dict, after: dict) -> str:
    """Return the markdown table of two result files."""
    out = ['| scenario | stop [m] before | after | from brake [m] before | after | '
           'max tension [kN] before | after | max compression [kN] before | after |',
           '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']

    def f(x, scale=1.0):
        return '-' if x is None else f'{x * scale:.1f}'
    for name in before:
        b, a = before[name], after.get(name, {})
        out.append(f'| {name} | {f(b["stopping_distance"])} | {f(a.get("stopping_distance"))} '
                   f'| {f(b["stopping_distance_from_brake"])} | '
                   f'{f(a.get("stopping_distance_from_brake"))} | '
                   f'{f(b["max_tension"], 1e-3)} | {f(a.get("max_tension"), 1e-3)} | '
                   f'{f(b["max_compression"], 1e-3)} | {f(a.get("max_compression"), 1e-3)} |')
    return '\n'.join(out)


def main(argv=None) -> int:
    """Run the scenarios or print the table."""
    p = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    p.add_argument('--repo', type=Path, default=Path.cwd())
    p.add_argument('--output', type=Path)
    p.add_argument('--only', nargs='*')
    p.add_argument('--table', nargs=2, type=Path, metavar=('BEFORE', 'AFTER'))
    a = p.parse_args(argv)
    if a.table:
        print(table(*(json.loads(t.read_text()) for t in a.table)))
        return 0
    results = json.loads(a.output.read_text()) if a.output and a.output.exists() else {}
    for name, params, duration in SCENARIOS:
        if a.only and name not in a.only:
            continue
        results[name] = run(a.repo.resolve(), params, duration)
        print(name, results[name], flush=True)
        if a.output:
            a.output.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
