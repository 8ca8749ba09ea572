"""
A run of ``train-dynamics compare`` summarised as it goes: memory independent of its duration.

:class:`RunSummary` is the output sink (:func:`train_dynamics.simulation.runner.run_simulation`)
of one compare run. It keeps, in blocks of at most :data:`BLOCK_ROWS` samples or
:data:`BLOCK_SPAN` s:

- the curves for the figures (:class:`train_dynamics.recording.history.Envelope`, as for a
  bag's figures): every sample while a run has at most
  :data:`MAX_PLOT_SAMPLES`, else the minimum and the maximum of each of
  ``MAX_PLOT_SAMPLES / 2`` equal time bins (min/max decimation: the figure shows the same
  envelope as the full curve; a 1800-pixel-wide axis cannot show more);
- the table: max / min coupler force and the sign changes of ydot per second, exact;
- the zoom: the ``width`` [s] window where ydot flips sign most (per coupler, the window
  starting at a flip with the most flips before start + width, as
  :func:`zoom_candidates` defines), and the full-rate ydot and F of that coupler in it; also
  the full-rate samples of a window given in advance (``capture``).

y = x_i - x_{i+1} [m], ydot [m/s], F [N] from the simulator's force law (paper eqs. 2-7) at
the sampled state (as :class:`train_dynamics.recording.sinks.ArraySink` computes them).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math
from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.kernel import couplers
from train_dynamics.recording import history
from train_dynamics.recording.history import Envelope, History
from train_dynamics.simulation.runner import Sample

#: samples of a run kept for the figures before min/max decimation sets in (the figures of
#: a bag use the same, :data:`train_dynamics.recording.history.MAX_PLOT_SAMPLES`)
MAX_PLOT_SAMPLES = history.MAX_PLOT_SAMPLES
#: samples summarised at once (numpy on blocks), and the longest block [s]
BLOCK_ROWS = 4096
BLOCK_SPAN = 0.1


@dataclass(frozen=True)
class Window:
    """A zoom window: ``t0`` .. ``t1`` [s] on coupler ``j`` (0-based)."""

    t0: float
    t1: float
    j: int


@dataclass(frozen=True)
class Candidate:
    """The densest flips of a coupler: ``count`` flips of ydot from ``start`` [s]."""

    count: int
    start: float
    where: float          # [s] middle of the first and last flip of the window
    j: int


def zoom_window(where: float, j: int, duration: float, width: float) -> Window:
    """Return the window of ``width`` [s] centred on ``where``, inside [0, ``duration``]."""
    half = min(width, duration) / 2
    t0 = min(max(0.0, where - half), max(0.0, duration - 2 * half))
    return Window(t0, t0 + 2 * half, j)


def zoom_candidates(flips: np.ndarray, width: float, final_before: float
                    ) -> tuple[Candidate | None, int]:
    """
    Return the densest window among the flips whose window is complete, and how many are.

    A window starts at each flip time ``flips[k]`` (sorted) and counts the flips in
    [flips[k], flips[k] + width); it is complete when ``flips[k] + width <= final_before``
    (no later flip can fall in it). The first densest wins.
    """
    done = int(np.searchsorted(flips + width, final_before, side='right'))
    if done == 0:
        return None, 0
    counts = np.searchsorted(flips, flips[:done] + width) - np.arange(done)
    k = int(np.argmax(counts))
    c = int(counts[k])
    return Candidate(c, float(flips[k]), float(flips[k] + flips[k + c - 1]) / 2, -1), done


class RunSummary:
    """
    The output sink of one compare run (see the module documentation).

    ``expected``: the number of samples (sizes the figures' curves); ``period``: [s] between
    samples; ``track``: find this run's zoom window; ``capture``: keep the full-rate samples
    of this window.
    """

    def __init__(self, n: int, duration: float, expected: int, period: float, *,
                 width: float = 0.2, track: bool = False,
                 capture: Window | None = None) -> None:
        self.n, self.m = n, n - 1
        self.duration, self.width = duration, width
        self.track, self.capture = track, capture
        self.envelope = Envelope(self.m, duration, expected, limit=MAX_PLOT_SAMPLES)
        self.fmax = np.full(self.m, -np.inf)
        self.fmin = np.full(self.m, np.inf)
        self.changes = np.zeros(self.m, dtype=np.int64)
        self.t_first: float | None = None
        self.t_last = 0.0
        self.best: Candidate | None = None          # this run's densest flips (track)
        self.best_data: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.captured: list[np.ndarray] = []        # rows (t, ydot, F) in ``capture``
        self._sign = np.zeros(self.m)               # last non-zero sign of ydot
        self._flips = [np.zeros(0) for _ in range(self.m)]   # flips of incomplete windows
        self._ring = np.zeros((0, 3, self.m))       # recent (t, ydot, F) for the zoom
        self._ring_span = 3 * width + BLOCK_SPAN + 2 * period
        self._sim: Any = None
        self._t: list[float] = []
        self._x: list[np.ndarray] = []
        self._v: list[np.ndarray] = []

    # -- the sink --------------------------------------------------------------------------
    def sample(self, s: Sample) -> None:
        """Keep one sample; summarise a block when it is full."""
        self._sim = s.sim
        self._t.append(s.t)
        self._x.append(s.sim.x)
        self._v.append(s.sim.v)
        if len(self._t) >= BLOCK_ROWS or self._t[-1] - self._t[0] >= BLOCK_SPAN:
            self._flush()

    def finish(self) -> None:
        """Summarise the last block and the windows still open (call after the run)."""
        self._flush()
        if self.track:
            for j in range(self.m):
                self._consider(j, math.inf)

    # -- results ---------------------------------------------------------------------------
    def table(self) -> list[tuple[str, float, float, float]]:
        """Return (coupler, max F [N], min F [N], ydot sign changes per second) each."""
        span = self.t_last - self.t_first if self.t_first is not None else 0.0
        rate = self.changes / span if span > 0 else np.zeros(self.m)
        return [(name, float(self.fmax[j]), float(self.fmin[j]), float(rate[j]))
                for j, name in enumerate(topics.coupler_names(self.n))]

    def history(self, label: str) -> tuple[History, bool]:
        """Return the curves for the figures, and whether they are decimated."""
        series, decimated = self.envelope.series(topics.coupler_names(self.n))
        return History(couplers=series, label=label), decimated

    def zoom_data(self, window: Window) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Return t, ydot, F of ``window`` if this run kept them, else None."""
        if self.best is not None and window == self.best_window():
            return self.best_data
        if self.capture is not None and window == self.capture:
            rows = np.concatenate(self.captured) if self.captured else np.zeros((0, 3))
            return rows[:, 0], rows[:, 1], rows[:, 2]
        return None

    def best_window(self) -> Window | None:
        """Return the zoom window of this run's densest flips (``track``), or None."""
        if self.best is None:
            return None
        return zoom_window(self.best.where, self.best.j, self.duration, self.width)

    # -- internals -------------------------------------------------------------------------
    def _flush(self) -> None:
        if not self._t:
            return
        t = np.asarray(self._t)
        x, v = np.asarray(self._x), np.asarray(self._v)
        self._t, self._x, self._v = [], [], []
        y, yd = x[:, :-1] - x[:, 1:], v[:, :-1] - v[:, 1:]
        sim = self._sim

        def tile(a):
            return np.tile(a, len(t))

        force = couplers.coupler_force(y.ravel(), yd.ravel(), tile(sim.ke), tile(sim.kf),
                                       tile(sim.kec), tile(sim.kfc), sim.model, sim.u
                                       ).reshape(len(t), self.m)
        self.envelope.add(t, np.stack([y, yd, force], axis=1))
        self.fmax = np.fmax(self.fmax, np.nanmax(force, axis=0))
        self.fmin = np.fmin(self.fmin, np.nanmin(force, axis=0))
        if self.t_first is None:
            self.t_first = float(t[0])
        self.t_last = float(t[-1])
        self._count_flips(t, yd)
        if self.capture is not None:
            c = self.capture
            sel = (t >= c.t0) & (t <= c.t1)
            if np.any(sel):
                self.captured.append(np.stack([t[sel], yd[sel, c.j], force[sel, c.j]], axis=1))
        if self.track:
            block = np.stack([np.repeat(t[:, None], self.m, 1), yd, force], axis=1)
            ring = np.concatenate([self._ring, block])
            self._ring = ring[ring[:, 0, 0] >= self.t_last - self._ring_span]
            for j in range(self.m):
                self._consider(j, self.t_last)

    def _count_flips(self, t: np.ndarray, yd: np.ndarray) -> None:
        """Count the sign changes of ydot (0 skipped); keep the flip times when tracking."""
        for j in range(self.m):
            s = np.sign(yd[:, j])
            keep = (s != 0) & np.isfinite(yd[:, j])
            s, ts = s[keep], t[keep]
            if s.size == 0:
                continue
            prev = np.concatenate([[self._sign[j]], s[:-1]])
            flip = (s != prev) & (prev != 0)
            self.changes[j] += int(np.count_nonzero(flip))
            self._sign[j] = s[-1]
            if self.track and np.any(flip):
                self._flips[j] = np.concatenate([self._flips[j], ts[flip]])

    def _consider(self, j: int, final_before: float) -> None:
        """Take coupler ``j``'s completed windows; keep the densest of the run and its data."""
        flips = self._flips[j]
        if flips.size == 0:
            return
        cand, done = zoom_candidates(flips, self.width, final_before)
        self._flips[j] = flips[done:]
        if cand is None:
            return
        best = self.best
        # the first densest: more flips, or as many on a coupler of lower index
        if best is not None and (cand.count < best.count or (
                cand.count == best.count and j >= best.j)):
            return
        self.best = Candidate(cand.count, cand.start, cand.where, j)
        w = self.best_window()
        ring = self._ring
        sel = (ring[:, 0, j] >= w.t0) & (ring[:, 0, j] <= w.t1)
        self.best_data = (ring[sel, 0, j].copy(), ring[sel, 1, j].copy(),
                          ring[sel, 2, j].copy())


def densest(summaries: Sequence[RunSummary]) -> tuple[int, Candidate] | None:
    """Return (index, candidate) of the densest flips over ``summaries`` (first wins ties)."""
    out = None
    for k, s in enumerate(summaries):
        if s.best is not None and (out is None or s.best.count > out[1].count):
            out = (k, s.best)
    return out
