"""
Figures of the brake systems of real trains (docs/brakes.md "Brake systems of real trains").

Runs the shipped scenarios through the simulator and writes
``docs/figures/brake_accelerators.png`` (1022 m passenger train, emergency, accelerators on
and off), ``docs/figures/brake_ep_ecp.png`` (EP and ECP, graduated commands) and
``docs/figures/brake_dp.png`` (1500 m freight train, emergency, with and without a remote
locomotive at the rear: pipe, cylinders, in-train forces); prints the numbers of the tables.
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

from train_dynamics.param_files import load_param_file  # noqa: E402
from train_dynamics.physics.brake_valve import BrakeValveModel  # noqa: E402
from train_dynamics.physics.pneumatic import propagation_speed  # noqa: E402
from train_dynamics.physics.train import TrainSimulator  # noqa: E402

FIGURES = os.path.join(ROOT, 'docs', 'figures')
BAR = 1.0e5


def scenario(name: str, **changes):
    """Return the configuration of a shipped parameter file, with changes."""
    cfg = load_param_file(os.path.join(ROOT, 'config', name))
    return cfg.replace(**changes) if changes else cfg


def run(cfg, duration: float, emergency_at: float | None = 1.0, ep=(),
        every: float = 0.02) -> dict:
    """Sample pipe, cylinders [bar] and coupler forces [kN] every ``every`` s."""
    sim = TrainSimulator(cfg)
    valve = BrakeValveModel(schedule=['0.0:release'] + (
        [f'{emergency_at}:emergency'] if emergency_at is not None else []))
    pending = sorted(ep)
    rows = []
    for k in range(int(round(duration / every))):
        t = (k + 1) * every
        while pending and pending[0][0] <= t - every + 1e-9:
            sim.set_ep_command(pending.pop(0)[1])
        sim.set_head_pipe_pressure(valve.advance_to(t - every))
        sim.advance_to(t)
        rows.append((sim.t, sim.pipe_pressure / BAR, sim.cylinder_pressure / BAR,
                     sim.coupler_force / 1e3))
    return {'t': np.array([r[0] for r in rows]), 'pipe': np.array([r[1] for r in rows]),
            'cyl': np.array([r[2] for r in rows]), 'F': np.array([r[3] for r in rows])}


def first(t, mask):
    """First instant at which mask holds (per column), inf where never."""
    hit = mask.any(axis=0)
    return np.where(hit, t[np.argmax(mask, axis=0)], np.inf)


def along(ax_pipe, ax_cyl, r, title):
    """Pipe and cylinder of five vehicles along the train."""
    n = r['pipe'].shape[1]
    for frac in (0.0, 0.25, 0.5, 0.75, 1.0):
        i = int(round(frac * (n - 1)))
        ax_pipe.plot(r['t'], r['pipe'][:, i], label=f'vehicle {i + 1}')
        ax_cyl.plot(r['t'], r['cyl'][:, i], label=f'vehicle {i + 1}')
    ax_pipe.set_title(f'{title}: brake pipe [bar gauge]')
    ax_cyl.set_title('brake cylinder [bar gauge]')


def figure(rows: int, cols: int, size):
    fig = Figure(figsize=size, dpi=100, layout='constrained')
    FigureCanvasAgg(fig)
    return fig, np.atleast_2d(fig.subplots(rows, cols, sharex='col'))


def finish(fig, axes, name):
    for ax in axes.flat:
        ax.grid(True, alpha=0.35)
        ax.legend(fontsize=7, loc='best')
    for ax in axes[-1]:
        ax.set_xlabel('time t [s]')
    fig.savefig(os.path.join(FIGURES, name))
    print(f'wrote docs/figures/{name}')


def accelerators() -> None:
    fig, axes = figure(2, 2, (14.0, 8.0))
    print('| 1022 m passenger, emergency at 1 s | 1 bar drop speed [m/s] | '
          'last cylinder 95 % at [s] after the emergency |')
    print('| --- | ---: | ---: |')
    for col, on in enumerate((True, False)):
        cfg = scenario('passenger_pneumatic_40.yaml')
        if not on:     # the library's coaches have them: switch them off per vehicle
            cfg.consist.fields['emergency_accelerator'][:] = 0.0
        r = run(cfg, 25.0)
        along(axes[0, col], axes[1, col], r,
              f'accelerators {"on" if on else "off"}')
        drop = first(r['t'], r['pipe'] < r['pipe'][0] - 1.0)
        speed = propagation_speed(cfg.consist['length'], drop)
        cyl = r['cyl'][:, -1]
        t95 = first(r['t'], (cyl >= 0.95 * 3.8)[:, None])[0] - 1.0
        print(f'| accelerators {"on" if on else "off"} | {speed:.0f} | {t95:.1f} |')
    finish(fig, axes, 'brake_accelerators.png')


def ep_ecp() -> None:
    fig, axes = figure(2, 2, (14.0, 8.0))
    steps = [(1.0, 0.5), (6.0, 0.25), (11.0, 1.0), (16.0, 0.0)]
    for col, system in enumerate(('ep', 'ecp')):
        cfg = scenario(f'passenger_{system}_16.yaml')
        r = run(cfg, 22.0, emergency_at=None, ep=steps)
        along(axes[0, col], axes[1, col], r, f'brake_system {system}, commands {steps}')
        start = first(r['t'], r['cyl'] > 0.05)
        print(f'{system}: cylinders start {start.min() - 1.0:.2f}-{start.max() - 1.0:.2f} s '
              'after the first command')
    finish(fig, axes, 'brake_ep_ecp.png')


def dp() -> None:
    fig, axes = figure(3, 2, (14.0, 11.0))
    print('| 1500 m freight, emergency at 1 s | last vehicle applied [s] | '
          'max tension [kN] | max compression [kN] |')
    print('| --- | ---: | ---: | ---: |')
    for col, name in enumerate(('freight_1500m.yaml', 'freight_1500m_dp.yaml')):
        r = run(scenario(name), 60.0)
        along(axes[0, col], axes[1, col], r, name)
        applied = first(r['t'], r['cyl'] > 0.1).max() - 1.0
        axes[2, col].plot(r['t'], r['F'].max(axis=1), label='max tension over the train')
        axes[2, col].plot(r['t'], r['F'].min(axis=1), label='max compression over the train')
        axes[2, col].set_title('in-train (coupler) force extremes [kN] (> 0 tension)')
        print(f'| {name} | {applied:.1f} | {r["F"].max():.0f} | {-r["F"].min():.0f} |')
    finish(fig, axes, 'brake_dp.png')


def main() -> int:
    accelerators()
    ep_ecp()
    dp()
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
