"""
How far a simulated force history is from a reference one: the metrics of the accuracy contract.

Every metric is a fraction of the reference's peak |F_ref| over all couplers and samples (so
1e-2 is "within 1 % of the peak"); inputs are arrays of shape (samples, couplers) on a common
time grid ``t`` [s] (the output samples, 100 Hz by default).

* ``worst_sample``: max |F - F_ref|: every sample. Well posed for short trains, impacts and
  replayed inputs; for long trains in stick-slip an individual sample depends on the masses to
  a degree no simulator can claim (docs/integrators.md, "The accuracy contract").
* ``tube``: the time-tolerant sample error, the distance of each sample from the band
  [min F_ref, max F_ref] over t +- ``tau`` (and the same with the roles exchanged, the larger
  taken): a force step that comes ``tau`` early or late costs nothing, a wrong level does.
  The "tube" comparison of the Modelica Association's regression-testing tool csv-compare,
  with the tube's width in time only.
* ``window_envelope``: per window of ``window`` seconds and coupler, the largest and the
  smallest force; the largest difference of either from the reference's.
* ``coupler_envelope``: the same over the whole run per coupler (max tension, max compression).
* ``del_error``: per coupler, the damage-equivalent load of the rainflow-counted history
  (:mod:`train_dynamics.physics.fatigue`, slope ``m``); the largest difference.
* ``cycle_count_error``: the rainflow cycles of range above ``cycle_threshold`` x the peak,
  summed over the couplers, relative to the reference's count (a fraction of that count, not of
  the peak).

No ROS, no bag I/O here.
"""
from __future__ import annotations

import numpy as np

from train_dynamics.physics.fatigue import cycle_count, damage_equivalent_load, rainflow


def _pair(f: np.ndarray, f_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    a = np.asarray(f, dtype=float)
    b = np.asarray(f_ref, dtype=float)
    if a.ndim == 1:
        a = a[:, None]
    if b.ndim == 1:
        b = b[:, None]
    if a.shape != b.shape:
        raise ValueError(f'comparison: shapes differ: {a.shape} and {b.shape}')
    peak = float(np.max(np.abs(b))) if b.size else 0.0
    if peak <= 0.0:
        raise ValueError('comparison: the reference is zero everywhere')
    return a, b, peak


def worst_sample(f: np.ndarray, f_ref: np.ndarray) -> float:
    """Return max |F - F_ref| / max |F_ref| over every sample and coupler."""
    a, b, peak = _pair(f, f_ref)
    return float(np.max(np.abs(a - b)) / peak)


def _running_extremes(x: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """Per sample k, min and max of x over samples k - half .. k + half (clipped at the ends)."""
    n = x.shape[0]
    lo = x.copy()
    hi = x.copy()
    for shift in range(1, half + 1):
        if shift >= n:
            break
        lo[shift:] = np.minimum(lo[shift:], x[:-shift])
        lo[:-shift] = np.minimum(lo[:-shift], x[shift:])
        hi[shift:] = np.maximum(hi[shift:], x[:-shift])
        hi[:-shift] = np.maximum(hi[:-shift], x[shift:])
    return lo, hi


def tube(t: np.ndarray, f: np.ndarray, f_ref: np.ndarray, tau: float = 0.01) -> float:
    """Largest distance of a sample from the other history's band over t +- tau, / peak."""
    a, b, peak = _pair(f, f_ref)
    t = np.asarray(t, dtype=float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
    half = int(round(tau / dt)) if tau > 0.0 else 0
    worst = 0.0
    for x, other in ((a, b), (b, a)):
        lo, hi = _running_extremes(other, half)
        outside = np.maximum(lo - x, 0.0) + np.maximum(x - hi, 0.0)
        worst = max(worst, float(np.max(outside)))
    return worst / peak


def window_envelope(t: np.ndarray, f: np.ndarray, f_ref: np.ndarray,
                    window: float = 1.0) -> float:
    """Largest difference of the per-window max and min [N] from the reference's, / peak."""
    a, b, peak = _pair(f, f_ref)
    t = np.asarray(t, dtype=float)
    index = np.floor((t - t[0]) / window + 1e-9).astype(int)
    worst = 0.0
    for k in np.unique(index):
        sel = index == k
        worst = max(worst,
                    float(np.max(np.abs(a[sel].max(axis=0) - b[sel].max(axis=0)))),
                    float(np.max(np.abs(a[sel].min(axis=0) - b[sel].min(axis=0)))))
    return worst / peak


def coupler_envelope(f: np.ndarray, f_ref: np.ndarray) -> float:
    """Largest difference of a coupler's max tension or max compression over the run, / peak."""
    a, b, peak = _pair(f, f_ref)
    return float(max(np.max(np.abs(a.max(axis=0) - b.max(axis=0))),
                     np.max(np.abs(a.min(axis=0) - b.min(axis=0)))) / peak)


def del_error(f: np.ndarray, f_ref: np.ndarray, m: float = 4.0) -> float:
    """Largest difference of a coupler's damage-equivalent load from the reference's, / peak."""
    a, b, peak = _pair(f, f_ref)
    worst = 0.0
    for j in range(a.shape[1]):
        ours = damage_equivalent_load(rainflow(a[:, j]), m)
        ref = damage_equivalent_load(rainflow(b[:, j]), m)
        worst = max(worst, abs(ours - ref))
    return worst / peak


def cycle_count_error(f: np.ndarray, f_ref: np.ndarray, cycle_threshold: float = 0.1) -> float:
    """(cycles above threshold x peak) - (the reference's), / the reference's; signed."""
    a, b, peak = _pair(f, f_ref)
    above = cycle_threshold * peak
    ours = sum(cycle_count(rainflow(a[:, j]), above) for j in range(a.shape[1]))
    ref = sum(cycle_count(rainflow(b[:, j]), above) for j in range(b.shape[1]))
    if ref == 0.0:
        return 0.0 if ours == 0.0 else float('inf')
    return float((ours - ref) / ref)


def all_metrics(t: np.ndarray, f: np.ndarray, f_ref: np.ndarray) -> dict[str, float]:
    """Every metric above at the accuracy contract's settings (tau 10 ms, 1 s windows, m 4)."""
    return {
        'worst_sample': worst_sample(f, f_ref),
        'tube_10ms': tube(t, f, f_ref, 0.01),
        'window_envelope_1s': window_envelope(t, f, f_ref, 1.0),
        'coupler_envelope': coupler_envelope(f, f_ref),
        'del_m4': del_error(f, f_ref, 4.0),
        'cycles_above_10pct': cycle_count_error(f, f_ref, 0.1),
    }
