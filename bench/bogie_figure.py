"""
Per-bogie wheelsets and WSP on the FLIRT (config/emu_flirt_4_wsp.yaml): figure and table.

Runs the shipped scenario (full service from 160 km/h, builtin blending, the last 1.5 km on
0.06 adhesion, two wheelsets per car with the builtin WSP per bogie, rail conditioning 0.2)
and its variants through the simulator (``TrainSimulator``, the offline command's model),
until the unit stops, and prints a markdown table: stopping distance and time from the
demand, the longest sliding time of a car, the creep work (energy into the rail), the
regenerated share of the energy and the energy balance's residue. Writes
``docs/figures/multiple_units_bogies.png``: the leading car's speed, its two bogies' wheel
speeds and cylinder pressures over the stop.

``python bench/bogie_figure.py``
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
from train_dynamics.physics.train import TrainSimulator  # noqa: E402

SCENARIO = os.path.join(ROOT, 'config', 'emu_flirt_4_wsp.yaml')
FIGURE = os.path.join(ROOT, 'docs', 'figures', 'multiple_units_bogies.png')
#: name -> overrides of the shipped scenario
VARIANTS = {
    'dry rail (emu_flirt_4.yaml)': {
        'bogie_wheelsets': False, 'wsp': 'none', 'rail_conditioning': 0.0,
        'track_adhesion': [], 'track_adhesion_positions': []},
    'one wheelset per car, WSP': {'bogie_wheelsets': False, 'wheelsets': True,
                                  'rail_conditioning': 0.0},
    'per bogie, WSP, no conditioning': {'rail_conditioning': 0.0},
    'per bogie, WSP, conditioning 0.2 (shipped)': {},
    'per bogie, no WSP, conditioning 0.2': {'wsp': 'none'},
}


def run(overrides: dict, every: float = 0.02, t_end: float = 200.0) -> dict:
    """Run the scenario with ``overrides`` until every car stops; the figures and a trace."""
    cfg = load_param_file(SCENARIO)
    cfg = cfg.replace(demand_schedule_times=[], demand_schedule_values=[], **overrides)
    sim = TrainSimulator(cfg)
    mass = float(sim.inertia.sum())
    e0 = sim.kinetic_energy + sim.wheel_kinetic_energy
    sim.advance_to(1.0)
    x0 = float(sim.x[0])
    sim.bcu.set_demand(1.0)
    rows = []
    while np.any(sim.v > 0.0) and sim.t < t_end:
        sim.advance_to(sim.t + every)
        u = sim.wheelset_speeds
        p = sim.bogie_cylinder_pressures if sim.bogies else np.repeat(sim.cylinder_pressure, 2)
        u = u[:2] if sim.bogies else np.repeat(u[:1], 2)
        rows.append((sim.t, sim.v[0], u[0], u[1], p[0], p[1]))
    e1 = sim.kinetic_energy + sim.wheel_kinetic_energy
    work = (sim.work_wheel_brake + sim.work_creep + sim.work_coupler + sim.work_resistance
            - sim.work_traction - sim.work_gravity + (0.0 if sim.wheelsets else sim.work_brake))
    return {'distance': float(sim.x[0]) - x0, 'time': sim.t - 1.0,
            'sliding': float(np.max(sim.sliding_time)), 'creep': sim.work_creep,
            'regen': -sim.work_traction / e0, 'residue': (e0 - e1 - work) / e0,
            'stopped': bool(np.all(sim.v == 0.0)), 'trace': np.array(rows), 'mass': mass}


def figure(trace: np.ndarray, path: str) -> None:
    """Car 1: speed and both bogies' wheel speeds [m/s], cylinder pressures [bar]."""
    fig = Figure(figsize=(9, 6.5))
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    t = trace[:, 0]
    ax1.plot(t, trace[:, 1], 'k', lw=1.2, label='car 1 speed')
    ax1.plot(t, trace[:, 2], lw=0.8, label='bogie 1 wheel (leading)')
    ax1.plot(t, trace[:, 3], lw=0.8, label='bogie 2 wheel (trailing)')
    ax1.set_ylabel('speed [m/s]')
    ax1.legend(loc='upper right')
    ax1.grid(alpha=0.3)
    ax2.plot(t, trace[:, 4] / 1e5, lw=0.8, label='bogie 1 cylinder')
    ax2.plot(t, trace[:, 5] / 1e5, lw=0.8, label='bogie 2 cylinder')
    ax2.set_ylabel('pressure [bar gauge]')
    ax2.set_xlabel('t [s]')
    ax2.legend(loc='upper right')
    ax2.grid(alpha=0.3)
    fig.suptitle('FLIRT, full service from 160 km/h onto 0.06 adhesion: per-bogie WSP')
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main() -> int:
    """Print the table; write the figure of the shipped scenario."""
    print('| run | stop from the demand | longest sliding (car) | creep work | regenerated '
          '| energy residue |')
    print('| --- | ---: | ---: | ---: | ---: | ---: |')
    for name, overrides in VARIANTS.items():
        r = run(overrides)
        stop = (f"{r['distance']:.0f} m / {r['time']:.1f} s" if r['stopped']
                else f"not stopped ({r['distance']:.0f} m)")
        print(f"| {name} | {stop} | {r['sliding']:.1f} s | {r['creep'] / 1e6:.2f} MJ "
              f"| {100 * r['regen']:.1f} % | {r['residue']:.1e} |")
        if not overrides:
            figure(r['trace'], FIGURE)
    return 0


if __name__ == '__main__':
    sys.exit(main())
