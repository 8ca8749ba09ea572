"""
``train-dynamics report``: the metrics of a recorded run, as summary.json, summary.md, figures.

Reads ``couplers`` and ``coaches`` from a bag written by ``train-dynamics simulate``, by the
node's ``record_bag`` or by ``ros2 bag record`` (the same topics) block by block, feeds them
into :class:`train_dynamics.physics.metrics.RunMetrics` (the code the sweep and the node run)
as they are read (:class:`train_dynamics.recording.metrics_report.MetricsFeed`; memory does not
depend on the bag's length, the figures' curves are bounded) and writes
:func:`train_dynamics.recording.metrics_report.write_report`'s files. The run's parameters
(limits, strokes and slacks, coupler stiffness for the dissipated energy) come from
``--params``, else from the bag's ``custom_data`` ``parameters`` (recorded by the node), else
the limits are off and the dissipated energy is not given. Strokes and slacks are those of the
parameters' consist (its vehicle ends in series), read as the simulator reads them.
"""
from __future__ import annotations

import argparse
from collections.abc import Callable
import json
import os
from pathlib import Path
import shutil
from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.cli.errors import CliError, EXIT_ERROR, EXIT_OK
from train_dynamics.cli.output import output_dir, remove_created
from train_dynamics.cli.scenario import load_config
from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.fatigue import FatigueFeed
from train_dynamics.physics.metrics import metrics_of_history, RunMetrics
from train_dynamics.quoting import clip
from train_dynamics.recording.bags import bag_info, BagError, shared_reader
from train_dynamics.recording.blending_metrics import blending_metrics
from train_dynamics.recording.history import History, natural_key, stream_history
from train_dynamics.recording.metrics_report import (MetricsFeed, stop_error_from_bag,
                                                     write_report)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``report`` command and its options."""
    r = sub.add_parser('report', help='metrics of a recorded run: summary.json, summary.md, '
                       'figures', description='Compute the run metrics of a bag (largest '
                       'tension/compression per coupler, blocking, decelerations, jerk, '
                       'stopping, energies, limit crossings) and write summary.json, '
                       'summary.md and figures.')
    r.add_argument('bag', metavar='BAG', help='rosbag2 holding couplers and coaches')
    r.add_argument('--output', required=True, metavar='DIR', help='directory for the report')
    r.add_argument('--params', metavar='FILE', help='parameter file of the run (default: the '
                   "bag's recorded parameters, when the node recorded it)")
    r.add_argument('--namespace', default='', metavar='NS', help='topics under this namespace')
    r.add_argument('--coupler-force-limit', type=float, metavar='N',
                   help='override coupler_force_limit [N] (0 = off)')
    r.add_argument('--jerk-limit', type=float, metavar='J',
                   help='override jerk_limit [m/s^3] (0 = off)')
    r.add_argument('--fatigue', action='store_true',
                   help='also count every coupler force history (rainflow, ASTM E1049-85) and '
                   'give each coupler its damage-equivalent load (slope m 4) and its cycles '
                   'above 10 %% of the peak (summary.json "fatigue")')
    r.add_argument('-q', '--quiet', action='store_true', help='print nothing')
    r.set_defaults(func=cmd_report)


class _FatigueTap:
    """The coupler forces of a bag as it is read, into a :class:`FatigueFeed` (last run)."""

    def __init__(self) -> None:
        self.feed: FatigueFeed | None = None

    def on_block(self, topic: str, t: np.ndarray, q: np.ndarray, names: list[str]) -> None:
        if topic != topics.COUPLERS_TOPIC:
            return
        if self.feed is None:
            self.feed = FatigueFeed(sorted(names, key=natural_key))
        where = {n: j for j, n in enumerate(names)}
        if set(where) != set(self.feed.names):
            raise CliError(f'{topic}: the couplers changed names within the run')
        self.feed.add(q[:, 2, [where[n] for n in self.feed.names]])

    def on_reset(self, topic: str) -> None:
        if topic == topics.COUPLERS_TOPIC:
            self.feed = None


def run_config(args: argparse.Namespace, info: dict[str, str]
               ) -> tuple[SimConfig | None, str]:
    """Return the run's parameters and where they came from (None: unknown)."""
    if args.params:
        return load_config(args.params), args.params
    text = info.get('parameters')
    if text:
        try:
            return SimConfig.from_dict(json.loads(text), ignore_unknown=True), 'bag custom_data'
        except (ValueError, ConfigError) as exc:
            raise CliError(f'{args.bag}: recorded parameters unusable ({clip(str(exc))}); '
                           'give --params') from None
    return None, 'none (limits off; give --params for limits and dissipated energy)'


def metrics_factory(cfg: SimConfig | None, **overrides: Any) -> Callable[[int], RunMetrics]:
    """Return ``make(n_vehicles)``: the run's RunMetrics (``overrides``: keyword arguments)."""
    def make(n: int) -> RunMetrics:
        if cfg is not None and cfg.n_coaches != n:
            raise CliError(f'the bag has {n} vehicles, the parameters {cfg.n_coaches}')
        return (RunMetrics.for_run(cfg, **overrides) if cfg is not None
                else RunMetrics(n, **overrides))
    return make


def report_metrics(hist: History, cfg: SimConfig | None, **overrides: Any) -> RunMetrics:
    """Return the metrics of a run loaded in memory (``overrides``: RunMetrics arguments)."""
    metrics = metrics_factory(cfg, **overrides)(len(hist.coaches.names))
    return metrics_of_history(hist, metrics)


def read_run(args: argparse.Namespace, overrides: dict[str, Any], curves: bool = True
             ) -> tuple[History, RunMetrics | None, str, dict | None]:
    """
    Read the bag once, block-wise: bounded curves for the figures and the run metrics.

    Return the curves, the metrics (None: no common couplers / coaches sample), where the
    parameters came from, and with ``args.fatigue`` the couplers' rainflow counts
    (:meth:`FatigueFeed.result`; else None). ``curves`` False: only ``couplers`` and
    ``coaches`` are read (what the metrics need; no figures will be drawn).
    """
    try:
        info = bag_info(args.bag)
    except BagError as exc:
        raise CliError(str(exc)) from None
    cfg, origin = run_config(args, info.custom_data)
    feed = MetricsFeed(metrics_factory(cfg, **overrides))
    tap = _FatigueTap() if getattr(args, 'fatigue', False) else None

    def on_block(*block: Any) -> None:
        feed.on_block(*block)
        if tap is not None:
            tap.on_block(*block)

    def on_reset(topic: str) -> None:
        feed.on_reset(topic)
        if tap is not None:
            tap.on_reset(topic)

    try:
        hist = stream_history(args.bag, namespace=args.namespace, on_block=on_block,
                              on_reset=on_reset, only=None if curves else (
                                  topics.COUPLERS_TOPIC, topics.COACHES_TOPIC))
    except BagError as exc:
        raise CliError(str(exc)) from None
    fatigue = tap.feed.result() if tap is not None and tap.feed else None
    return hist, feed.finish(), origin, fatigue


def refuse_non_finite(bag: str, hist: History) -> None:
    """
    Refuse a run whose ``couplers`` or ``coaches`` hold a NaN or an infinite value.

    The metrics of such a run would be wrong (a NaN speed read as 0 m/s gives a deceleration
    of hundreds of m/s^2) or not representable in JSON (an infinite speed): no report is
    written; the message names the first such value (topic, field, joint, time).
    """
    bad = [hist.non_finite[k] for k in (topics.COUPLERS_TOPIC, topics.COACHES_TOPIC)
           if k in hist.non_finite]
    if bad:
        raise CliError(f'{bag}: {"; ".join(bad)}: the run metrics would be wrong, no report '
                       'written (the bag holds a diverged or corrupt run)')


def write_whole_report(result: dict[str, Any], hist: History, out: Path,
                       source: dict[str, Any]) -> list[Path]:
    """
    Write the report into ``out``: every file or none (e.g. on a full disk).

    The files are written into a hidden folder in ``out`` and moved into place (renames,
    which need no space) once all are written; on a failure that folder, and the folders
    created for ``out``, are removed.
    """
    created = output_dir(out)
    staging = out / f'.report.partial-{os.getpid()}'
    try:
        written = write_report(result, hist, staging, source=source)
        paths = []
        for p in written:
            final = out / p.relative_to(staging)
            final.parent.mkdir(parents=True, exist_ok=True)
            os.replace(p, final)
            paths.append(final)
    except OSError as exc:
        raise CliError(f'cannot write the report to {out}: {exc.strerror or exc} (nothing '
                       'written)', EXIT_ERROR) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
        remove_created(created)                  # only those left empty
    return paths


def run_result(args: argparse.Namespace, overrides: dict, curves: bool = True
               ) -> tuple[dict, Any, dict]:
    """
    Return the run metrics of ``args.bag``, its history and the report's ``source`` entry.

    The steps every report of a bag takes (``train-dynamics report`` and the harness): read
    it block by block, refuse a bag without ``couplers``/``coaches`` or with a non-finite or
    ragged sample (:class:`CliError`, one line), take the metrics, fill the stop error from
    the bag's last ``distance_to_go``. The bag is opened once for all of it
    (:func:`~train_dynamics.recording.bag_read.shared_reader`). ``curves`` False: the
    history holds ``couplers`` and ``coaches`` only (a report without figures).
    """
    with shared_reader(args.bag):
        return _run_result(args, overrides, curves)


def _run_result(args: argparse.Namespace, overrides: dict, curves: bool
                ) -> tuple[dict, Any, dict]:
    hist, metrics, origin, fatigue = read_run(args, overrides, curves)
    if hist.couplers is None or hist.coaches is None or not len(hist.coaches) \
            or metrics is None:
        raise CliError(f'{args.bag}: needs the couplers and coaches topics (JointState)')
    refuse_non_finite(args.bag, hist)
    result = metrics.result()
    try:
        stop_error_from_bag(result, args.bag, args.namespace)
    except BagError as exc:
        raise CliError(str(exc)) from None
    blending = blending_metrics(args.bag, args.namespace)       # multiple units only
    if blending is not None:
        result['blending'] = blending
    if fatigue is not None:                                      # report --fatigue
        result['fatigue'] = fatigue
    keys = ('model_type', 'scale_factor', 'integration_step', 'generator')
    model = ', '.join(f'{k} {hist.info[k]}' for k in keys if k in hist.info)
    source = {'bag': str(args.bag), 'parameters': origin, 'model': model,
              'notes': list(hist.notes)}
    return result, hist, source


def cmd_report(args: argparse.Namespace) -> int:
    """Run ``report``; return the exit status."""
    if not Path(args.bag).exists():
        raise CliError(f'bag not found: {args.bag}')
    overrides = {}
    for name in ('coupler_force_limit', 'jerk_limit'):
        value = getattr(args, name)
        if value is not None:
            if not value >= 0.0:
                raise CliError(f'--{name.replace("_", "-")} must be >= 0, got {value:g}')
            overrides[name] = value
    result, hist, source = run_result(args, overrides)
    paths = write_whole_report(result, hist, Path(args.output), source)
    if not args.quiet:
        tr = result['train']
        print(f"max tension {tr['max_tension'] * 1e-3:.2f} kN (coupler "
              f"{tr['max_tension_coupler']}), max compression "
              f"{tr['max_compression'] * 1e-3:.2f} kN (coupler "
              f"{tr['max_compression_coupler']}), "
              + (f"stopped after {tr['stopping_time']:.2f} s / {tr['stopping_distance']:.1f} m"
                 if tr['stopped'] else 'not stopped')
              + f", {tr['limit_crossings']} limit crossing(s)")
        for p in paths:
            print(p)
    return EXIT_OK
