"""
``train-dynamics compare``: the paper's comparison of the coupler friction models.

The same scenario (parameter file, brake input as for ``simulate``) with the sign model at
several integration steps and the tanh model at several scale factors u, run in memory
(:class:`train_dynamics.recording.sinks.ArraySink`) and sampled on the runner's output grid
(:func:`train_dynamics.physics.runner.iter_output_steps`) at ``--sample-rate``, at most once
per integration step. Writes one figure per quantity and a zoom on the window where the sign
model chatters most (:func:`train_dynamics.recording.plots.plot_comparison`), and prints a
table: max / min coupler force and sign changes of ydot per second of every run.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path
import time

import numpy as np

from train_dynamics.cli.errors import CliError, EXIT_ERROR, EXIT_OK, warn
from train_dynamics.cli.progress import progress_bar
from train_dynamics.cli.scenario import brake_inputs, check_duration, load_config
from train_dynamics.physics.parameters import ConfigError, SimConfig
from train_dynamics.physics.runner import BrakeInputs, output_steps, run_simulation
from train_dynamics.recording.history import History, sign_changes_per_second
from train_dynamics.recording.plots import plot_comparison
from train_dynamics.recording.sinks import ArraySink

#: width of a run's label in the table and the progress bar
LABEL_WIDTH = 34


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
    inputs = brake_inputs(args, base)
    us = _parse_floats(args.scale_factors, '--scale-factors')
    h0 = float(base.integration_step)
    steps = _parse_floats(args.steps, '--steps') if args.steps else [h0, h0 / 10.0]
    variants = _variants(base, steps, us)
    runs, table = [], []
    for label, cfg in variants:
        hist, wall = _run(label, cfg, duration, inputs, args)
        runs.append((label, hist))
        c = hist.couplers
        changes = sign_changes_per_second(c.t, c.velocity, tol=0.0)
        for j, name in enumerate(c.names):
            table.append((label, name, float(np.nanmax(c.effort[:, j])) * 1e-3,
                          float(np.nanmin(c.effort[:, j])) * 1e-3, changes[j], wall))
    sampling = ('curves sampled at every integration step'
                if 1.0 / args.sample_rate <= min(steps + [h0]) * (1 + 1e-9) else
                f'curves sampled every {_fmt_step(1.0 / args.sample_rate)} (or step)')
    title = (f'{base.n_coaches} coaches, {Path(args.params).name}, brake input: '
             f'{inputs.source}; {sampling}')
    out = Path(args.output)
    try:
        paths = plot_comparison(runs, out, title=title, zoom=_zoom_window(runs, duration))
    except OSError as exc:
        raise CliError(f'cannot write figures to {out}: {exc.strerror or exc}',
                       EXIT_ERROR) from None
    _print_table(table)
    if not args.quiet:
        for p in paths:
            print(p)
    return EXIT_OK


def _variants(base: SimConfig, steps: list[float], us: list[float]
              ) -> list[tuple[str, SimConfig]]:
    """Return (label, parameters) of every run: sign at each step, tanh at each u."""
    h0 = float(base.integration_step)
    changes = [(f'sign, h = {_fmt_step(h)}', {'model_type': 'sign', 'integration_step': h})
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


def _run(label: str, cfg: SimConfig, duration: float, inputs: BrakeInputs,
         args: argparse.Namespace) -> tuple[History, float]:
    """Run one variant in memory; return its history and its wall time [s]."""
    h = float(cfg.integration_step)
    sink = ArraySink()
    t0 = time.monotonic()
    sim = run_simulation(cfg, duration, inputs.for_step(h), on_sample=sink.sample,
                         sample_steps=output_steps(duration, min(args.sample_rate, 1.0 / h), h),
                         progress=progress_bar(f'{label:<{LABEL_WIDTH}}', duration, args.quiet))
    wall = time.monotonic() - t0
    if sim.fault is not None:
        warn(f'{label}: simulation fault: {sim.fault}')
    return sink.history(sim, label), wall


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


def _zoom_window(runs: list[tuple[str, History]], duration: float,
                 width: float = 0.2) -> tuple[float, float, int]:
    """Return (t0, t1, coupler index): the ``width`` [s] where a sign run flips ydot most."""
    best, where, coupler = -1, duration / 2, 0
    for label, hist in runs:
        if not label.startswith('sign'):
            continue
        c = hist.couplers
        for j in range(c.velocity.shape[1]):
            s = np.sign(c.velocity[:, j])
            keep = s != 0
            ts, s = c.t[keep], s[keep]
            tf = ts[1:][s[1:] != s[:-1]]
            if tf.size == 0:
                continue
            counts = np.searchsorted(tf, tf + width) - np.arange(tf.size)
            k = int(np.argmax(counts))
            if counts[k] > best:
                span = tf[k:k + counts[k]]
                best, where, coupler = int(counts[k]), float(span[0] + span[-1]) / 2, j
    half = min(width, duration) / 2
    t0 = min(max(0.0, where - half), max(0.0, duration - 2 * half))
    return t0, t0 + 2 * half, coupler
