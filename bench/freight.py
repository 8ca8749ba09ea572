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
- the speed target (:func:`target`): whole runs of the moving train (up to just before the
  first vehicle stops) at default settings and at the plain fixed step, interleaved;
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

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.simulation.runner import schedule_events
import vehicle_cost

HERE = os.path.dirname(os.path.abspath(__file__))
PARAMS = os.path.join(os.path.dirname(HERE), 'config', 'freight_750m.yaml')
T_END = vehicle_cost.T_END
SAMPLE = vehicle_cost.SAMPLE       # [s] output period at which the peaks are taken
REFERENCE_H = 1.0e-4


def _run(cfg: SimConfig) -> dict:
    """Run the scenario; return peaks, stop and the wall time of the integration."""
    sim = TrainSimulator(cfg)
    events = sorted(schedule_events(cfg), key=lambda e: e.step)
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
        'speed': float(cfg.integration_step) / (cost['freight']['moving'] * 1e-9 * n),
        'ns_per_vehicle_step': ns,
        'plain_ns_per_vehicle_step': cost[f'paper{n}']['ns'][0], 'cost': cost,
        'run': best, 'reference': ref,
        'err_tension': err('max_tension'), 'err_compression': err('max_compression'),
        'err_stop_distance': err('stop_distance'),
        'err_stop_time': abs(best['stop_time'] - ref['stop_time']),
    }


#: the speed target at default settings [x real time] and the sample-accuracy target
SPEED_TARGET = 200.0
STOP_MARGIN = 0.5       # [s] the timed span ends this long before the first vehicle stops


def _sampled(cfg: SimConfig, t_end: float = T_END) -> dict:
    """
    Run the scenario untimed; sample every coupler's force and displacement every SAMPLE.

    Returns the samples (F, y: samples x couplers, from t = SAMPLE) and the first sample
    instant at which a vehicle is at rest or held (None if none before ``t_end``).
    """
    sim = TrainSimulator(cfg)
    events = sorted(schedule_events(cfg), key=lambda e: e.step)
    k_end = int(round(t_end / SAMPLE))
    F = np.empty((k_end, sim.n - 1))
    Y = np.empty_like(F)
    t_stop = None
    for k in range(k_end):
        vehicle_cost.drive(sim, events, k * SAMPLE)
        sim.advance_to((k + 1) * SAMPLE)
        F[k] = sim.coupler_force
        Y[k] = sim.y
        if t_stop is None and (np.any(sim.v <= 0.0) or np.any(sim.held)):
            t_stop = sim.t
    return {'F': F, 'y': Y, 't_stop': t_stop, 'fault': sim.fault, 'steps': int(sim.steps),
            'integration': dict(sim.integration_stats)}


def _timed(cfg: SimConfig, t_span: float) -> tuple[float, float]:
    """Return wall and CPU time [s] of a whole run over [0, t_span] (inputs, 100 Hz read-out)."""
    sim = TrainSimulator(cfg)
    events = sorted(schedule_events(cfg), key=lambda e: e.step)
    c0 = time.process_time()
    t0 = time.perf_counter()
    for k in range(int(round(t_span / SAMPLE))):
        vehicle_cost.drive(sim, events, k * SAMPLE)
        sim.advance_to((k + 1) * SAMPLE)
        _ = np.abs(sim.coupler_force).max()
    return time.perf_counter() - t0, time.process_time() - c0


def target(settings, repeats: int = 5, log=print) -> list[dict]:
    """
    Speed of the freight at each setting, in whole runs of the moving train, and accuracy.

    ``settings``: [(label, overrides of the scenario's parameters)]. Each setting is run
    once untimed (samples every SAMPLE); the timed span ends STOP_MARGIN before the first
    vehicle stops (the earliest over the settings: all timed over the same span); then
    ``repeats`` whole runs of each setting, interleaved, in this process (kernels warm);
    the figure is the fastest (and beside it the least process CPU time). Accuracy: the
    independent reference of ``core.py`` (Radau) has no pneumatic brake, traction,
    gradients, curves, resistance or strokes, so there is no independent figure here; the
    rows give instead every coupler-force and displacement sample against the SAME model
    at a fixed 0.1 ms step (multirate off), max over samples and couplers / its peak (a
    convergence figure, not an independent one).
    """
    base = load_param_file(PARAMS)
    cfgs = [base.replace(**over) if over else base for _, over in settings]
    log(f'freight target: reference run, fixed {REFERENCE_H * 1e3:g} ms')
    ref = _sampled(base.replace(integration_step=REFERENCE_H, multirate_tolerance=0.0,
                                integration_tolerance=0.0))
    runs = []
    for cfg in cfgs:
        TrainSimulator(cfg).advance(1)      # kernels loaded, not timed
        runs.append(_sampled(cfg))
    stops = [r['t_stop'] for r in runs + [ref] if r['t_stop'] is not None]
    t_stop = min(stops) if stops else T_END + STOP_MARGIN
    span = SAMPLE * int(round((t_stop - STOP_MARGIN) / SAMPLE))
    k = int(round(span / SAMPLE))
    walls = [[] for _ in cfgs]
    for _ in range(repeats):
        for j, cfg in enumerate(cfgs):
            walls[j].append(_timed(cfg, span))
    rows = []
    for (label, over), cfg, run, t in zip(settings, cfgs, runs, walls):
        w = [a for a, _ in t]
        cpu = min(c for _, c in t)
        pk_f = np.abs(ref['F'][:k]).max()
        pk_y = np.abs(ref['y'][:k]).max()
        rows.append({'label': label, 'overrides': over, 'n': cfg.n_coaches,
                     'h': float(cfg.integration_step),
                     'multirate': float(cfg.values['multirate_tolerance']),
                     'span_s': span, 't_first_stop': run['t_stop'], 'walls_s': w,
                     'wall_s': min(w), 'rtf': span / min(w), 'repeats': repeats,
                     'cpu_s': cpu, 'rtf_cpu': span / cpu,
                     'fault': run['fault'], 'integration': run['integration'],
                     'conv_force_err': float(np.abs(run['F'][:k] - ref['F'][:k]).max() / pk_f),
                     'conv_disp_err': float(np.abs(run['y'][:k] - ref['y'][:k]).max() / pk_y)})
        log(f"  freight {label}: {rows[-1]['rtf']:.0f}x real time over 0-{span:g} s, "
            f"force samples {100 * rows[-1]['conv_force_err']:.2f} % of the 0.1 ms run's peak")
    return rows


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
        f"Speed while moving (CPU time of its moving part): {res['speed']:.0f}x real time "
        '(the whole runs of the targets table are the figure to judge). Cost per '
        'vehicle-step (process CPU time, '
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
