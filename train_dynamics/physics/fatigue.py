"""
Fatigue of the couplers: rainflow cycle counting and the damage-equivalent load.

Rainflow counting, the three-point method of ASTM E1049-85 (reapproved 2017), "Standard
Practices for Cycle Counting in Fatigue Analysis", section 5.4.4: the load history is reduced
to its turning points (peaks and valleys); scanning them in order, the last three points X
(the most recent range) and Y (the range before it) are compared; where X >= Y, Y is a cycle
(a full cycle, or a half cycle when Y contains the history's start); what is left at the end
counts as half cycles. The standard's worked example (its Fig. 6: -2, 1, -3, 5, -1, 3, -4,
4, -2 load units) gives ranges 3 (0.5 cycle), 4 (1.5), 6 (0.5), 8 (1.0), 9 (0.5); the tests
check this function against it.

Damage-equivalent load (DEL), Palmgren-Miner's linear damage rule with a Basquin S-N curve of
slope m (N S^m = const): the constant-amplitude range that does the same damage in N_eq
cycles as the counted spectrum,

    DEL = (sum_i n_i S_i^m / N_eq) ^ (1 / m)                                  [N]

with n_i the cycle count (0.5 for a half cycle) of range S_i [N]. m = 4 is the usual slope
for welded steel structures under variable amplitude (EN 1993-1-9, detail categories above
the knee point: m = 3, below: m = 5; m = 4 sits between and is the value used in the
accuracy contract of docs/integrators.md); N_eq defaults to 1 (the DEL of the whole run as
one cycle) so that it compares runs of the same length.

No ROS, no bag I/O here.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Cycles(NamedTuple):
    """Counted cycles: ``ranges`` [load units, >= 0] and ``counts`` (1.0 or 0.5 each)."""

    ranges: np.ndarray
    counts: np.ndarray


def turning_points(signal: np.ndarray, hysteresis: float = 0.0) -> np.ndarray:
    """
    Return the peaks and valleys of ``signal``, in order, the first and last samples included.

    Plateaus count once; a reversal smaller than ``hysteresis`` [load units] is ignored (the
    gate of ASTM E1049-85, 5.4.1, that keeps numerical noise out of the count).
    """
    x = np.asarray(signal, dtype=float).ravel()
    if x.size == 0:
        return x
    if not np.all(np.isfinite(x)):
        raise ValueError('rainflow: the signal holds NaN or infinity')
    points = [x[0]]
    direction = 0.0   # +1 rising, -1 falling, 0 not yet known
    for value in x[1:]:
        last = points[-1]
        delta = value - last
        if direction == 0.0:
            if abs(delta) > hysteresis:
                direction = np.sign(delta)
                points.append(value)
            continue
        if delta * direction >= 0.0:
            points[-1] = value   # the excursion goes on: move the extreme
        elif abs(delta) > hysteresis:
            points.append(value)   # a reversal
            direction = -direction
    return np.asarray(points)


def rainflow(signal: np.ndarray, hysteresis: float = 0.0) -> Cycles:
    """Rainflow cycles of ``signal`` (ASTM E1049-85, 5.4.4, three-point method)."""
    ranges: list[float] = []
    counts: list[float] = []
    stack: list[float] = []
    for point in turning_points(signal, hysteresis):
        stack.append(float(point))
        while len(stack) >= 3:
            x_range = abs(stack[-1] - stack[-2])
            y_range = abs(stack[-2] - stack[-3])
            if x_range < y_range:
                break
            if len(stack) == 3:
                # Y contains the starting point: a half cycle, the start is dropped
                ranges.append(y_range)
                counts.append(0.5)
                stack.pop(0)
            else:
                ranges.append(y_range)
                counts.append(1.0)
                last = stack.pop()
                del stack[-2:]
                stack.append(last)
    for a, b in zip(stack[:-1], stack[1:]):
        ranges.append(abs(b - a))
        counts.append(0.5)
    return Cycles(np.asarray(ranges, dtype=float), np.asarray(counts, dtype=float))


def damage_equivalent_load(cycles: Cycles, m: float = 4.0, n_eq: float = 1.0) -> float:
    """DEL = (sum n_i S_i^m / N_eq)^(1/m) [load units] (Palmgren-Miner, Basquin slope m)."""
    if m <= 0.0 or n_eq <= 0.0:
        raise ValueError('damage_equivalent_load: m and n_eq must be > 0')
    if cycles.ranges.size == 0:
        return 0.0
    return float((np.sum(cycles.counts * cycles.ranges ** m) / n_eq) ** (1.0 / m))


def cycle_count(cycles: Cycles, above: float) -> float:
    """Count the cycles (half cycles count 0.5) whose range exceeds ``above`` [load units]."""
    return float(np.sum(cycles.counts[cycles.ranges > above]))


def turning_points_of_block(block: np.ndarray) -> list[np.ndarray]:
    """
    Return per column of ``block`` (K samples, M columns) its peaks and valleys, vectorised.

    Equal to :func:`turning_points` with no hysteresis (plateaus once, first and last sample
    kept); used to compress a long history block by block before it is counted.
    """
    x = np.asarray(block, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    out = []
    for j in range(x.shape[1]):
        col = x[:, j]
        if col.size < 3:
            out.append(col.copy())
            continue
        keep = np.concatenate(([True], np.diff(col) != 0.0))
        col = col[keep]
        d = np.diff(col)
        turn = np.concatenate(([True], d[:-1] * d[1:] < 0.0, [True])) if col.size > 1 else \
            np.array([True])
        out.append(col[turn])
    return out


class FatigueFeed:
    """
    The rainflow count and damage-equivalent load of each coupler of a run, fed block by block.

    :meth:`add` takes blocks of coupler forces (K samples, M couplers) [N] and keeps only
    their turning points; :meth:`result` counts each coupler's whole history (ASTM E1049-85,
    :func:`rainflow`) and returns per coupler the DEL at slope ``m`` over one equivalent cycle
    and the number of cycles whose range exceeds ``threshold`` x the run's peak |F|.
    """

    def __init__(self, names: list[str], m: float = 4.0, threshold: float = 0.1) -> None:
        self.names = list(names)
        self.m = float(m)
        self.threshold = float(threshold)
        self._points: list[list[np.ndarray]] = [[] for _ in self.names]
        self._peak = 0.0

    def add(self, forces: np.ndarray) -> None:
        """Take a block of coupler forces [N], shape (K, M) in the order of ``names``."""
        f = np.asarray(forces, dtype=float)
        if f.size == 0:
            return
        if not np.all(np.isfinite(f)):
            raise ValueError('fatigue: the coupler forces hold NaN or infinity')
        self._peak = max(self._peak, float(np.max(np.abs(f))))
        for j, tp in enumerate(turning_points_of_block(f)):
            self._points[j].append(tp)

    def result(self) -> dict:
        """Return {'m', 'threshold_N', 'couplers': {name: {'del', 'cycles'}}, train-wide max}."""
        above = self.threshold * self._peak
        per = {}
        for name, parts in zip(self.names, self._points):
            history = np.concatenate(parts) if parts else np.zeros(0)
            cycles = rainflow(history)
            per[name] = {'del': damage_equivalent_load(cycles, self.m),
                         'cycles': cycle_count(cycles, above)}
        worst = max(per, key=lambda n: per[n]['del']) if per else None
        return {'m': self.m, 'threshold_N': above, 'couplers': per,
                'max_del': per[worst]['del'] if worst else None, 'max_del_coupler': worst,
                'cycles': float(sum(p['cycles'] for p in per.values()))}
