"""
Where the multirate refinement's time goes: its groups, their size and sub-steps, over a run.

The paper's coaches (``paperN`` of ``bench/vehicle_cost.py``: strokes out of reach), the head
brake pipe vented at t = 0, the default settings unless ``--mr`` sets ``multirate_tolerance``.
Per chunk of simulated time (in one process, after a warm-up simulator):

- CPU time of ``advance`` [ns] per vehicle-step;
- refined groups per long step and accepted sub-steps per group (``integration_stats``:
  ``mr_groups``, ``mr_substeps``);
- couplers per group, weighted by its sub-steps: the growth of the sum of
  ``substeps_per_coupler`` over the growth of ``mr_substeps`` (each sub-step of a group adds
  one to every coupler inside it);
- coupler sub-steps per coupler and long step: the same growth over couplers x long steps,
  the refinement's work relative to the long step's (0: none).

``python bench/multirate_spans.py [--cases paper100,paper1000] [--duration 60] [--chunk 10]
[--mr TOL]``; prints a markdown table.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from vehicle_cost import _config  # noqa: E402


def spans(case: str, duration: float, chunk: float, mr: float | None) -> list[dict]:
    """Return one row per chunk of ``case`` (see the module docstring)."""
    from train_dynamics.physics.train import TrainSimulator
    cfg = _config(case)
    if mr is not None:
        cfg = cfg.replace(multirate_tolerance=mr)
    TrainSimulator(cfg).advance(1)       # load the compiled kernels (not timed)
    sim = TrainSimulator(cfg)
    sim.set_head_pipe_pressure(0.0)
    n = sim.n
    per = int(round(chunk / sim.h))
    rows = []
    groups0 = sub0 = cpl0 = 0
    for _ in range(int(round(duration / chunk))):
        t0 = time.process_time()
        sim.advance(per)
        cpu = time.process_time() - t0
        stats = sim.integration_stats
        groups, sub = stats['mr_groups'], stats['mr_substeps']
        cpl = int(sim.substeps_per_coupler.sum())
        dg, ds, dc = groups - groups0, sub - sub0, cpl - cpl0
        rows.append({'case': case, 't': sim.t, 'ns': cpu * 1e9 / (per * n),
                     'groups_per_step': dg / per, 'sub_per_group': ds / dg if dg else 0.0,
                     'couplers_per_group': dc / ds if ds else 0.0,
                     'work': dc / (per * (n - 1)), 'v_head': float(sim.v[0]),
                     'v_tail': float(sim.v[-1])})
        groups0, sub0, cpl0 = groups, sub, cpl
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--cases', default='paper100,paper1000')
    ap.add_argument('--duration', type=float, default=60.0)
    ap.add_argument('--chunk', type=float, default=10.0)
    ap.add_argument('--mr', type=float, default=None, help='multirate_tolerance (default: the '
                    "simulator's default)")
    args = ap.parse_args(argv)
    print('| case | until t [s] | ns per vehicle-step | groups per long step | sub-steps per '
          'group | couplers per group | coupler sub-steps per coupler-step | v head / tail '
          '[m/s] |')
    print('| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |')
    for case in args.cases.split(','):
        for r in spans(case, args.duration, args.chunk, args.mr):
            print(f"| {r['case']} | {r['t']:.0f} | {r['ns']:.0f} | {r['groups_per_step']:.2f} | "
                  f"{r['sub_per_group']:.1f} | {r['couplers_per_group']:.1f} | "
                  f"{r['work']:.2f} | {r['v_head']:.1f} / {r['v_tail']:.1f} |")


if __name__ == '__main__':
    main()
