"""
Benchmark of a real train: the 750 m freight scenario (``config/freight_750m.yaml``).

Two locomotives and 45 wagons (loaded and empty, G brakes) on a falling gradient into a
curve, dynamic brake then emergency braking: every new force of the model acts (Davis
resistance with standstill holding, gradient and curve forces over the vehicles' lengths,
traction curves, rotating masses). Measured:

- speed at the default step: the cost per vehicle-step [ns] (process CPU time, fresh
  processes interleaved with the comparison trains, best and spread of 5:
  ``vehicle_cost.py``), against the same number of the paper's coaches on flat track
  without the new forces, with the strokes out of reach (the paper's idealisation: no
  blocking) and with the default strokes (long uniform trains block); the
  whole 120 s run and its moving part (the train stands still from ~53 s on);
- accuracy: the largest coupler tension and compression, the stopping distance and time
  against a reference run of the same model at a 20x smaller step (0.1 ms; the fixed-step
  ROS2 solution converged: halving it again changes the peaks by < 0.05 %). The scipy
  reference of ``core.py`` has neither the new forces nor the brake holding a stopped
  vehicle, so it cannot serve here.
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

from train_dynamics.physics.config import load_param_file, SimConfig
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.simulation.runner import traction_schedule
import vehicle_cost

HERE = os.path.dirname(os.path.abspath(__file__))
PARAMS = os.path.join(os.path.dirname(HERE), 'config', 'freight_750m.yaml')
T_END = vehicle_cost.T_END
SAMPLE = vehicle_cost.SAMPLE       # [s] output period at which the peaks are taken
REFERENCE_H = 1.0e-4


def _run(cfg: SimConfig) -> dict:
    """Run the scenario; return peaks, stop and the wall time of the integration."""
    sim = TrainSimulator(cfg)
    events = sorted(traction_schedule(cfg), key=lambda e: e.step)
    per = int(round(SAMPLE / sim.h))
    f_max = f_min = 0.0
    t_stop = None
    wall = 0.0
    for k in range(int(round(T_END / SAMPLE))):
        vehicle_cost.drive(sim, events, k * SAMPLE)
        t0 = time.perf_counter()
        sim.advance(per)
        wall += time.perf_counter() - t0
        f = sim.coupler_force
        f_max, f_min = max(f_max, f.max()), min(f_min, f.min())
        if t_stop is None and np.all(sim.v == 0.0):
            t_stop = sim.t
    return {'max_tension': f_max, 'max_compression': -f_min, 'stop_time': t_stop,
            'stop_distance': float(sim.x[0]), 'wall_s': wall, 'steps': sim.steps,
            'n': sim.n, 'fault': sim.fault}


def run(log=print) -> dict:
    """Measure speed and accuracy of the freight scenario; return the figures."""
    cfg = load_param_file(PARAMS)
    log('freight: 750 m, 47 vehicles, default step')
    best = _run(cfg)
    n = best['n']
    cases = ['freight', f'paper{n}', f'uniform{n}']
    cost = vehicle_cost.interleave([('', sys.executable, None)], cases, log=log)
    cost = {key.strip(): value for key, value in cost.items()}
    log(f'freight: reference at h = {REFERENCE_H:g} s')
    ref = _run(cfg.replace(integration_step=REFERENCE_H))
    ns = cost['freight']['ns'][0]

    def err(key):
        return abs(best[key] - ref[key]) / abs(ref[key])

    return {
        'n': n, 'h': float(cfg.integration_step), 't_end': T_END,
        'speed': float(cfg.integration_step) / (ns * 1e-9 * n), 'ns_per_vehicle_step': ns,
        'plain_ns_per_vehicle_step': cost[f'paper{n}']['ns'][0], 'cost': cost,
        'run': best, 'reference': ref,
        'err_tension': err('max_tension'), 'err_compression': err('max_compression'),
        'err_stop_distance': err('stop_distance'),
        'err_stop_time': abs(best['stop_time'] - ref['stop_time']),
    }


def render(res: dict) -> str:
    """Return the RESULTS.md section of the freight benchmark (markdown)."""
    r, ref = res['run'], res['reference']
    return '\n'.join([
        f"### Real train: 750 m freight ({res['n']} vehicles), h = {res['h'] * 1e3:g} ms",
        '',
        '| quantity | default step | reference (0.1 ms) | error |',
        '| --- | --- | --- | --- |',
        f"| max tension [kN] | {r['max_tension'] / 1e3:.1f} | {ref['max_tension'] / 1e3:.1f} "
        f"| {res['err_tension'] * 100:.2f} % |",
        f"| max compression [kN] | {r['max_compression'] / 1e3:.1f} | "
        f"{ref['max_compression'] / 1e3:.1f} | {res['err_compression'] * 100:.2f} % |",
        f"| stopping distance [m] | {r['stop_distance']:.2f} | {ref['stop_distance']:.2f} | "
        f"{res['err_stop_distance'] * 100:.3f} % |",
        f"| stopping time [s] | {r['stop_time']:.2f} | {ref['stop_time']:.2f} | "
        f"{res['err_stop_time']:.2f} s |",
        '',
        f"Speed: {res['speed']:.0f}x real time. Cost per vehicle-step (process CPU time, "
        'fresh processes interleaved, best / median / max of '
        f"{len(res['cost']['freight']['ns'])}; `bench/vehicle_cost.py`), 120 s with the "
        "freight's inputs, and of its moving part (best):",
        '',
        '| train | ns per vehicle-step | moving |',
        '| --- | --- | --- |',
        *[f"| {label} | {' / '.join(f'{t:.0f}' for t in _spread(res['cost'][key]['ns']))} "
          f"| {res['cost'][key]['moving']:.0f} |"
          for key, label in (('freight', 'freight, every new force'),
                             (f"paper{res['n']}", f"{res['n']} paper coaches, flat, strokes "
                              'out of reach'),
                             (f"uniform{res['n']}", f"{res['n']} paper coaches, default "
                              'strokes'))],
        '',
        f"Freight against the paper's coaches: "
        f"{res['ns_per_vehicle_step'] / res['plain_ns_per_vehicle_step'] - 1:+.0%}.",
    ])


def _spread(ts):
    """Return best, median and max of sorted timings."""
    return ts[0], ts[len(ts) // 2], ts[-1]


if __name__ == '__main__':
    print(render(run()))
