"""
Accuracy against the independent reference, per setting: error and cost of each.

Four cases, each run at the default setting (the multirate refinement of the 2 ms step), the
plain fixed step, error control and other multirate settings, and compared with
:func:`train_dynamics.physics.chain_reference.solve_chain` (Radau, rtol 1e-9, events at the
coupler law's breakpoints, restarted at every input instant) fed the same inputs:

- ``paper``: the paper's 3 coaches, head pipe vented at t = 1 s (closed-form brake forces:
  the filling table from 1 s + the pipe delay of each coach), 0-20 s;
- ``khz_unequal``: 4 coaches 45/30/60/25 t, tanh u = 700, cylinder pressures replayed at
  1 kHz (edges every few tens of ms, half of them between the 2 ms ticks), 0-3 s;
- ``paper30``: the paper's scenario with 30 coaches (default strokes: buffers block), 0-8 s;
- ``mixed_freeplay``: a 90 t locomotive and 7 loaded/empty wagons (80/22 t), free play
  4-12 mm, strokes 20-30 mm, blocked stiffness 5e7-8e7 N/m, brakes applied front to rear
  in three steps (run-in through the free play to blocking), 0-4 s.

Figures: every coupler-force sample (every 2 ms) and displacement sample: max |ours - ref| /
max |ref| [%]; the peak force's error [%]; chain steps; wall time of the run [s]
(in-process, 2 ms read-out; shared machine: compare within a table only).
``python bench/accuracy.py [--case NAME]``; the table is kept in
``bench/results/accuracy_results.md``.

``--robust`` adds the long-train metrics of the accuracy contract (docs/integrators.md,
:mod:`train_dynamics.physics.comparison`, on the 10 ms samples): the +-10 ms tube, 1 s window
and per-coupler envelopes, damage-equivalent load (rainflow, m = 4) and the count of cycles
above 10 % of the peak; and, first, the sensitivity floor: the same metrics between the
reference and the reference of the same train with one coach (the middle one) 1e-3 heavier.
Cases ``paper100`` (100 coaches, 0-20 s) and ``paper1000`` (1000 coaches, 0-20 s) exist for
it (the references take minutes to tens of minutes).
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from train_dynamics.physics import comparison, replay_cases
from train_dynamics.physics.chain_reference import ChainLaw, solve_chain
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.config.budgets import max_period_steps
from train_dynamics.physics.config.table import MULTIRATE_REVERSAL_WEIGHT, MULTIRATE_TOLERANCE
from train_dynamics.physics.kernel.layout import COUPLER
from train_dynamics.physics.reference import HeadVentBraking
from train_dynamics.physics.train import TrainSimulator

#: the plain fixed step: no multirate refinement
PLAIN = {'multirate_tolerance': 0.0}

#: (label, overrides): the default first
SETTINGS = (
    (f'default (multirate {MULTIRATE_TOLERANCE:.0e} + reversal weight '
     f'{MULTIRATE_REVERSAL_WEIGHT:g})'.replace('e-0', 'e-'), {}),
    ('fixed 2 ms', PLAIN),
    ('fixed 1 ms', {**PLAIN, 'integration_step': 1e-3}),
    ('fixed 0.5 ms', {**PLAIN, 'integration_step': 5e-4}),
    ('fixed 0.1 ms', {**PLAIN, 'integration_step': 1e-4}),
    ('tolerance 3e-3', {'integration_tolerance': 3e-3}),
    ('tolerance 2e-3', {'integration_tolerance': 2e-3}),
    ('tolerance 1e-3', {'integration_tolerance': 1e-3}),
    ('tolerance 1e-4', {'integration_tolerance': 1e-4}),
    ('tolerance 1e-5', {'integration_tolerance': 1e-5}),
) + tuple(
    (f'multirate {tol:.0e}'.replace('e-0', 'e-'),
     {'multirate_tolerance': tol, 'multirate_reversal_weight': 0.0})
    for tol in (1e-2, 1e-3, 3e-4, 2e-4, 1e-4)
) + tuple(
    (f'multirate {tol:.0e}'.replace('e-0', 'e-') + f' + reversal weight {w:g}',
     {'multirate_tolerance': tol, 'multirate_reversal_weight': w})
    for tol in (1e-2, 3e-3, 1e-3) for w in (10.0, 5.0, 3.0, 2.0, 1.0, 0.5, 0.3, 0.1, 0.03)
) + (('multirate 3e-4 + reversal weight 1',
      {'multirate_tolerance': 3e-4, 'multirate_reversal_weight': 1.0}),)
DT = 0.002      # [s] read-out


def _paper(n=3, t_end=20.0):
    base = {'num_coaches': n}

    def make(**o):
        sim = TrainSimulator(SimConfig.from_dict({**base, **o}))
        sim.schedule(1.0, lambda: sim.set_head_pipe_pressure(0.0))
        return sim

    cfg = SimConfig.from_dict(base)
    brake = HeadVentBraking(cfg, 1.0)
    steps = brake.steps(t_end)
    return make, steps, brake, t_end, cfg.initial_speed


def _khz_unequal(t_end=3.0, seed=1):
    cfg = replay_cases.khz_config()
    times, levels = replay_cases.khz_pressures(cfg, t_end, seed, 0.02)

    def make(**o):
        sim = TrainSimulator(replay_cases.khz_config(**o))
        for t, p in zip(times, levels):
            sim.schedule(t, lambda p=p, sim=sim: sim.set_cylinder_pressure(p))
        return sim

    forces = replay_cases.khz_braking_forces(cfg, levels)
    return make, (times, forces), None, t_end, cfg.initial_speed


def _mixed_freeplay(t_end=4.0):
    masses = [90000.0, 80000.0, 22000.0, 80000.0, 22000.0, 22000.0, 80000.0, 22000.0]
    rng = np.random.default_rng(3)
    gap, stroke, kb = (rng.uniform(0.004, 0.012, 7), rng.uniform(0.02, 0.03, 7),
                       rng.uniform(5e7, 8e7, 7))
    base = {'masses': masses, 'brake_input': 'cylinder_per_coach', 'initial_speed': 20.0}
    cfg = SimConfig.from_dict(base)
    pmax = cfg.max_cylinder_pressure
    times = np.array([0.0, 0.3, 0.9, 1.5])
    on = np.array([[0] * 8, [1] * 2 + [0] * 6, [1] * 4 + [0] * 4, [1] * 8], float)

    def make(**o):
        sim = TrainSimulator(SimConfig.from_dict({**base, **o}))
        for row, value in ((COUPLER.GT, gap), (COUPLER.GC, gap), (COUPLER.ST, stroke),
                           (COUPLER.SC, stroke), (COUPLER.KB, kb)):
            sim.cpl[row] = value
        for t, p in zip(times, on * pmax):
            sim.schedule(t, lambda p=p, sim=sim: sim.set_cylinder_pressure(p))
        return sim

    full = cfg.adhesion_coefficient * np.array(masses) * cfg.gravity
    return make, (times, on * full), None, t_end, cfg.initial_speed


CASES = {'paper': _paper, 'khz_unequal': _khz_unequal, 'mixed_freeplay': _mixed_freeplay,
         'paper30': lambda: _paper(30, 8.0), 'paper100': lambda: _paper(100, 20.0),
         'paper1000': lambda: _paper(1000, 20.0)}

#: the sensitivity floor's perturbation: one coach's mass, relative
FLOOR_PERTURBATION = 1e-3
#: the robust metrics are taken on the output samples (10 ms), as a user's run has them
ROBUST_EVERY = 5


def _robust(F: np.ndarray, ref_F: np.ndarray, t_eval: np.ndarray) -> dict:
    """Return the accuracy contract's metrics [% of the reference's peak] on 10 ms samples."""
    sel = slice(ROBUST_EVERY - 1, None, ROBUST_EVERY)
    found = comparison.all_metrics(t_eval[sel], F[sel], ref_F[sel])
    return {key: 100.0 * value for key, value in found.items()}


def _floor(name: str, t_eval: np.ndarray, ref_F: np.ndarray) -> dict:
    """Return the robust metrics between the reference and a one-coach-heavier reference."""
    make, steps, brake, t_end, v0 = CASES[name]()
    sim = make()
    inertia = np.array(sim.inertia, dtype=float)
    inertia[sim.n // 2] *= 1.0 + FLOOR_PERTURBATION
    law = ChainLaw.of_simulator(sim)
    perturbed = solve_chain(inertia, law, v0, steps, t_eval, brake_of_t=brake)
    label = f'reference, coach {sim.n // 2 + 1} mass x (1 + {FLOOR_PERTURBATION:g})'
    return {'case': name, 'setting': label,
            'force_pct': 100.0 * np.abs(perturbed.F - ref_F).max() / np.abs(ref_F).max(),
            'disp_pct': float('nan'), 'peak_pct': float('nan'), 'steps': 0, 'groups': 0,
            'substeps': 0, 'wall_s': float('nan'), 'fault': '',
            **_robust(perturbed.F, ref_F, t_eval)}


def run_case(name: str, only=None, robust: bool = False) -> list[dict]:
    """Return one row per setting of case ``name`` (errors in %, steps, wall [s])."""
    make, steps, brake, t_end, v0 = CASES[name]()
    t_eval = np.round(np.arange(1, int(round(t_end / DT)) + 1) * DT, 10)
    sim = make()
    ref = solve_chain(sim.inertia, ChainLaw.of_simulator(sim), v0, steps, t_eval,
                      brake_of_t=brake)
    peak_f = np.abs(ref.F).max()
    peak_y = np.abs(ref.y).max()
    rows = [_floor(name, t_eval, ref.F)] if robust else []
    budget = {'integration_max_steps': max_period_steps(sim.n), 'publish_rate': 1.0 / DT}
    for label, over in SETTINGS:
        if only and not any(label.startswith(o) for o in only):
            continue
        opts = {**over, **(budget if 'integration_tolerance' in over else {})}
        sim = make(**opts)
        F = np.empty_like(ref.F)
        Y = np.empty_like(ref.y)
        t0 = time.perf_counter()
        for k, t in enumerate(t_eval):
            sim.advance_to(t)
            F[k] = sim.coupler_force
            Y[k] = sim.y
        wall = time.perf_counter() - t0
        stats = sim.integration_stats
        rows.append({'case': name, 'setting': label,
                     'force_pct': 100.0 * np.abs(F - ref.F).max() / peak_f,
                     'disp_pct': 100.0 * np.abs(Y - ref.y).max() / peak_y,
                     'peak_pct': 100.0 * (np.abs(F).max() / peak_f - 1.0),
                     'steps': stats['steps'] if stats['adaptive'] else sim.steps,
                     'groups': stats['mr_groups'], 'substeps': stats['mr_substeps'],
                     'wall_s': wall, 'fault': sim.fault,
                     **(_robust(F, ref.F, t_eval) if robust else {})})
    return rows


ROBUST_COLUMNS = (('tube_10ms', 'tube +-10 ms'), ('window_envelope_1s', '1 s windows'),
                  ('coupler_envelope', 'per-coupler envelope'), ('del_m4', 'DEL (m = 4)'),
                  ('cycles_above_10pct', 'cycles > 10 % [% of count]'))


def robust_table(rows: list[dict]) -> str:
    """Return the rows' accuracy-contract metrics as a markdown table."""
    head = ' | '.join(label for _, label in ROBUST_COLUMNS)
    out = [f'| case | setting | worst sample | {head} | wall [s] |',
           '|---|---|' + '---|' * (len(ROBUST_COLUMNS) + 2)]
    for r in rows:
        cells = ' | '.join(f'{r[key]:.3f}' for key, _ in ROBUST_COLUMNS)
        out.append(f"| {r['case']} | {r['setting']} | {r['force_pct']:.3f} | {cells} | "
                   f"{r['wall_s']:.2f} |")
    return '\n'.join(out)


def table(rows: list[dict]) -> str:
    """Return the rows as a markdown table."""
    out = ['| case | setting | force samples [% of peak] | displacements [% of peak] | '
           'peak [%] | chain steps | groups sub-stepped | sub-steps | wall [s] |',
           '|---|---|---|---|---|---|---|---|---|']
    for r in rows:
        out.append(f"| {r['case']} | {r['setting']} | {r['force_pct']:.3f} | "
                   f"{r['disp_pct']:.3f} | {r['peak_pct']:+.3f} | {r['steps']} | "
                   f"{r['groups']} | {r['substeps']} | {r['wall_s']:.2f} |")
    return '\n'.join(out)


def main(argv=None) -> int:
    """Run every case and print the table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument('--case', choices=sorted(CASES), action='append')
    ap.add_argument('--setting', action='append', help='only the settings starting with this')
    ap.add_argument('--robust', action='store_true',
                    help="the accuracy contract's long-train metrics and the sensitivity floor")
    args = ap.parse_args(argv)
    rows = []
    default_cases = [c for c in CASES if c not in ('paper100', 'paper1000')]
    for name in args.case or default_cases:
        rows += run_case(name, args.setting, args.robust)
    print(robust_table(rows) if args.robust else table(rows))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
