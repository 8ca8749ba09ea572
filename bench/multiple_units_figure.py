"""
Figures of the multiple units with builtin blending (docs/multiple_units.md).

Runs the shipped units (config/emu_flirt_4.yaml, config/hs_ice3_8.yaml) through the
offline run loop and writes ``docs/figures/multiple_units_<name>.png``: the demanded and
achieved deceleration, and the train's ED, friction and track brake forces over a stop;
``multiple_units_trip.png``: the FLIRT at half of full service with the ED lost at 15 s;
``multiple_units_track_brake.png``: its emergency with magnetic track brakes on the two
middle sections (50 kN at rest on each: a guess for illustration, not part of the shipped
unit). Prints the numbers of the tables.
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

FIGURES = os.path.join(ROOT, 'docs', 'figures')


def run(cfg, duration: float, events=(), every: float = 0.05, consist=None) -> dict:
    """Sample the brake control unit's forces and decelerations every ``every`` s."""
    if consist is not None:
        cfg = cfg.replace(consist_file=consist)
    sim = TrainSimulator(cfg)
    pending = sorted(events)
    rows = []
    mass = float(sim.inertia.sum())
    for k in range(int(round(duration / every))):
        t = k * every
        while pending and pending[0][0] <= t + 1e-9:
            _, kind, value = pending.pop(0)
            getattr(sim.bcu, kind)(value)
        sim.advance_to(t + every)
        b = sim.bcu
        ed, fb, tr = b.ed_force().sum(), sim.brake_force.sum(), b.track.force.sum()
        rows.append((sim.t, sim.v.mean(), b.demanded_deceleration, (ed + fb + tr) / mass,
                     ed, fb, tr))
    r = np.array(rows)
    keys = ('t', 'v', 'demand', 'achieved', 'ed', 'friction', 'track')
    out = {k: r[:, i] for i, k in enumerate(keys)}
    out['regen'] = -sim.work_traction
    out['friction_energy'] = sim.work_brake
    out['ke0'] = 0.5 * mass * float(cfg.initial_speed) ** 2
    out['x'] = float(sim.x[0])
    return out


def figure(data: dict, title: str, path: str) -> None:
    """Write the forces [kN] and decelerations [m/s^2] of ``data`` to ``path``."""
    fig = Figure(figsize=(9, 6))
    FigureCanvasAgg(fig)
    a1, a2 = fig.subplots(2, 1, sharex=True)
    t = data['t']
    a1.plot(t, data['ed'] * 1e-3, label='ED (regenerative)')
    a1.plot(t, data['friction'] * 1e-3, label='friction (disc)')
    if data['track'].any():
        a1.plot(t, data['track'] * 1e-3, label='magnetic track brake')
    a1.set_ylabel('train brake force [kN]')
    a1.legend(loc='best')
    a1.grid(True, alpha=0.3)
    a2.plot(t, data['demand'], '--', label='demanded (jerk-limited)')
    a2.plot(t, data['achieved'], label='achieved (brake forces / inertial mass)')
    a2.set_ylabel('deceleration [m/s^2]')
    a2.set_xlabel('t [s]')
    a2.legend(loc='best')
    a2.grid(True, alpha=0.3)
    ax = a2.twinx()
    ax.plot(t, data['v'] * 3.6, color='0.6', lw=0.8)
    ax.set_ylabel('speed [km/h] (grey)')
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main() -> None:
    """Run the stops, write the figures, print the numbers."""
    flirt = load_param_file(os.path.join(ROOT, 'config', 'emu_flirt_4.yaml'))
    ice = load_param_file(os.path.join(ROOT, 'config', 'hs_ice3_8.yaml'))
    for name, cfg, dur, title in (
            ('flirt', flirt, 45.0, 'Stadler FLIRT (RABe 523): full service from 160 km/h'),
            ('ice3', ice, 100.0, 'ICE 3 (class 403): full service from 300 km/h')):
        cfg = cfg.replace(demand_schedule_times=[], demand_schedule_values=[])
        d = run(cfg, dur, [(1.0, 'set_demand', 1.0)])
        figure(d, title, os.path.join(FIGURES, f'multiple_units_{name}.png'))
        print(f"{name}: x {d['x']:.1f} m, regenerated {d['regen'] / d['ke0']:.3f}, friction "
              f"{d['friction_energy'] / d['ke0']:.3f} of the kinetic energy")
    cfg = flirt.replace(demand_schedule_times=[], demand_schedule_values=[])
    d = run(cfg, 40.0, [(1.0, 'set_demand', 0.5), (15.0, 'set_ed_trip', True)])
    figure(d, 'FLIRT: half of full service, ED lost at 15 s',
           os.path.join(FIGURES, 'multiple_units_trip.png'))
    text = open(os.path.join(ROOT, 'config', 'consist_flirt_4.yaml')).read().replace(
        '    rotating_mass_factor: 0.04\n',
        '    rotating_mass_factor: 0.04\n    track_brake_force: 50000.0\n')
    consist = os.path.join(FIGURES, '..', '..', 'build_mu_consist.yaml')
    with open(consist, 'w') as f:
        f.write(text)
    try:
        for label, ev in (('track', [(1.0, 'set_emergency', True)]),):
            d = run(cfg, 35.0, ev, consist=os.path.abspath(consist))
            figure(d, 'FLIRT: emergency from 160 km/h with magnetic track brakes (guessed)',
                   os.path.join(FIGURES, 'multiple_units_track_brake.png'))
            print(f"{label}: x {d['x']:.1f} m")
        d = run(cfg, 35.0, [(1.0, 'set_emergency', True)])
        print(f"emergency without track brakes: x {d['x']:.1f} m")
    finally:
        os.remove(consist)


if __name__ == '__main__':
    main()
