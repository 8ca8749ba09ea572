"""
The report of a run and the figures of a sweep (``train-dynamics report`` / ``sweep``).

:func:`write_report` writes, for the metrics of one run
(:class:`train_dynamics.physics.metrics.RunMetrics`), ``summary.json``, a readable
``summary.md`` and the figures:

* ``force_envelope.png``: the largest tension and compression of every coupling along the
  train (coupler 1 = front), the worst force marked (coupler, value, time), the limit dashed;
* ``worst_force.png``: the force of the worst coupler against time, its peak marked, over
  the band of all couplers' forces;
* ``vehicles.png``: per vehicle the largest deceleration (1 s mean and sample), jerk (1 s);
* the paper's figures of :func:`train_dynamics.recording.plots.plot_history`.

:func:`sweep_figures` draws each metric against each swept parameter. Agg canvas only.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
import json
import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.recording.bags import read_topics
from train_dynamics.recording.blending_metrics import blending_markdown
from train_dynamics.recording.history import History, natural_key

# matplotlib (0.3-0.7 s to import) is imported by the functions that draw, not here: the
# metrics and summary.md of a report without figures (the harness's) never import it

#: how many rows of couplers / vehicles ``summary.md`` lists (the worst ones first)
MD_ROWS = 20
#: samples fed to the run metrics at once by :class:`MetricsFeed` (and the most it holds)
FEED_ROWS = 20000

_UNITS = {'max_tension': ('kN', 1e-3), 'max_compression': ('kN', 1e-3),
          'stopping_distance': ('m', 1.0), 'stopping_time': ('s', 1.0),
          'stopping_distance_from_brake': ('m', 1.0), 'stopping_time_from_brake': ('s', 1.0),
          'max_deceleration': ('m/s^2', 1.0), 'peak_deceleration': ('m/s^2', 1.0),
          'max_jerk': ('m/s^3', 1.0), 'brake_energy': ('MJ', 1e-6),
          'coupler_work': ('J', 1.0), 'coupler_dissipated': ('J', 1.0), 't_end': ('s', 1.0),
          'max_blocking_overrun': ('mm', 1e3), 'max_impact_speed': ('m/s', 1.0),
          'final_speed': ('m/s', 1.0), 'stop_error': ('m', 1.0)}


def write_report(result: dict[str, Any], hist: History, outdir: str | os.PathLike, *,
                 source: dict[str, Any] | None = None) -> list[Path]:
    """Write summary.json, summary.md and the figures of ``result`` into ``outdir``."""
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    doc = {'source': source or {}, **result}
    paths = [out / 'summary.json', out / 'summary.md']
    paths[0].write_text(json.dumps(doc, indent=2, allow_nan=False) + '\n', encoding='utf-8')
    paths[1].write_text(summary_markdown(doc), encoding='utf-8')
    paths.append(force_envelope(result, out / 'force_envelope.png'))
    if hist.couplers is not None and len(hist.couplers):
        paths.append(worst_force(result, hist, out / 'worst_force.png'))
    paths.append(vehicle_figure(result, out / 'vehicles.png'))
    from train_dynamics.recording.plots import PlotError
    try:
        paths.extend(plot_history(hist, out))
    except PlotError:
        pass
    return paths


class MetricsFeed:
    """
    Feed :class:`train_dynamics.physics.metrics.RunMetrics` from a bag as it is read.

    Give :meth:`on_block` / :meth:`on_reset` to
    :func:`train_dynamics.recording.history.stream_history`. The samples fed are those where
    ``couplers`` and ``coaches`` share a header stamp (rounded to 1 ns, the first of equal
    stamps), as :func:`train_dynamics.physics.metrics.metrics_of_history` takes them from
    whole arrays; they go to the metrics in blocks of :data:`FEED_ROWS` (a run of at most
    that many samples in one block: the very numbers of the in-memory report). Columns are
    those of each topic's first block in natural order (coupler_2 before coupler_10). A
    topic that restarts (reset during the recording) restarts the metrics: the last run
    counts. ``make_metrics(n_vehicles)`` creates the accumulator.
    """

    def __init__(self, make_metrics: Callable[[int], RunMetrics]) -> None:
        self.make_metrics = make_metrics
        self.metrics: RunMetrics | None = None
        self._cols: dict[str, list[str]] = {}
        self._pending: dict[str, tuple[np.ndarray, np.ndarray] | None] = {}
        self._ready: list[tuple[np.ndarray, ...]] = []
        self._ready_rows = 0
        self._last_key = -math.inf

    def on_reset(self, topic: str) -> None:
        """Restart the metrics when ``couplers`` or ``coaches`` restarts."""
        if topic in (topics.COUPLERS_TOPIC, topics.COACHES_TOPIC):
            self._pending[topic] = None
            self._ready, self._ready_rows = [], 0
            self._last_key = -math.inf
            if self.metrics is not None:
                self.metrics = self.make_metrics(self.metrics.n)

    def on_block(self, topic: str, t: np.ndarray, q: np.ndarray, names: list[str]) -> None:
        """Take a block of ``couplers`` or ``coaches`` (t (K,), q (K, 3, M), M names)."""
        if topic not in (topics.COUPLERS_TOPIC, topics.COACHES_TOPIC):
            return
        cols = self._cols.setdefault(topic, sorted(names, key=natural_key))
        where = {n: j for j, n in enumerate(names)}
        fixed = np.full((q.shape[0], 3, len(cols)), np.nan)
        for j, n in enumerate(cols):
            if n in where:
                fixed[:, :, j] = q[:, :, where[n]]
        key = np.round(t, 9)
        new = key > self._last_key
        old = self._pending.get(topic)
        rows = (key[new], t[new], fixed[new])
        self._pending[topic] = rows if old is None else tuple(
            np.concatenate([a, b]) for a, b in zip(old, rows))
        self._match()

    def _match(self) -> None:
        cp, co = (self._pending.get(k) for k in (topics.COUPLERS_TOPIC, topics.COACHES_TOPIC))
        if cp is None or co is None:
            return
        _, ic, iv = np.intersect1d(cp[0], co[0], return_indices=True)
        if ic.size:
            self._ready.append((cp[1][ic], cp[2][ic], co[2][iv]))
            self._ready_rows += ic.size
            self._last_key = float(cp[0][ic[-1]])
            if self._ready_rows >= FEED_ROWS:
                self._feed()
        for k in (topics.COUPLERS_TOPIC, topics.COACHES_TOPIC):
            key, t, q = self._pending[k]
            keep = key > self._last_key
            keep[:max(keep.size - FEED_ROWS, 0)] = False      # never matched: bounded
            self._pending[k] = (key[keep], t[keep], q[keep])

    def _feed(self) -> None:
        if not self._ready:
            return
        t, c, v = (np.concatenate(parts) for parts in zip(*self._ready))
        self._ready, self._ready_rows = [], 0
        if self.metrics is None:
            self.metrics = self.make_metrics(v.shape[2])
        self.metrics.add_block(t, c[:, 0], c[:, 1], c[:, 2], v[:, 0], v[:, 1], v[:, 2])

    def finish(self) -> RunMetrics | None:
        """Feed what is left; return the metrics (None: no common sample)."""
        self._feed()
        return self.metrics


def stop_error_from_bag(result: dict[str, Any], bag: str | os.PathLike,
                        namespace: str = '') -> None:
    """
    Set ``result['train']['stop_error']`` from the last ``distance_to_go`` of ``bag``, if any.

    The stop error [m] is the track position of vehicle 1's front minus the target stopping
    point at the last sample: minus its distance to go (the target as it was then, also when
    its input topic moved it during the run); None when the train is not at rest at the end
    (``final_speed`` above the result's ``stop_speed``). A bag without
    the topic keeps the value computed from the run's parameters.
    """
    ns = namespace.strip('/')
    topic = (f'{ns}/' if ns else '') + topics.DISTANCE_TO_GO_TOPIC
    last = None
    for _, _, msg in read_topics(bag, [topic]):
        last = msg
    if last is None or not len(last.position):
        return
    train = result['train']
    at_rest = (train.get('final_speed') is not None
               and train['final_speed'] <= result['settings']['stop_speed'])
    train['stop_error'] = -float(last.position[0]) if at_rest else None


def _worst(train: dict[str, Any]) -> tuple[str, int, float, float | None]:
    """Return ('tension' or 'compression', coupler, signed force [N], time) of the worst."""
    if train['max_tension'] > train['max_compression']:
        return ('tension', train['max_tension_coupler'], train['max_tension'],
                train['max_tension_time'])
    return ('compression', train['max_compression_coupler'], -train['max_compression'],
            train['max_compression_time'])


def plot_history(hist: History, outdir: Path) -> list[Path]:
    """Draw the paper's figures of ``hist`` (:func:`.plots.plot_history`, imported here)."""
    from train_dynamics.recording import plots
    return plots.plot_history(hist, outdir)


def force_envelope(result: dict[str, Any], path: Path) -> Path:
    """Draw the largest tension (up) and compression (down) of each coupling [kN]."""
    from matplotlib.ticker import MaxNLocator

    from train_dynamics.recording.plots import _new_figure, _save, _style
    rows = result['couplers']
    pos = np.arange(1, len(rows) + 1)
    ten = np.array([r['max_tension'] for r in rows]) * 1e-3
    com = -np.array([r['max_compression'] for r in rows]) * 1e-3
    fig = _new_figure('single')
    ax = fig.add_subplot()
    _style(ax)
    marker = 'o' if len(rows) <= 60 else None
    ax.plot(pos, ten, color='tab:blue', marker=marker, ms=4, lw=1.5, label='largest tension')
    ax.plot(pos, com, color='tab:red', marker=marker, ms=4, lw=1.5,
            label='largest compression')
    ax.fill_between(pos, com, ten, color='0.85', zorder=0)
    kind, j, f, t = _worst(result['train'])
    ax.plot([j], [f * 1e-3], marker='*', ms=16, color='black', zorder=5,
            label=f'worst: {kind} {abs(f) * 1e-3:.1f} kN, coupler {j}'
            + (f' at t = {t:.2f} s' if t is not None else ''))
    limit = result['settings'].get('coupler_force_limit') or 0.0
    if limit > 0:
        for s in (1, -1):
            ax.axhline(s * limit * 1e-3, color='black', ls='--', lw=1.0,
                       label='limit' if s > 0 else None)
    ax.set_xlabel('coupling position (coupler i joins vehicles i and i+1; 1 = front)',
                  fontsize=11)
    ax.set_ylabel('coupler force F [kN] (> 0 tension)', fontsize=11)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    if len(rows) > 1:
        ax.set_xlim(0.5, len(rows) + 0.5)
    ax.legend(loc='best', fontsize=9, framealpha=0.9)
    fig.suptitle('Force envelope along the train', fontsize=13)
    return _save(fig, path)


def worst_force(result: dict[str, Any], hist: History, path: Path) -> Path:
    """Draw F(t) of the worst coupler over the band of all couplers, its peak marked."""
    from train_dynamics.recording.plots import _new_figure, _save, _set_xlim, _style
    c = hist.couplers
    kind, j, f, t = _worst(result['train'])
    fig = _new_figure('single')
    ax = fig.add_subplot()
    _style(ax)
    force = c.effort * 1e-3
    if force.shape[1] > 1:
        ax.fill_between(c.t, np.nanmin(force, axis=1), np.nanmax(force, axis=1), color='0.85',
                        zorder=0, label='all couplers (min - max)')
    col = c.names.index(f'coupler_{j}') if f'coupler_{j}' in c.names else j - 1
    ax.plot(c.t, force[:, col], color='tab:red' if f < 0 else 'tab:blue', lw=1.3,
            label=f'coupler {j}', zorder=3)
    if t is not None:
        ax.plot([t], [f * 1e-3], marker='*', ms=16, color='black', zorder=5,
                label=f'worst {kind}: {abs(f) * 1e-3:.1f} kN at t = {t:.2f} s')
        ax.annotate(f'coupler {j}\nt = {t:.2f} s\n{f * 1e-3:.1f} kN', (t, f * 1e-3),
                    textcoords='offset points', xytext=(14, 8 if f < 0 else -40),
                    fontsize=9)
    _set_xlim(ax, c.t)
    ax.set_xlabel('time t [s]', fontsize=11)
    ax.set_ylabel('coupler force F [kN] (> 0 tension)', fontsize=11)
    ax.legend(loc='best', fontsize=9, framealpha=0.9)
    fig.suptitle('The worst coupler force', fontsize=13)
    return _save(fig, path)


def vehicle_figure(result: dict[str, Any], path: Path) -> Path:
    """Draw per vehicle the largest deceleration (1 s mean, sample) and jerk (1 s)."""
    from train_dynamics.recording.plots import _new_figure, _save, _style
    rows = result['vehicles']
    pos = np.arange(1, len(rows) + 1)
    fig = _new_figure('single')
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    for ax in (ax1, ax2):
        _style(ax)
    window = result['settings']['comfort_window']
    ax1.plot(pos, [r['max_deceleration'] for r in rows], marker='o', ms=4,
             label=f'{window:g} s mean')
    ax1.plot(pos, [r['peak_deceleration'] for r in rows], marker='.', ms=4, ls='--',
             label='sample period mean')
    ax1.set_ylabel('largest deceleration [m/s$^2$]', fontsize=11)
    ax1.legend(loc='best', fontsize=9)
    ax2.plot(pos, [r['max_jerk'] for r in rows], marker='o', ms=4, color='tab:purple')
    limit = result['settings'].get('jerk_limit') or 0.0
    if limit > 0:
        ax2.axhline(limit, color='black', ls='--', lw=1.0, label='limit')
        ax2.legend(loc='best', fontsize=9)
    ax2.set_ylabel(f'largest jerk ({window:g} s) [m/s$^3$]', fontsize=11)
    ax2.set_xlabel('vehicle (1 = front)', fontsize=11)
    fig.suptitle('Decelerations and jerk per vehicle', fontsize=13)
    return _save(fig, path)


def _fmt(key: str, value: Any) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return 'n/a'
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    if isinstance(value, int):
        return str(value)
    unit, scale = _UNITS.get(key, ('s' if key.endswith('_time') else '', 1.0))
    return f'{value * scale:.4g} {unit}'.strip()


def summary_markdown(doc: dict[str, Any]) -> str:
    """Return ``summary.md``: the train's metrics, worst couplers and vehicles, crossings."""
    tr = doc['train']
    src = doc.get('source', {})
    lines = ['# Run report', '']
    for key in ('bag', 'parameters', 'model'):
        if src.get(key):
            lines.append(f'- {key}: {src[key]}')
    kind, j, f, t = _worst(tr)
    lines += ['', f'**Worst coupler force: {kind} {abs(f) * 1e-3:.2f} kN in coupler {j}'
              + (f' at t = {t:.3f} s**' if t is not None else '**'), '']
    if tr['stopped']:
        lines.append(f"**Stopped after {tr['stopping_time']:.2f} s and "
                     f"{tr['stopping_distance']:.1f} m** (from the first sample; from the "
                     f"brake onset: {_fmt('stopping_time', tr['stopping_time_from_brake'])}, "
                     f"{_fmt('stopping_distance', tr['stopping_distance_from_brake'])}).")
    else:
        lines.append(f"**Not stopped** by t = {tr['t_end']:.2f} s (largest speed left "
                     f"{tr['final_speed']:.3g} m/s).")
    if tr.get('stop_error') is not None:
        lines.append(f"Stop error {tr['stop_error']:+.2f} m (the front of vehicle 1 minus the "
                     'target stopping point; > 0 overrun).')
    lines += ['', '| metric | value |', '| --- | --- |']
    lines += [f'| {k} | {_fmt(k, v)} |' for k, v in tr.items()]
    cp = sorted(doc['couplers'], key=lambda r: -max(r['max_tension'], r['max_compression']))
    lines += ['', f'## Couplers (worst {min(MD_ROWS, len(cp))} of {len(cp)})', '',
              '| coupler | max tension [kN] | t [s] | max compression [kN] | t [s] | '
              'work [J] | blockings | worst overrun [mm] | impacts | worst impact [m/s] |',
              '| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |']
    for r in cp[:MD_ROWS]:
        lines.append(f"| {r['name']} | {r['max_tension'] * 1e-3:.2f} | "
                     f"{_t(r['max_tension_time'])} | {r['max_compression'] * 1e-3:.2f} | "
                     f"{_t(r['max_compression_time'])} | {r['work']:.4g} | "
                     f"{r['blocking_count']} | {r['max_blocking_overrun'] * 1e3:.3g} | "
                     f"{r['impact_count']} | {r['max_impact_speed']:.3g} |")
    ve = sorted(doc['vehicles'], key=lambda r: -r['max_jerk'])
    window = doc['settings']['comfort_window']
    lines += ['', f'## Vehicles (largest jerk first, {min(MD_ROWS, len(ve))} of {len(ve)})',
              '', f'| vehicle | max deceleration ({window:g} s) [m/s^2] | t [s] | '
              'peak deceleration (sample) [m/s^2] | max jerk [m/s^3] | t [s] | '
              'brake energy [MJ] |', '| --- | ---: | ---: | ---: | ---: | ---: | ---: |']
    for r in ve[:MD_ROWS]:
        lines.append(f"| {r['name']} | {r['max_deceleration']:.3f} | "
                     f"{_t(r['max_deceleration_time'])} | {r['peak_deceleration']:.3f} | "
                     f"{r['max_jerk']:.3f} | {_t(r['max_jerk_time'])} | "
                     f"{r['brake_energy'] * 1e-6:.3f} |")
    lines += ['', '## Limit crossings', '']
    cross = doc.get('crossings', [])
    if not cross:
        lines.append('None (limits: coupler force '
                     f"{_limit(doc['settings']['coupler_force_limit'], 'N')}, jerk "
                     f"{_limit(doc['settings']['jerk_limit'], 'm/s^3')}).")
    for e in cross:
        unit = 'N' if e['kind'] == 'coupler_force' else 'm/s^3'
        end = f"{e['t_end']:.3f} s" if e['t_end'] is not None else 'end of run'
        lines.append(f"- WARN {e['name']}: {e['kind']} {e['value']:.4g} {unit} at t = "
                     f"{e['t']:.3f} s (beyond {e['limit']:.4g} {unit} from {e['t_start']:.3f} "
                     f'to {end})')
    lines += [''] + blending_markdown(doc.get('blending'))
    lines += ['', 'Deceleration and jerk over the comfort window (EN 12299 practice); '
              'energies by the trapezoid rule over the recorded samples. See docs/offline.md '
              '("Run metrics").', '']
    return '\n'.join(lines)


def _t(value: float | None) -> str:
    return 'n/a' if value is None else f'{value:.3f}'


def _limit(value: float, unit: str) -> str:
    return 'off' if not value else f'{value:g} {unit}'


def sweep_figures(columns: dict[str, np.ndarray], params: Sequence[str],
                  metrics: Sequence[str], outdir: str | os.PathLike, *,
                  failed: np.ndarray | None = None) -> list[Path]:
    """
    Draw each metric against each swept parameter: ``<metric>__vs__<param>.png``.

    ``columns`` maps names to equal-length arrays (numbers or strings for a parameter);
    ``failed`` marks the cases with an error (not drawn).
    """
    from train_dynamics.recording.plots import _new_figure, _save, _style
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    ok = ~failed if failed is not None else None
    paths = []
    for p in params:
        xs = np.asarray(columns[p], dtype=object)
        numeric = all(isinstance(v, (int, float, np.integer, np.floating))
                      and not isinstance(v, bool) for v in xs)
        labels = sorted({str(v) for v in xs}) if not numeric else []
        for m in metrics:
            ys = np.asarray(columns[m], dtype=float)
            keep = np.isfinite(ys) if ok is None else np.isfinite(ys) & ok
            if not keep.any():
                continue
            unit, scale = _UNITS.get(m, ('s' if m.endswith('_time') else '', 1.0))
            fig = _new_figure('single')
            ax = fig.add_subplot()
            _style(ax)
            x = (xs[keep].astype(float) if numeric
                 else np.array([labels.index(str(v)) for v in xs[keep]], dtype=float))
            ax.plot(x, ys[keep] * scale, 'o', ms=5, alpha=0.8)
            if not numeric:
                ax.set_xticks(range(len(labels)), labels)
            ax.set_xlabel(p, fontsize=11)
            ax.set_ylabel(f'{m} [{unit}]' if unit else m, fontsize=11)
            fig.suptitle(f'{m} against {p} ({int(keep.sum())} cases)', fontsize=13)
            paths.append(_save(fig, out / f'{m}__vs__{p}.png'))
    return paths
