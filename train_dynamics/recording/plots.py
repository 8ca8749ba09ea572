"""
Figures of a run: the paper's figs. 5-7 / 9-11 from any bag that holds ``couplers``.

:func:`plot_bag` reads a bag (:func:`train_dynamics.recording.history.stream_history`) and
:func:`plot_history` draws, one curve per coupler, in engineering units with the SI quantity
in the label:

* ``coupler_displacement.png``  relative displacement y = x_i - x_{i+1} [mm]  (fig. 5 / 9)
* ``coupler_velocity.png``      relative velocity ydot [m/s]                  (fig. 6 / 10)
* ``coupler_force.png``         coupler force F [kN], > 0 tension              (fig. 7 / 11)
* ``couplers.png``              the three stacked on one page
* ``coaches.png``               (when ``coaches`` is present) speed [km/h], braking force
  [kN], and brake-cylinder / brake-pipe pressures [bar gauge] when recorded.
* ``vehicle_forces.png``        (when ``vehicle_forces`` is present) traction / dynamic
  brake, resistance and gradient force per vehicle [kN].

:func:`plot_comparison` draws the ``compare`` command's figures. Only the Agg canvas is used
(no pyplot, no display needed). Every figure has a fixed pixel size (:data:`SIZE_PX`).
"""
from __future__ import annotations

from collections.abc import Sequence
import math
import os
from pathlib import Path
import re

from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
import numpy as np

from train_dynamics import topics
from train_dynamics.recording.history import History, stream_history

#: Figure sizes [inch] and resolution [dpi]; SIZE_PX gives the PNG sizes in pixels.
DPI = 120
FIGSIZE = {'single': (11.0, 6.0), 'stack': (11.0, 11.0), 'coaches': (11.0, 11.0),
           'compare': (15.0, 9.0), 'zoom': (11.0, 8.0), 'brake_pressures': (11.0, 12.0)}
SIZE_PX = {k: (int(round(w * DPI)), int(round(h * DPI))) for k, (w, h) in FIGSIZE.items()}

MAX_LEGEND_ENTRIES = 10          # more curves than this: colour map + colour bar instead


#: the zoom of one compare run: t [s], ydot [m/s], F [N] of one coupler in the window
ZoomData = tuple[np.ndarray, np.ndarray, np.ndarray]


class PlotError(Exception):
    """Nothing to plot (e.g. no ``couplers`` topic); the message is one line."""


# -- drawing helpers ----------------------------------------------------------------------------

def _new_figure(kind: str):
    fig = Figure(figsize=FIGSIZE[kind], dpi=DPI, layout='constrained')
    FigureCanvasAgg(fig)
    return fig


def _style(ax) -> None:
    ax.grid(True, which='major', alpha=0.35, linewidth=0.7)
    ax.tick_params(labelsize=10)
    ax.axhline(0.0, color='0.35', linewidth=0.8, zorder=1)


def _colors(n: int):
    if n <= MAX_LEGEND_ENTRIES:
        cmap = colormaps['tab10']
        return [cmap(j % 10) for j in range(n)], None
    cmap = colormaps['viridis']
    return [cmap(j / max(n - 1, 1)) for j in range(n)], cmap


def _curve_label(name: str, kind: str) -> str:
    m = re.fullmatch(r'(coupler|coach)_(\d+)', name)
    if not m:
        return name
    i = int(m.group(2))
    if kind == 'coupler':
        return f'coupler {i} (coaches {i}-{i + 1})'
    return f'coach {i}'


def _plot_lines(ax, t, values, names, kind: str, *, legend: bool = True, lw: float = 1.3):
    """One curve per column; legend (or colour bar for many columns)."""
    colors, cmap = _colors(len(names))
    lw = lw if len(names) <= MAX_LEGEND_ENTRIES else 0.9
    for j, name in enumerate(names):
        col = values[:, j]
        if np.all(np.isnan(col)):
            continue
        ax.plot(t, col, color=colors[j], linewidth=lw, label=_curve_label(name, kind), zorder=3)
    if cmap is not None:
        sm = ScalarMappable(norm=Normalize(1, len(names)), cmap=cmap)
        cb = ax.figure.colorbar(sm, ax=ax, pad=0.01, aspect=30)
        cb.set_label(f'{kind} number (1 = front)', fontsize=10)
    elif legend and names:
        ax.legend(loc='best', fontsize=9, framealpha=0.9, ncols=1 if len(names) <= 5 else 2)


def _set_xlim(ax, t) -> None:
    if len(t) > 1 and t[-1] > t[0]:
        ax.set_xlim(t[0], t[-1])


def _finite_range(values) -> tuple[float, float]:
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 0.0
    return float(v.min()), float(v.max())


def _describe(hist: History) -> str:
    """Short model description from the bag's custom data (written by the offline command)."""
    info = hist.info
    parts = []
    if info.get('model_type') == 'tanh':
        parts.append(f"tanh model, u = {float(info.get('scale_factor', 'nan')):g} s/m")
    elif info.get('model_type') == 'sign':
        parts.append('sign model')
    if 'integration_step' in info:
        parts.append(f"h = {float(info['integration_step']) * 1e3:g} ms")
    if 'brake_input' in info:
        parts.append(f"brake input {info['brake_input']}")
    return ', '.join(parts)


# Quantities of the coupler figures: (key, field, scale, axis label, title)
COUPLER_QUANTITIES = [
    ('displacement', 'position', 1e3, 'relative displacement y [mm]',
     'Relative displacement between coaches  (y = x$_i$ - x$_{i+1}$;  y < 0 buffers compressed)'),
    ('velocity', 'velocity', 1.0, 'relative velocity $\\dot{y}$ [m/s]',
     'Relative velocity between coaches  ($\\dot{y}$ = v$_i$ - v$_{i+1}$)'),
    ('force', 'effort', 1e-3, 'coupler force F [kN]',
     'Longitudinal force in the couplers  (F > 0 tension, F < 0 compression)'),
]


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=DPI, metadata={'Software': None})
    return path


# -- the figures -----------------------------------------------------------------------------

def plot_history(hist: History, outdir: str | os.PathLike, *, title: str | None = None
                 ) -> list[Path]:
    """Write the PNG figures of ``hist`` into ``outdir`` (created); return their paths."""
    if hist.couplers is None or len(hist.couplers) == 0 or not hist.couplers.names:
        raise PlotError('no coupler data (topic couplers) to plot')
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    c = hist.couplers
    sub = title if title is not None else ' - '.join(
        p for p in (hist.label, _describe(hist)) if p)
    paths = []
    for key, fld, scale, ylabel, heading in COUPLER_QUANTITIES:
        fig = _new_figure('single')
        ax = fig.add_subplot()
        _style(ax)
        _plot_lines(ax, c.t, getattr(c, fld) * scale, c.names, 'coupler')
        ax.set_xlabel('time t [s]', fontsize=11)
        ax.set_ylabel(ylabel, fontsize=11)
        _set_xlim(ax, c.t)
        fig.suptitle(heading, fontsize=13)
        if sub:
            ax.set_title(sub, fontsize=10, color='0.3')
        paths.append(_save(fig, out / f'coupler_{key}.png'))

    fig = _new_figure('stack')
    axes = fig.subplots(3, 1, sharex=True)
    for ax, (key, fld, scale, ylabel, heading) in zip(axes, COUPLER_QUANTITIES):
        _style(ax)
        _plot_lines(ax, c.t, getattr(c, fld) * scale, c.names, 'coupler', legend=(key == 'force'))
        ax.set_ylabel(ylabel, fontsize=11)
        ax.set_title(heading, fontsize=11)
        _set_xlim(ax, c.t)
    axes[-1].set_xlabel('time t [s]', fontsize=11)
    fig.suptitle('Coupler response' + (f'\n{sub}' if sub else ''), fontsize=13)
    paths.append(_save(fig, out / 'couplers.png'))

    if hist.coaches is not None and len(hist.coaches):
        paths.append(_plot_coaches(hist, out / 'coaches.png', sub))
    if hist.forces is not None and len(hist.forces):
        paths.append(_plot_forces(hist, out / 'vehicle_forces.png', sub))
    if hist.reservoirs is not None and len(hist.reservoirs) and hist.cylinders is not None:
        paths.append(_plot_brake_pressures(hist, out / 'brake_pressures.png', sub))
    return paths


def _plot_forces(hist: History, path: Path, sub: str) -> Path:
    """Draw ``vehicle_forces``: traction, resistance and gradient force per vehicle [kN]."""
    fo = hist.forces
    fig = _new_figure('coaches')
    axes = fig.subplots(3, 1, sharex=True)
    for ax, fld, title, legend in (
            (axes[0], 'position', 'Traction (> 0) / dynamic brake (< 0) force', True),
            (axes[1], 'velocity', 'Running + curve resistance (on the vehicle)', False),
            (axes[2], 'effort', 'Gradient force (> 0 downhill)', False)):
        _style(ax)
        _plot_lines(ax, fo.t, getattr(fo, fld) * 1e-3, fo.names, 'coach', legend=legend)
        ax.set_ylabel('[kN]', fontsize=11)
        ax.set_title(title, fontsize=11)
        _set_xlim(ax, fo.t)
    axes[-1].set_xlabel('time t [s]', fontsize=11)
    fig.suptitle('External forces per vehicle' + (f'\n{sub}' if sub else ''), fontsize=13)
    return _save(fig, path)


def _plot_brake_pressures(hist: History, path: Path, sub: str) -> Path:
    """Pipe, control reservoir, auxiliary reservoir and cylinder of every vehicle [bar]."""
    cy, rs = hist.cylinders, hist.reservoirs
    panels = ((cy, 'effort', 'brake pipe'), (rs, 'effort', 'control reservoir'),
              (rs, 'position', 'auxiliary reservoir'), (cy, 'position', 'brake cylinder'))
    fig = _new_figure('brake_pressures')
    axes = fig.subplots(len(panels), 1, sharex=True)
    for k, (ax, (series, fld, name)) in enumerate(zip(axes, panels)):
        _style(ax)
        _plot_lines(ax, series.t, getattr(series, fld) * 1e-5, series.names, 'coach',
                    legend=(k == 0))
        ax.set_ylabel('[bar gauge]', fontsize=11)
        ax.set_title(f'{name.capitalize()} pressure per vehicle (pneumatic brake)', fontsize=11)
        _set_xlim(ax, series.t)
    axes[-1].set_xlabel('time t [s]', fontsize=11)
    fig.suptitle('Brake pressures' + (f'\n{sub}' if sub else ''), fontsize=13)
    return _save(fig, path)


def _plot_coaches(hist: History, path: Path, sub: str) -> Path:
    co = hist.coaches
    assert co is not None
    have_p = hist.cylinders is not None and len(hist.cylinders) or hist.head_pressure is not None
    fig = _new_figure('coaches')
    axes = fig.subplots(3 if have_p else 2, 1, sharex=True)
    ax = axes[0]
    _style(ax)
    _plot_lines(ax, co.t, co.velocity * 3.6, co.names, 'coach')
    ax.set_ylabel('speed v [km/h]', fontsize=11)
    ax.set_title('Coach speeds', fontsize=11)
    lo, hi = _finite_range(co.velocity * 3.6)
    if hi > lo:
        ax.set_ylim(min(0.0, lo), hi + 0.05 * (hi - min(0.0, lo)))
    ax = axes[1]
    _style(ax)
    _plot_lines(ax, co.t, co.effort * 1e-3, co.names, 'coach', legend=False)
    ax.set_ylabel('braking force F$_b$ [kN]', fontsize=11)
    ax.set_title('Braking force per coach (paper eq. 13)', fontsize=11)
    _set_xlim(ax, co.t)
    if have_p:
        ax = axes[2]
        _style(ax)
        if hist.cylinders is not None and len(hist.cylinders):
            cy = hist.cylinders
            _plot_lines(ax, cy.t, cy.position * 1e-5, cy.names, 'coach', legend=False)
            if np.any(np.isfinite(cy.effort)):
                colors, _ = _colors(len(cy.names))
                for j in range(len(cy.names)):
                    ax.plot(cy.t, cy.effort[:, j] * 1e-5, color=colors[j], linewidth=0.9,
                            linestyle='--', zorder=2)
        if hist.head_pressure is not None:
            t, p = hist.head_pressure
            ax.plot(t, p * 1e-5, color='black', linewidth=1.0, linestyle=':', zorder=4,
                    label='head of brake pipe')
        ax.set_ylabel('pressure [bar gauge]', fontsize=11)
        ax.set_title('Brake-cylinder pressures (solid), local brake-pipe pressures (dashed)',
                     fontsize=11)
        if hist.head_pressure is not None:
            ax.legend(loc='best', fontsize=9, framealpha=0.9)
    axes[-1].set_xlabel('time t [s]', fontsize=11)
    _set_xlim(axes[-1], co.t)
    fig.suptitle('Coaches' + (f'\n{sub}' if sub else ''), fontsize=13)
    return _save(fig, path)


def plot_bag(bag: str | os.PathLike, outdir: str | os.PathLike, *, namespace: str = '',
             title: str | None = None) -> list[Path]:
    """
    Read a bag and write its figures (:func:`plot_history`); raise PlotError / BagError.

    The bag is read block-wise into bounded curves
    (:func:`train_dynamics.recording.history.stream_history`): memory does not depend on its
    length; past 20000 samples a topic is drawn as its min/max envelope.
    """
    hist = stream_history(bag, namespace=namespace)
    if hist.couplers is None:
        raise PlotError(f'{bag}: no {topics.COUPLERS_TOPIC} topic ({topics.JOINT_STATE}) in '
                        'the bag')
    return plot_history(hist, outdir, title=title)


def plot_comparison(runs: Sequence[tuple[str, History]], outdir: str | os.PathLike, *,
                    title: str = '', zoom: tuple[float, float, int] | None = None,
                    prefix: str = 'compare', zoom_data: Sequence[ZoomData] | None = None
                    ) -> list[Path]:
    """
    Write the ``compare`` figures: one per quantity, one panel per run (shared axes).

    Also ``<prefix>_zoom.png``: relative velocity and force of coupler ``j`` (0-based) of every
    run overlaid on the window ``zoom = (t0, t1, j)`` [s], where the sign model chatters;
    from ``zoom_data`` (per run: t [s], ydot [m/s], F [N] of that coupler in the window) when
    given, else from the runs' histories.
    """
    out = Path(outdir)
    out.mkdir(parents=True, exist_ok=True)
    if not runs:
        raise PlotError('no runs to compare')
    paths = [_save(_compare_figure(runs, quantity, title), out / f'{prefix}_{quantity[0]}.png')
             for quantity in COUPLER_QUANTITIES]
    if zoom is not None:
        if zoom_data is None:
            zoom_data = [_window_of(hist, zoom) for _, hist in runs]
        paths.append(_save(_zoom_figure([label for label, _ in runs], zoom_data, zoom, title),
                           out / f'{prefix}_zoom.png'))
    return paths


def _compare_figure(runs: Sequence[tuple[str, History]], quantity: tuple, title: str):
    """Return the figure of one coupler quantity: a panel per run, shared axes."""
    key, fld, scale, ylabel, heading = quantity
    n = len(runs)
    ncols = n if n <= 3 else math.ceil(n / 2)
    nrows = math.ceil(n / ncols)
    fig = _new_figure('compare')
    axes = np.atleast_1d(fig.subplots(nrows, ncols, sharex=True, sharey=True, squeeze=False)
                         ).ravel()
    for ax, (label, hist) in zip(axes, runs):
        c = hist.couplers
        _style(ax)
        _plot_lines(ax, c.t, getattr(c, fld) * scale, c.names, 'coupler',
                    legend=(ax is axes[0]), lw=1.0)
        ax.set_title(label, fontsize=11)
        _set_xlim(ax, c.t)
    for k, ax in enumerate(axes):
        if k >= n:
            ax.set_visible(False)
            continue
        if k % ncols == 0:
            ax.set_ylabel(ylabel, fontsize=11)
        if k // ncols == nrows - 1 or k + ncols >= n:
            ax.set_xlabel('time t [s]', fontsize=11)
            ax.xaxis.set_tick_params(labelbottom=True)
    fig.suptitle(heading + (f'\n{title}' if title else ''), fontsize=13)
    return fig


def _window_of(hist: History, zoom: tuple[float, float, int]) -> ZoomData:
    """Return t, ydot, F of coupler ``zoom[2]`` of ``hist`` in ``zoom[0]`` .. ``zoom[1]``."""
    t0, t1, jc = zoom
    c = hist.couplers
    sel = (c.t >= t0) & (c.t <= t1)
    return c.t[sel], c.velocity[sel, jc], c.effort[sel, jc]


def _zoom_figure(run_labels: Sequence[str], data: Sequence[ZoomData],
                 zoom: tuple[float, float, int], title: str):
    """Return the zoom figure: ydot and F of one coupler of every run on a short window."""
    t0, t1, jc = zoom
    fig = _new_figure('zoom')
    axes = fig.subplots(2, 1, sharex=True)
    colors, _ = _colors(len(run_labels))
    labels = {'velocity': f'relative velocity $\\dot{{y}}_{{{jc + 1}}}$ [m/s]',
              'force': f'coupler force F$_{{{jc + 1}}}$ [kN]'}
    for ax, (key, fld, scale, _, _) in zip(axes, COUPLER_QUANTITIES[1:]):
        _style(ax)
        sign_vals = []
        for k, (label, (t, ydot, force)) in enumerate(zip(run_labels, data)):
            vals = (ydot if fld == 'velocity' else force) * scale
            is_sign = label.startswith('sign')
            if is_sign:
                sign_vals.append(vals)
            ax.plot(t, vals, color=colors[k], linewidth=0.9 if is_sign else 1.6,
                    label=label, zorder=(10 - k) if is_sign else 3,
                    drawstyle='steps-post' if is_sign else 'default')
        if key == 'velocity' and sign_vals:
            # scale to the sign runs: their chattering is orders of magnitude smaller
            lim = 1.3 * max(float(np.nanmax(np.abs(v))) if v.size else 0.0 for v in sign_vals)
            if lim > 0:
                ax.set_ylim(-lim, lim)
                ax.set_title('relative velocity (axis scaled to the sign runs; smooth tanh '
                             'curves may leave it)', fontsize=10)
        ax.set_ylabel(labels[key], fontsize=11)
        ax.set_xlim(t0, t1)
    axes[0].legend(loc='best', fontsize=9, framealpha=0.9, ncols=2)
    axes[-1].set_xlabel('time t [s]', fontsize=11)
    fig.suptitle(f'Coupler {jc + 1} from {t0:.2f} s to {t1:.2f} s: the sign model chatters '
                 '(its friction force flips with the sign of $\\dot{y}$ every step)'
                 + (f'\n{title}' if title else ''), fontsize=12)
    return fig


def png_size(path: str | os.PathLike) -> tuple[int, int]:
    """Return (width, height) [px] from a PNG file's IHDR; ValueError if it is not a PNG."""
    with open(path, 'rb') as fh:
        head = fh.read(24)
    if len(head) < 24 or head[:8] != b'\x89PNG\r\n\x1a\n' or head[12:16] != b'IHDR':
        raise ValueError(f'{path}: not a PNG file')
    return int.from_bytes(head[16:20], 'big'), int.from_bytes(head[20:24], 'big')
