"""
Figure of the pneumatic brake: empirical vs pneumatic, paper train and 750 m freight.

Writes ``docs/figures/pneumatic_vs_empirical.png`` and prints the numbers of the table in
``docs/brakes.md``.
Emergency from the ``brake_valve`` (400 kPa/s to 0) at t = 1 s; 60 s.
"""
from __future__ import annotations

import os
import sys

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from train_dynamics.physics.brake_valve import BrakeValveModel  # noqa: E402
from train_dynamics.physics.config import SimConfig  # noqa: E402
from train_dynamics.physics.train import TrainSimulator  # noqa: E402

OUT = os.path.join(os.path.dirname(HERE), 'docs', 'figures', 'pneumatic_vs_empirical.png')
TRAINS = (('paper, 3 coaches (P)', {'num_coaches': 3}),
          ('freight 750 m, 30 wagons of 90 t (G)', {
              'num_coaches': 30, 'coach_mass': 90000.0, 'brake_regime': 'G',
              'initial_speed': 27.78}))


def run(params: dict, duration: float = 60.0) -> dict:
    """Sample t, head/tail pipe and cylinder [bar], max tension/compression [kN] at 10 ms."""
    sim = TrainSimulator(SimConfig.from_dict(params))
    valve = BrakeValveModel(schedule=['1.0:emergency'])
    rows = []
    for k in range(int(round(duration / 0.01))):
        t = (k + 1) * 0.01
        sim.set_head_pipe_pressure(valve.advance_to(t - 0.01))
        sim.advance_to(t)
        F = sim.coupler_force
        p, c = sim.pipe_pressure, sim.cylinder_pressure
        rows.append((sim.t, p[0], p[-1], c[0], c[-1], F.max(), F.min(), sim.v[0]))
    a = np.array(rows)
    stop = a[np.argmax(a[:, 7] <= 0.0), 0] if np.any(a[:, 7] <= 0.0) else np.nan
    return {'t': a[:, 0], 'pipe': a[:, 1:3] * 1e-5, 'cyl': a[:, 3:5] * 1e-5,
            'tension': a[:, 5] * 1e-3, 'compression': a[:, 6] * 1e-3, 'stop_t': stop,
            'x': float(sim.x[0])}


def main() -> int:
    """Draw the figure and print the table."""
    fig = Figure(figsize=(14.0, 10.0), dpi=100, layout='constrained')
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, 2, sharex='col')
    print('| train | brake model | tail cylinder 95 % at [s] | max tension [kN] | '
          'max compression [kN] | stops at [s] | stopping distance [m] |')
    print('| --- | --- | ---: | ---: | ---: | ---: | ---: |')
    for col, (name, params) in enumerate(TRAINS):
        for model, style in (('empirical', '--'), ('pneumatic', '-')):
            r = run(dict(params, brake_model=model))
            t = r['t']
            for j, (where, color) in enumerate((('head', 'tab:blue'), ('tail', 'tab:red'))):
                lab = f'{model}, {where}'
                axes[0, col].plot(t, r['pipe'][:, j], style, color=color, label=lab)
                axes[1, col].plot(t, r['cyl'][:, j], style, color=color, label=lab)
            axes[2, col].plot(t, r['tension'], style, color='tab:green',
                              label=f'{model}, max tension')
            axes[2, col].plot(t, r['compression'], style, color='tab:purple',
                              label=f'{model}, max compression')
            c_tail = r['cyl'][:, 1]
            t95 = t[np.argmax(c_tail >= 0.95 * 3.8)] if np.any(c_tail >= 0.95 * 3.8) else np.nan
            print(f'| {name} | {model} | {t95:.1f} | {r["tension"].max():.1f} | '
                  f'{-r["compression"].min():.1f} | {r["stop_t"]:.1f} | {r["x"]:.0f} |')
        axes[0, col].set_title(f'{name}: brake pipe [bar gauge]')
        axes[1, col].set_title('brake cylinder [bar gauge]')
        axes[2, col].set_title('coupler force extremes over the train [kN] (> 0 tension)')
        axes[2, col].set_xlabel('time t [s]')
        for ax in axes[:, col]:
            ax.grid(True, alpha=0.35)
            ax.legend(fontsize=8, loc='best')
            ax.set_xlim(0.0, 60.0 if col else 20.0)
    fig.suptitle('Emergency brake at t = 1 s: empirical (dashed) vs pneumatic (solid)')
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    fig.savefig(OUT)
    print(f'wrote {OUT}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
