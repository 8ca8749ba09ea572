"""
Speed of a 2 x 8-car multiple unit with builtin blending: offline and in the node at 100 Hz.

Train: two ICE 3 units coupled (``config/consist_ice3_8.yaml``'s cars twice: 16 cars, 8 motor
cars; written to a temporary consist file), the settings of ``config/hs_ice3_8.yaml``
(``blending: builtin``, 2 ms step, 100 Hz output), a full-service demand at t = 1 s from
300 km/h. Cases: ``lumped`` (no wheelsets), ``wheelsets`` (``wheelsets: true``: one
lumped wheelset per car) and ``bogies`` (``bogie_wheelsets: true``: two per car, one per
bogie, with the builtin WSP per bogie: the issue's case).

- offline: the offline command's loop writing the bag (``bench/offline_speed.py``'s
  ``run_inprocess`` mode ``bag``: ``simulate`` minus its start-up) over ``--offline-duration``
  s (the unit still runs at about 36 m/s at 60 s), real-time factor = simulated / wall, the
  best of ``--repeats``; target >= 50x;
- node: ``sim_node`` at 100 Hz, real time, measured by ``bench/node.py``'s probe (DDS
  reception times of ``couplers``): p99 of abs(period - 10 ms) over ``--node-duration`` s;
  target <= 2 ms.

Prints a markdown table with the load average (the machine may be shared).
``python bench/multiple_units_speed.py [--repeats 3] [--node-duration 30] [--case lumped]``.
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(1, ROOT)

import node as node_bench  # noqa: E402
import offline_speed  # noqa: E402
import yaml  # noqa: E402

TARGET_RTF = 50.0
TARGET_P99_MS = 2.0
UNIT = os.path.join(ROOT, 'config', 'consist_ice3_8.yaml')
#: the blending settings of config/hs_ice3_8.yaml (full service 0.8 m/s^2 from 300 km/h)
SETTINGS = {'initial_speed': 83.333, 'brake_input': 'cylinder_per_coach',
            'blending': 'builtin', 'brake_demand_mode': 'fraction',
            'full_service_deceleration': 0.8, 'blending_jerk_limit': 0.8,
            'friction_response_time': 0.3, 'demand_schedule_times': [1.0],
            'demand_schedule_values': [1.0], 'buffer_stiffness': 2.0e7,
            'buffer_friction': 5.0e6, 'draw_gear_stiffness': 2.0e7,
            'draw_gear_friction': 5.0e6, 'integration_step': 0.002, 'publish_rate': 100.0}
CASES = {'lumped': {}, 'wheelsets': {'wheelsets': True},
         'bogies': {'bogie_wheelsets': True, 'wsp': 'builtin'}}


def write_train(tmp: str, extra: dict) -> tuple[str, str]:
    """Write the 16-car consist and its parameter file into ``tmp``; return both paths."""
    with open(UNIT, encoding='utf-8') as fh:
        unit = yaml.safe_load(fh)
    unit['vehicles'] = list(unit['vehicles']) * 2         # two units coupled
    consist = os.path.join(tmp, 'consist_ice3_2x8.yaml')
    with open(consist, 'w', encoding='utf-8') as fh:
        yaml.safe_dump(unit, fh, sort_keys=False)
    params = os.path.join(tmp, 'ice3_2x8.yaml')
    doc = {'/**/train_dynamics': {'ros__parameters': {'consist_file': consist, **SETTINGS,
                                                      **extra}}}
    with open(params, 'w', encoding='utf-8') as fh:
        yaml.safe_dump(doc, fh, sort_keys=False)
    return consist, params


def offline(params: str, duration: float, repeats: int, tmp: str) -> dict:
    """Return the best wall and CPU real-time factors of ``repeats`` offline runs."""
    offline_speed.run_inprocess(params, 'bag', 2.0, tmp)          # warm-up: numba cache
    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = offline_speed.run_inprocess(params, 'bag', duration, tmp)
        walls.append(wall)
        cpus.append(cpu)
    return {'duration': duration, 'rtf': duration / min(walls), 'rtf_cpu': duration / min(cpus),
            'walls': walls}


def in_node(consist: str, extra: dict, duration: float) -> dict:
    """Return bench/node.py's figures of sim_node running the unit at 100 Hz, real time."""
    params = {'consist_file': consist, **SETTINGS, **extra}
    for key in ('demand_schedule_times', 'demand_schedule_values'):
        params[key] = '[' + ', '.join(repr(float(x)) for x in params[key]) + ']'
    return node_bench.run(16, 100.0, duration, extra_params=params)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--case', choices=sorted(CASES), action='append')
    ap.add_argument('--repeats', type=int, default=3)
    ap.add_argument('--offline-duration', type=float, default=60.0)
    ap.add_argument('--node-duration', type=float, default=30.0)
    ap.add_argument('--no-node', action='store_true')
    args = ap.parse_args(argv)
    rows = ['| case | offline RTF wall (CPU), best of %d | node p99 jitter (p50 / max) | '
            'node RTF | load avg before / after |' % args.repeats,
            '| --- | ---: | ---: | ---: | --- |']
    for case in args.case or sorted(CASES):
        tmp = tempfile.mkdtemp(prefix='td_bench_mu_')
        try:
            load0 = os.getloadavg()[0]
            consist, params = write_train(tmp, CASES[case])
            off = offline(params, args.offline_duration, args.repeats, tmp)
            nd = None if args.no_node else in_node(consist, CASES[case], args.node_duration)
            load1 = os.getloadavg()[0]
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
        ok = 'PASS' if off['rtf'] >= TARGET_RTF else 'FAIL'
        node_cell, node_rtf = 'not run', ''
        if nd is not None:
            verdict = 'PASS' if nd['jitter_p99_ms'] <= TARGET_P99_MS else 'FAIL'
            node_cell = (f"{nd['jitter_p99_ms']:.3f} ms {verdict} ({nd['jitter_p50_ms']:.3f} / "
                         f"{nd['jitter_max_ms']:.3f} ms; {nd['messages']} outputs, "
                         f"{nd['stamp_gaps']} gaps)")
            node_rtf = f"{nd['rtf']:.4f}"
        rows.append(f"| 2 x 8-car ICE 3, builtin blending, {case} | {off['rtf']:.0f}x "
                    f"({off['rtf_cpu']:.0f}x) {ok} | {node_cell} | {node_rtf} | "
                    f'{load0:.2f} / {load1:.2f} |')
        print(rows[-1], flush=True)
    print(f'\n{time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, {os.cpu_count()} cores; '
          f'targets: offline >= {TARGET_RTF:g}x, node p99 <= {TARGET_P99_MS:g} ms\n')
    print('\n'.join(rows))
    return 0


if __name__ == '__main__':
    sys.exit(main())
