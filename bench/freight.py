"""
Benchmark of a real train: the 750 m freight scenario (``config/freight_750m.yaml``).

Two locomotives and 45 wagons (loaded and empty, G brakes) on a falling gradient into a
curve, dynamic brake then emergency braking: every new force of the model acts (Davis
resistance with standstill holding, gradient and curve forces over the vehicles' lengths,
traction curves, rotating masses). Measured:

- speed at the default step: simulated seconds per wall second, and the cost per
  vehicle-step [ns], against the same number of the paper's coaches on flat track without
  the new forces (the cost of the real-train model);
- accuracy: the largest coupler tension and compression, the stopping distance and time
  against a reference run of the same model at a 20x smaller step (0.1 ms; the fixed-step
  ROS2 solution converged: halving it again changes the peaks by < 0.05 %). The scipy
  reference of ``core.py`` has neither the new forces nor the brake holding a stopped
  vehicle, so it cannot serve here.
"""
from __future__ import annotations

import os
import time

import numpy as np

from train_dynamics.physics.parameters import load_param_file, SimConfig
from train_dynamics.physics.runner import traction_schedule
from train_dynamics.physics.train import TrainSimulator

HERE = os.path.dirname(os.path.abspath(__file__))
PARAMS = os.path.join(os.path.dirname(HERE), 'config', 'freight_750m.yaml')
T_END = 120.0
T_EMERGENCY = 5.0
SAMPLE = 0.01       # [s] output period at which the peaks are taken
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
        t = k * SAMPLE
        for e in events:
            if abs(e.t_ns * 1e-9 - t) < 1e-9:
                sim.set_traction_command(e.command, e.index)
        sim.set_head_pipe_pressure(0.0 if t >= T_EMERGENCY - 1e-9 else 500000.0)
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
    _run(cfg.replace(consist_file=cfg.consist_file))                  # compile / warm up
    log('freight: 750 m, 47 vehicles, default step')
    best = min((_run(cfg) for _ in range(3)), key=lambda r: r['wall_s'])
    n = best['n']
    plain = SimConfig.from_dict({'num_coaches': n})
    base = min((_run(plain) for _ in range(3)), key=lambda r: r['wall_s'])
    log(f'freight: reference at h = {REFERENCE_H:g} s')
    ref = _run(cfg.replace(integration_step=REFERENCE_H))
    ns = 1e9 / (best['steps'] * n)

    def err(key):
        return abs(best[key] - ref[key]) / abs(ref[key])

    return {
        'n': n, 'h': float(cfg.integration_step), 't_end': T_END,
        'speed': T_END / best['wall_s'], 'ns_per_vehicle_step': best['wall_s'] * ns,
        'plain_ns_per_vehicle_step': base['wall_s'] * 1e9 / (base['steps'] * n),
        'run': best, 'reference': ref,
        'err_tension': err('max_tension'), 'err_compression': err('max_compression'),
        'err_stop_distance': err('stop_distance'),
        'err_stop_time': abs(best['stop_time'] - ref['stop_time']),
    }


def render(res: dict) -> str:
    """Return the README/RESULTS section of the freight benchmark (markdown)."""
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
        f"Speed: {res['speed']:.0f}x real time; {res['ns_per_vehicle_step']:.0f} ns per "
        f"vehicle-step with every new force, {res['plain_ns_per_vehicle_step']:.0f} ns for "
        f"{res['n']} paper coaches on flat track "
        f"({res['ns_per_vehicle_step'] / res['plain_ns_per_vehicle_step'] - 1:+.0%}).",
    ])


if __name__ == '__main__':
    print(render(run()))
