"""
``train-dynamics compare``: the paper's comparison of the coupler friction models.

The same scenario (parameter file, brake input as for ``simulate``) with the sign model at several
integration steps and the tanh model at several scale factors u, sampled on the runner's output
grid (:func:`train_dynamics.simulation.runner.iter_output_steps`) at ``--sample-rate``, at most
once per integration step, and summarised as they run
(:class:`train_dynamics.recording.summary.RunSummary`: memory independent of the duration; curves
min/max-decimated beyond 20000 samples per run; the zoom at full rate; a sign run whose own densest
window is not the chosen one is run again up to its end). Writes one figure per quantity and a zoom
on the window where the sign model chatters most
(:func:`train_dynamics.recording.plots.plot_comparison`), and prints a table: max / min coupler
force and sign changes of ydot per second of every run.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import time

from train_dynamics.cli.errors import check_runnable, CliError, EXIT_OK, warn
from train_dynamics.cli.output import output_dir, remove_created
from train_dynamics.cli.progress import progress_bar
from train_dynamics.cli.scenario import brake_inputs, check_duration, load_config
from train_dynamics.physics.config import ConfigError, PARAMETERS, SimConfig
from train_dynamics.recording.plots import plot_comparison
from train_dynamics.recording.summary import densest, RunSummary, Window, zoom_window
from train_dynamics.simulation.runner import InputSchedule, iter_output_steps, run_simulation

#: width of a run's label in the table and the progress bar
LABEL_WIDTH = 34
#: [s] the zoom figure's window
ZOOM_WIDTH = 0.2


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``compare`` command and its options."""
    c = sub.add_parser('compare', help='sign vs tanh (several u), sign at several steps',
                       description="The paper's comparison: the same scenario with the sign "
                       'model at several integration steps and the tanh model at several scale '
                       'factors u; one figure per quantity and a table on stdout.')
    c.add_argument('--params', required=True, metavar='FILE', help='ROS 2 parameter file')
    c.add_argument('--input', metavar='BAG', help='brake-input bag (as for simulate)')
    c.add_argument('--duration', required=True, type=float, metavar='T',
                   help='simulated time [s], > 0')
    c.add_argument('--output', required=True, metavar='DIR', help='directory for the PNGs')
    c.add_argument('--scale-factors', default='100,1000,10000', metavar='U,U,...',
                   help='tanh scale factors u [s/m] (default 100,1000,10000)')
    c.add_argument('--steps', default=None, metavar='H,H,...',
                   help="integration steps [s] for the sign model (default: the file's step "
                   'and a tenth of it)')
    c.add_argument('--sample-rate', type=float, default=10000.0, metavar='HZ',
                   help='sampling of the curves [Hz] (default 10000, at most one per step)')
    c.add_argument('--namespace', default='', metavar='NS', help='input topics namespace')
    c.add_argument('-q', '--quiet', action='store_true', help='no progress bar, no file list')
    c.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    """Run ``compare``; return the exit status."""
    if not args.sample_rate > 0 or not math.isfinite(args.sample_rate):
        raise CliError('--sample-rate must be > 0')
    duration = check_duration(args.duration)
    base = load_config(args.params)
    check_runnable(base, args.params)
    inputs = brake_inputs(args, base)
    us = _parse_floats(args.scale_factors, '--scale-factors')
    h0 = float(base.integration_step)
    steps = _parse_floats(args.steps, '--steps') if args.steps else [h0, h0 / 10.0]
    variants = _variants(base, steps, us)
    created = output_dir(args.output)
    try:
        return _compare(args, base, inputs, variants, duration, steps)
    except BaseException:
        remove_created(created)
        raise


def _compare(args: argparse.Namespace, base: SimConfig, inputs: InputSchedule,
             variants: list[tuple[str, SimConfig]], duration: float, steps: list[float]) -> int:
    """Run every variant streaming (:class:`RunSummary`), then draw and print."""
    h0 = float(base.integration_step)
    default = zoom_window(duration / 2, 0, duration, ZOOM_WIDTH)
    summaries, walls = [], []
    window = None
    for label, cfg in variants:
        is_sign = label.startswith('sign')
        if not is_sign and window is None:          # the sign runs (first) are done
            window = _chosen_window(summaries, default)
        summary, wall = _run(label, cfg, duration, inputs, args, track=is_sign,
                             capture=default if window is None else window)
        summaries.append(summary)
        walls.append(wall)
    if window is None:
        window = _chosen_window(summaries, default)
    runs, zooms, table, decimated = [], [], [], False
    for (label, cfg), summary, wall in zip(variants, summaries, walls):
        hist, dec = summary.history(label)
        decimated |= dec
        runs.append((label, hist))
        data = summary.zoom_data(window)
        if data is None:                             # another run's window: run it again
            again, _ = _run(f'{label} (zoom)', cfg, window.t1, inputs, args, capture=window)
            data = again.zoom_data(window)
        zooms.append(data)
        table += [(label, name, fmax * 1e-3, fmin * 1e-3, ch, wall)
                  for name, fmax, fmin, ch in summary.table()]
    sampling = ('curves sampled at every integration step'
                if 1.0 / args.sample_rate <= min(steps + [h0]) * (1 + 1e-9) else
                f'curves sampled every {_fmt_step(1.0 / args.sample_rate)} (or step)')
    if decimated:
        sampling += ', drawn as min/max envelopes'
    title = (f'{base.n_coaches} coaches, {Path(args.params).name}, brake input: '
             f'{inputs.source}; {sampling}')
    out = Path(args.output)
    try:
        paths = plot_comparison(runs, out, title=title, zoom=(window.t0, window.t1, window.j),
                                zoom_data=zooms)
    except OSError as exc:
        raise CliError(f'cannot write figures to {out}: {exc.strerror or exc}') from None
    _print_table(table)
    if not args.quiet:
        for p in paths:
            print(p)
    return EXIT_OK


def _chosen_window(summaries: list[RunSummary], default: Window) -> Window:
    """Return the zoom window: where a sign run flips ydot most (first wins), or ``default``."""
    found = densest(summaries)
    if found is None:
        return default
    return summaries[found[0]].best_window()


def _variants(base: SimConfig, steps: list[float], us: list[float]
              ) -> list[tuple[str, SimConfig]]:
    """Return (label, parameters) of every run: sign at each step, tanh at each u."""
    h0 = float(base.integration_step)
    changes = [(f'sign, h = {_fmt_step(h)}', {'model_type': 'sign', 'integration_step': h,
                                              'publish_rate': _grid_rate(base, h)})
               for h in steps]
    changes += [(f'tanh, u = {u:g} s/m, h = {_fmt_step(h0)}',
                 {'model_type': 'tanh', 'scale_factor': u}) for u in us]
    variants = []
    for label, change in changes:
        try:
            variants.append((label, base.replace(**change)))
        except ConfigError as exc:
            raise CliError(f'{label}: {exc}') from None
    return variants


def _grid_rate(base: SimConfig, h: float) -> float:
    """
    Return a publish_rate [Hz] on the grid of step ``h`` [s] (the file's when it is).

    compare samples at ``--sample-rate``, not at publish_rate; this only keeps the validator's
    exact-grid rule (1 / publish_rate a whole number of steps) for steps given by --steps.
    """
    rate = float(base.publish_rate)
    k = max(1, round(1.0 / (rate * h)), math.ceil(1.0 / (PARAMETERS['publish_rate'].high * h)))
    return rate if abs(1.0 / (rate * h) - k) <= 1e-9 * k else 1.0 / (k * h)


def _run(label: str, cfg: SimConfig, duration: float, inputs: InputSchedule,
         args: argparse.Namespace, *, track: bool = False,
         capture: Window | None = None) -> tuple[RunSummary, float]:
    """Run one variant, summarised as it goes; return its summary and wall time [s]."""
    h = float(cfg.integration_step)
    rate = min(args.sample_rate, 1.0 / h)
    summary = RunSummary(cfg.n_coaches, duration, math.floor(duration * rate + 1e-9) + 1,
                         1.0 / rate, width=ZOOM_WIDTH, track=track, capture=capture)
    t0 = time.monotonic()
    sim = run_simulation(cfg, duration, inputs.for_step(h), on_sample=summary.sample,
                         sample_steps=iter_output_steps(duration, rate, h),
                         progress=progress_bar(f'{label:<{LABEL_WIDTH}}', duration, args.quiet))
    summary.finish()
    wall = time.monotonic() - t0
    if sim.fault is not None:
        warn(f'{label}: simulation fault: {sim.fault}')
    return summary, wall


def _print_table(table: list[tuple]) -> None:
    """Print one row per run and coupler: max / min F [kN], ydot sign changes/s, wall time."""
    w = LABEL_WIDTH
    print(f'{"run":<{w}} {"coupler":<10} {"max F [kN]":>11} {"min F [kN]":>11} '
          f'{"ydot sign changes/s":>20} {"wall [s]":>9}')
    for label, name, fmax, fmin, ch, wall in table:
        print(f'{label:<{w}} {name:<10} {fmax:11.2f} {fmin:11.2f} {ch:20.1f} {wall:9.2f}')


def _parse_floats(text: str, what: str) -> list[float]:
    """Return the comma-separated numbers > 0 of option ``what``."""
    try:
        vals = [float(v) for v in text.split(',') if v.strip()]
    except ValueError:
        raise CliError(f'{what}: expected comma-separated numbers, got {text!r}') from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise CliError(f'{what}: expected numbers > 0, got {text!r}')
    return vals


def _fmt_step(h: float) -> str:
    return f'{h * 1e3:g} ms'
