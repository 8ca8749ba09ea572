"""
Figure and figures of the shipped low-adhesion scenario (docs/brakes.md "Scenario").

Runs ``config/passenger_low_adhesion_12.yaml`` (wsp none) and its ``_wsp`` twin (wsp
builtin) through the offline runner (the brake valve's schedule of the file), prints per run
the stop (distance, time), the longest sliding time and distance of any vehicle and the
train's kinetic energy balance, and writes ``docs/figures/wheel_slide_160.png``: speed, wheel
peripheral speed and cylinder pressure of the first coach behind the locomotive, and the
slip speeds of all vehicles, both runs.

    .venv/bin/python bench/wheel_slide_figure.py
"""
from __future__ import annotations

import os
import sys

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)

from train_dynamics import topics  # noqa: E402
from train_dynamics.cli.scenario import valve_from_param_file  # noqa: E402
from train_dynamics.param_files import load_param_file  # noqa: E402
from train_dynamics.physics.metrics import RunMetrics  # noqa: E402
from train_dynamics.simulation.runner import InputSchedule, run_simulation  # noqa: E402

FIGURE = os.path.join(ROOT, 'docs', 'figures', 'wheel_slide_160.png')
SCENARIOS = (('wsp none', 'passenger_low_adhesion_12.yaml'),
             ('wsp builtin', 'passenger_low_adhesion_12_wsp.yaml'))
DURATION = 150.0
EVERY = 0.02        # [s] sampling of the figure
COACH = 1           # the first coach behind the locomotive (index)


def run(name: str) -> dict:
    """Run one scenario; return its traces and the run metrics' train figures."""
    path = os.path.join(ROOT, 'config', name)
    cfg = load_param_file(path)
    metrics = RunMetrics.for_run(cfg)
    inputs = InputSchedule(topics.PIPE_HEAD, [], valve_from_param_file(path, cfg), 'valve')
    rows = []
    steps = [int(round(k * EVERY / cfg.integration_step))
             for k in range(int(round(DURATION / EVERY)) + 1)]

    def sample(s):
        metrics.sample(s)
        rows.append((s.t, s.sim.v.copy(), s.sim.wheel_speed.copy(),
                     s.sim.cylinder_pressure.copy(), s.sim.x[0]))

    sim = run_simulation(cfg, DURATION, inputs, on_sample=sample, sample_steps=steps)
    return {'t': np.array([r[0] for r in rows]), 'v': np.array([r[1] for r in rows]),
            'u': np.array([r[2] for r in rows]), 'p': np.array([r[3] for r in rows]),
            'train': metrics.result()['train'], 'sim': sim}


def main() -> None:
    """Run both scenarios, print their figures, write the figure."""
    fig = Figure(figsize=(11, 8), dpi=100, layout='constrained')
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, 2, sharex=True)
    for label, name in SCENARIOS:
        r = run(name)
        tr = r['train']
        sim = r['sim']
        print(f'{label}: stop {tr["stopping_distance"]:.0f} m / {tr["stopping_time"]:.1f} s; '
              f'sliding at most {tr["max_sliding_time"]:.1f} s '
              f'(vehicle {tr["max_sliding_time_vehicle"]}), '
              f'{tr["max_sliding_distance"]:.0f} m '
              f'(vehicle {tr["max_sliding_distance_vehicle"]}); '
              f'longest wheel rest while moving '
              f'{longest_rest(r["t"], r["v"], r["u"]):.2f} s; '
              f'creep work {sim.work_creep / 1e6:.1f} MJ, wheel brakes '
              f'{sim.work_wheel_brake / 1e6:.1f} MJ')
        axes[0, 0].plot(r['t'], r['v'][:, COACH] * 3.6, label=f'{label}: vehicle')
        axes[0, 0].plot(r['t'], r['u'][:, COACH] * 3.6, '--', label=f'{label}: wheel')
        axes[1, 0].plot(r['t'], r['p'][:, COACH] / 1e5, label=label)
        slip = np.max(r['v'] - r['u'], axis=1)
        axes[0 if label == 'wsp none' else 1, 1].plot(r['t'], slip * 3.6, label=label)
    axes[0, 0].set_title(f'vehicle {COACH + 1}: speed and wheel speed [km/h]')
    axes[1, 0].set_title(f'vehicle {COACH + 1}: brake cylinder [bar]')
    axes[0, 1].set_title('largest slip speed of any vehicle [km/h], wsp none')
    axes[1, 1].set_title('largest slip speed of any vehicle [km/h], wsp builtin')
    for ax in axes.flat:
        ax.grid(True)
        ax.legend(fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel('t [s]')
    fig.savefig(FIGURE)
    print('wrote', FIGURE)


def longest_rest(t, v, u) -> float:
    """Longest time [s] a wheel of any vehicle stayed at rest while its vehicle moved."""
    dt = t[1] - t[0]
    run_ = np.zeros(v.shape[1])
    longest = 0.0
    for k in range(len(t)):
        run_ = np.where((v[k] > 0.0) & (u[k] == 0.0), run_ + dt, 0.0)
        longest = max(longest, float(run_.max()))
    return longest


if __name__ == '__main__':
    main()
