"""
Run metrics: what an engineer asks of a run, computed from its output samples.

One accumulator, :class:`RunMetrics`, is fed with the output samples of a run (per coupler
t, y, ydot, F; per vehicle x, v, Fb: what the contract's coupler and vehicle outputs carry) and
keeps running values, so the very same code serves the offline runner (:meth:`RunMetrics.
sample` as a :func:`train_dynamics.simulation.runner.run_simulation` sink), the node (one
:meth:`RunMetrics.add` per published sample) and ``train-dynamics report`` (a recorded
history, :meth:`RunMetrics.add_block`). Samples are processed in blocks (vectorised over
samples and couplers); the result depends only on the samples, not on the block size.

Per coupler i (y = x_i - x_{i+1} [m], F > 0 tension, paper eqs. 4, 9):

* largest tension max(F) and compression max(-F) [N] and their times;
* the same over every integration step (the in-train force envelope, when the source is a
  simulator: :meth:`RunMetrics.set_envelope`), which the samples can miss: a buffer-blocking
  impact lasts a few tens of ms, so 100 Hz samples understate its peak by up to ~10 %;
* blocking (only with strokes): the coupler is blocked while y > g_t + S_t (draw gear) or
  y < -(g_c + S_c) (buffers), g = slack, S = stroke [m]; count of blockings and the worst
  overrun [m]; ``None`` strokes never block;
* free-play impacts (only with slack): a contact starts when y leaves [-g_c, g_t]; count and
  the largest closing speed |ydot| at contact [m/s];
* work done on the coupler, sum of the trapezoid rule over the samples of F ydot [J]; minus
  the elastic energy left at the end (when ``elastic_energy`` is given): the energy the
  coupler friction dissipated (paper eqs. 2-3).

Per vehicle: the braking work, trapezoid of Fb v [J]; the largest deceleration as the mean
over the comfort window W (default 1 s), a_W(t) = (v(t) - v(t - W)) / W, and as the mean
over one sample period (the coupler shocks); the largest jerk |a_W(t) - a_W(t - W)| / W
[m/s^3]. This is the evaluation of EN 12299 (ride comfort; its P_CT index takes the
acceleration as a 1 s moving average and the jerk as the difference of two such averages
1 s apart), applied to the longitudinal direction: it removes the coupler oscillations
(~2 Hz for 45 t coaches) that a passenger does not feel as jerk, and keeps the brake
application and release. Before the first sample the train is taken to run at constant
speed (a = 0), so a brake applied at t = 0 still shows its jerk.

Wheel slide (a simulator with rotating wheelsets or the adhesion limit as the source,
:meth:`RunMetrics.set_sliding`): per vehicle the time its wheels slid and the distance it ran
on sliding wheels (every integration step: a wheel is sliding while its slip exceeds the
slide-protection's vent threshold, :func:`train_dynamics.physics.kernel.wheelset.sliding`,
or, without wheelsets, while its brake asks for more than the adhesion carries,
:func:`train_dynamics.physics.kernel.wheelset.adhesion_limit`; wheel-flat risk); the
train's largest of each (``max_sliding_time``, ``max_sliding_distance`` and their vehicles,
present in :meth:`RunMetrics.flat` only with wheelsets or once the adhesion limit slid a
wheel).

Train: stopping time and distance, the first sample at which every |v_i| <= ``stop_speed``
(0.01 m/s), from the first sample (x of the leading vehicle) and from the brake onset (the
first sample with any Fb > 0); resolution one sample period. With a target stopping point
(``target_stop_position`` [m, track position]): the stop error [m] = track position of the
leading vehicle's front at the last sample (``track_origin`` + x_1) minus the target, > 0
overrun; defined only when the train is at rest then (else None: no stop to judge).

Sampling error: the energies integrate the output samples (default 100 Hz), not the
integrator's steps. Smooth parts: trapezoid error ~ (dt w)^2 / 12 relative (2e-4 for
dt = 10 ms at w = 13 rad/s, the coupler mode of the paper's train); each friction reversal
(a kink of F ydot) adds O(dt) locally. On the paper's run the brake energy is within
0.05 % and the coupler work within 1 % of the integrator's per-step integrals
(test/physics/test_metrics.py).

Limits (``coupler_force_limit`` [N] on |F|, ``jerk_limit`` [m/s^3]; 0 = off): every
excursion beyond a limit is a crossing {coupler or vehicle, start, end, peak value, time of
the peak}; the node reports them as WARN in /diagnostics (:meth:`RunMetrics.diagnostic`).

No ROS, no bag I/O here.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
import math
from typing import Any

import numpy as np

from train_dynamics.physics.kernel import couplers

#: comfort window W [s] of the mean deceleration and of the jerk (EN 12299 practice)
COMFORT_WINDOW = 1.0
#: a vehicle is at rest below this speed [m/s]
STOP_SPEED = 0.01
#: samples buffered by :meth:`RunMetrics.add` before a vectorised update
BLOCK = 256

#: the train-level metrics of :meth:`RunMetrics.flat` (a sweep's columns), SI units
FLAT_KEYS = ('max_tension', 'max_tension_coupler', 'max_tension_time', 'max_compression',
             'max_compression_coupler', 'max_compression_time', 'max_tension_every_step',
             'max_compression_every_step', 'stopped', 'stopping_time',
             'stopping_distance', 'stopping_time_from_brake', 'stopping_distance_from_brake',
             'brake_onset_time', 'final_speed', 'max_deceleration', 'max_deceleration_vehicle',
             'peak_deceleration', 'max_jerk', 'max_jerk_vehicle', 'max_jerk_time',
             'brake_energy', 'coupler_work', 'coupler_dissipated', 'blocking_count',
             'max_blocking_overrun', 'impact_count', 'max_impact_speed', 'limit_crossings',
             'samples', 't_end', 'stop_error')
#: the wheelsets' metrics of :meth:`RunMetrics.flat` (a simulator with rotating wheelsets)
SLIDING_KEYS = ('max_sliding_time', 'max_sliding_time_vehicle', 'max_sliding_distance',
                'max_sliding_distance_vehicle')


def _per_coupler(value: Any, m: int, default: float) -> np.ndarray:
    """Return ``value`` (None, scalar or m values) as m floats; None -> ``default``."""
    if value is None:
        return np.full(m, default)
    arr = np.broadcast_to(np.asarray(value, dtype=float), (m,)).copy()
    arr[~np.isfinite(arr)] = default
    return arr


def _runs(flags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return start and end (exclusive) indices of the runs of True in ``flags``."""
    d = np.diff(np.concatenate(([0], flags.astype(np.int8), [0])))
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def _rising(flags: np.ndarray, prev: np.ndarray) -> np.ndarray:
    """Return (K, M) True where ``flags`` turns on (``prev``: the row before the block)."""
    before = np.vstack((prev[None, :], flags[:-1]))
    return flags & ~before


def _interp_rows(tt: np.ndarray, vv: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Interpolate the rows ``vv`` (at times ``tt``) linearly at ``tq``; clamp at both ends."""
    n = tt.shape[0]
    if n == 1:
        return np.repeat(vv, tq.shape[0], axis=0)
    i = np.clip(np.searchsorted(tt, tq, side='right') - 1, 0, n - 2)
    dt = tt[i + 1] - tt[i]
    w = np.clip(np.divide(tq - tt[i], dt, out=np.zeros_like(tq), where=dt > 0), 0.0, 1.0)
    return vv[i] + (vv[i + 1] - vv[i]) * w[:, None]


class _Peak:
    """Running maximum of each column and the time at which it occurred."""

    def __init__(self, m: int, initial: float = 0.0) -> None:
        self.value = np.full(m, initial)
        self.t = np.full(m, np.nan)

    def update(self, t: np.ndarray, values: np.ndarray) -> None:
        """Take the (K, M) ``values`` at times ``t`` (K,); earlier times win ties."""
        if values.shape[0] == 0:
            return
        k = np.argmax(values, axis=0)
        best = values[k, np.arange(values.shape[1])]
        better = best > self.value
        self.value[better] = best[better]
        self.t[better] = t[k[better]]


class _Crossings:
    """Excursions of |values| beyond a limit, per column, across blocks."""

    def __init__(self, m: int, limit: float, what: str, names: list[str]) -> None:
        self.limit, self.what, self.names = float(limit), what, names
        self.open: dict[int, dict] = {}
        self.done: list[dict] = []

    def update(self, t: np.ndarray, values: np.ndarray) -> None:
        """Take the (K, M) signed ``values`` at times ``t``."""
        if self.limit <= 0.0:
            return
        over = np.abs(values) > self.limit
        cols = set(np.flatnonzero(over.any(axis=0)).tolist()) | set(self.open)
        for j in sorted(cols):
            starts, ends = _runs(over[:, j])
            if j in self.open and (starts.size == 0 or starts[0] > 0):
                self._close(j, t[0])
            for s, e in zip(starts, ends):
                seg = values[s:e, j]
                p = int(np.argmax(np.abs(seg)))
                ep = self.open.get(j) if s == 0 else None
                if ep is None:
                    ep = {self.what: j + 1, 'name': self.names[j], 'limit': self.limit,
                          't_start': float(t[s]), 't_end': None, 'value': float(seg[p]),
                          't': float(t[s + p])}
                    self.open[j] = ep
                elif abs(seg[p]) > abs(ep['value']):
                    ep['value'], ep['t'] = float(seg[p]), float(t[s + p])
                if e < len(t):
                    self._close(j, t[e])

    def _close(self, j: int, t_end: float) -> None:
        ep = self.open.pop(j)
        ep['t_end'] = float(t_end)
        self.done.append(ep)

    def all(self) -> list[dict]:  # noqa: A003 - reads as crossings.all()
        """Return every crossing, the open ones (``t_end`` None) included, by start time."""
        episodes = self.done + list(self.open.values())
        return sorted(episodes, key=lambda e: (e['t_start'], e['name']))


class RunMetrics:
    """
    The metrics accumulator of one run (see the module documentation).

    ``buffer_stroke`` / ``draw_gear_stroke`` (S_c, S_t [m]) and ``buffer_slack`` /
    ``draw_gear_slack`` (g_c, g_t [m]): None, a scalar or one value per coupler; None (or
    inf) stroke = never blocks, None slack = no free play. ``elastic_energy(y)`` returns the
    energy stored in each coupler at displacement y [J] (for the dissipated energy).
    ``coupler_names`` / ``vehicle_names``: the labels of the couplers (front first) and the
    vehicles in the rows, crossings and the diagnostic message; this layer knows only their
    positions (default ``coupler 1`` ..., ``vehicle 1`` ...): the recording layer passes the
    outputs' joint names (:func:`train_dynamics.recording.metrics_report.run_metrics`).
    """

    def __init__(self, n_vehicles: int, *, coupler_force_limit: float = 0.0,
                 jerk_limit: float = 0.0, buffer_stroke: Any = None,
                 draw_gear_stroke: Any = None, buffer_slack: Any = None,
                 draw_gear_slack: Any = None,
                 elastic_energy: Callable[[np.ndarray], np.ndarray] | None = None,
                 window: float = COMFORT_WINDOW, stop_speed: float = STOP_SPEED,
                 block: int = BLOCK, target_stop_position: float | None = None,
                 track_origin: float = 0.0, coupler_names: Sequence[str] | None = None,
                 vehicle_names: Sequence[str] | None = None) -> None:
        if n_vehicles < 2:
            raise ValueError('a train has at least 2 vehicles')
        n = self.n = int(n_vehicles)
        m = n - 1
        self.coupler_names = _labels(coupler_names, m, 'coupler')
        self.vehicle_names = _labels(vehicle_names, n, 'vehicle')
        self.window, self.stop_speed = float(window), float(stop_speed)
        self.gt = _per_coupler(draw_gear_slack, m, 0.0)
        self.gc = _per_coupler(buffer_slack, m, 0.0)
        self.block_t = self.gt + _per_coupler(draw_gear_stroke, m, np.inf)
        self.block_c = self.gc + _per_coupler(buffer_stroke, m, np.inf)
        self.has_slack = (self.gt > 0.0) | (self.gc > 0.0)
        self.elastic_energy = elastic_energy
        self._buf = {k: np.empty((block,) + s) for k, s in (
            ('t', ()), ('y', (m,)), ('ydot', (m,)), ('f', (m,)), ('x', (n,)), ('v', (n,)),
            ('fb', (n,)))}
        self._k = 0
        self._derive = np.zeros(block, dtype=bool)
        self.tension, self.compression = _Peak(m), _Peak(m)
        self.envelope: tuple[np.ndarray, np.ndarray] | None = None     # every step, if known
        self.sliding: tuple[np.ndarray, np.ndarray] | None = None      # wheelsets, if any
        self.overrun, self.impact_speed = _Peak(m), _Peak(m)
        self.decel, self.peak_decel, self.jerk = _Peak(n), _Peak(n), _Peak(n)
        self.blockings = np.zeros(m, dtype=np.int64)
        self.impacts = np.zeros(m, dtype=np.int64)
        self.coupler_work = np.zeros(m)
        self.brake_energy = np.zeros(n)
        self.force_crossings = _Crossings(m, coupler_force_limit, 'coupler', self.coupler_names)
        self.jerk_crossings = _Crossings(n, jerk_limit, 'vehicle', self.vehicle_names)
        self.samples = 0
        self._last: dict[str, Any] | None = None       # the last sample (arrays)
        self._flags = {'blocked': np.zeros(m, bool), 'engaged': np.zeros(m, bool)}
        self._hist_t = np.empty(0)                     # samples kept for the windows
        self._hist_v = np.empty((0, n))
        self.t_start = self.x_start = self.brake_onset = None
        self.stop_time = self.stop_x = None
        self.target, self.track_origin = target_stop_position, float(track_origin)

    # -- feeding -----------------------------------------------------------------------------
    def sample(self, s: Any) -> None:
        """Take a :class:`train_dynamics.simulation.runner.Sample` (a ``run_simulation`` sink)."""
        sim, b, k = s.sim, self._buf, self._k
        b['t'][k] = s.t
        b['x'][k], b['v'][k] = sim.x, sim.v
        b['f'][k], b['fb'][k] = sim.coupler_force, sim.brake_force
        self._derive[k] = True                 # y, ydot from x, v at the flush (eq. 9)
        self.set_envelope(*sim.coupler_force_envelope)
        if getattr(sim, 'counts_sliding', False):
            self.set_sliding(sim.sliding_time, sim.sliding_distance)
        self._next()

    def set_sliding(self, time: Sequence[float], distance: Sequence[float]) -> None:
        """Take each vehicle's sliding time [s] and distance [m] so far (every step)."""
        self.sliding = (np.array(time, dtype=float), np.array(distance, dtype=float))

    def set_envelope(self, tension: Sequence[float], compression: Sequence[float]) -> None:
        """
        Take the in-train force envelope so far: per coupler largest tension, compression [N].

        The simulator's extremes over every integration step since t = 0
        (``TrainSimulator.coupler_force_envelope``); without them (a recorded bag) the
        ``*_every_step`` metrics are None.
        """
        self.envelope = (np.array(tension, dtype=float), np.array(compression, dtype=float))

    def add(self, t: float, y: Sequence[float], ydot: Sequence[float], f: Sequence[float],
            x: Sequence[float], v: Sequence[float], fb: Sequence[float]) -> None:
        """Take one output sample at time ``t`` [s] (times increasing)."""
        b, k = self._buf, self._k
        b['t'][k] = t
        b['y'][k], b['ydot'][k], b['f'][k] = y, ydot, f
        b['x'][k], b['v'][k], b['fb'][k] = x, v, fb
        self._derive[k] = False
        self._next()

    def _next(self) -> None:
        self._k += 1
        if self._k == self._derive.shape[0]:
            self.flush()

    def add_block(self, t, y, ydot, f, x, v, fb) -> None:
        """Take K samples at once: ``t`` (K,), coupler arrays (K, N-1), vehicle (K, N)."""
        self.flush()
        self._process(*(np.nan_to_num(np.asarray(a, dtype=float))
                        for a in (t, y, ydot, f, x, v, fb)))

    def flush(self) -> None:
        """Process the buffered samples (done by :meth:`result` and when the buffer fills)."""
        k, self._k = self._k, 0
        if k:
            b = self._buf
            rows = self._derive[:k]
            if rows.any():
                x, v = b['x'][:k][rows], b['v'][:k][rows]
                b['y'][:k][rows], b['ydot'][:k][rows] = x[:, :-1] - x[:, 1:], v[:, :-1] - v[:, 1:]
            names = ('t', 'y', 'ydot', 'f', 'x', 'v', 'fb')
            self._process(*(np.nan_to_num(b[n][:k]) for n in names))

    # -- the update ------------------------------------------------------------------------
    def _process(self, t, y, ydot, f, x, v, fb) -> None:
        if t.shape[0] == 0:
            return
        first = self._last is None
        if first:
            self.t_start, self.x_start = float(t[0]), float(x[0, 0])
        self.tension.update(t, f)
        self.compression.update(t, -f)
        self.force_crossings.update(t, f)
        self._couplers(t, y, ydot)
        self._energies(t, ydot * f, fb * v)
        self._windows(t, v)
        self._stops(t, x, v, fb)
        self.samples += t.shape[0]
        self._last = {'t': float(t[-1]), 'y': y[-1].copy(), 'v': v[-1].copy(),
                      'pc': ydot[-1] * f[-1], 'pb': fb[-1] * v[-1], 'x1': float(x[-1, 0])}

    def _couplers(self, t, y, ydot) -> None:
        """Blocking and free-play impacts (the couplings' strokes and slacks)."""
        prev = self._flags
        over = np.maximum(y - self.block_t, -y - self.block_c)
        blocked = over > 0.0
        self.blockings += _rising(blocked, prev['blocked']).sum(axis=0)
        self.overrun.update(t, np.where(blocked, over, 0.0))
        engaged = ((y > self.gt) | (y < -self.gc)) & self.has_slack
        hit = _rising(engaged, prev['engaged'])
        self.impacts += hit.sum(axis=0)
        self.impact_speed.update(t, np.where(hit, np.abs(ydot), 0.0))
        self._flags = {'blocked': blocked[-1].copy(), 'engaged': engaged[-1].copy()}

    def _energies(self, t, pc, pb) -> None:
        """Trapezoid rule of F ydot and Fb v over the samples (with the previous block's)."""
        if self._last is not None:
            t = np.concatenate(([self._last['t']], t))
            pc = np.vstack((self._last['pc'], pc))
            pb = np.vstack((self._last['pb'], pb))
        dt = np.diff(t)[:, None]
        self.coupler_work += np.sum(0.5 * (pc[1:] + pc[:-1]) * dt, axis=0)
        self.brake_energy += np.sum(0.5 * (pb[1:] + pb[:-1]) * dt, axis=0)

    def _windows(self, t, v) -> None:
        """Sample and window (W) decelerations, window jerk, and the jerk crossings."""
        tt = np.concatenate((self._hist_t, t))
        vv = np.vstack((self._hist_v, v))
        k0 = self._hist_t.shape[0]
        if tt.shape[0] > 1:
            dt = np.diff(tt)[:, None]
            a = np.divide(np.diff(vv, axis=0), dt, out=np.zeros_like(vv[1:]), where=dt > 0)
            self.peak_decel.update(tt[1:][max(k0 - 1, 0):], -a[max(k0 - 1, 0):])
        w = self.window
        v1 = _interp_rows(tt, vv, t - w)
        v2 = _interp_rows(tt, vv, t - 2.0 * w)
        a_now = (v - v1) / w
        jerk = (a_now - (v1 - v2) / w) / w
        self.decel.update(t, -a_now)
        self.jerk.update(t, np.abs(jerk))
        self.jerk_crossings.update(t, jerk)
        keep = max(int(np.searchsorted(tt, tt[-1] - 2.0 * w, side='right')) - 1, 0)
        self._hist_t, self._hist_v = tt[keep:], vv[keep:]

    def _stops(self, t, x, v, fb) -> None:
        """Brake onset (first Fb > 0) and the first sample with the whole train at rest."""
        if self.brake_onset is None:
            on = np.flatnonzero(np.any(fb > 0.0, axis=1))
            if on.size:
                self.brake_onset = (float(t[on[0]]), float(x[on[0], 0]))
        if self.stop_time is None:
            rest = np.flatnonzero(np.all(np.abs(v) <= self.stop_speed, axis=1))
            if rest.size:
                self.stop_time, self.stop_x = float(t[rest[0]]), float(x[rest[0], 0])

    def set_limits(self, coupler_force_limit: float | None = None,
                   jerk_limit: float | None = None) -> None:
        """Change the limits [N], [m/s^3] (0 = off) from the next sample on (live change)."""
        self.flush()
        if coupler_force_limit is not None:
            self.force_crossings.limit = float(coupler_force_limit)
        if jerk_limit is not None:
            self.jerk_crossings.limit = float(jerk_limit)

    # -- results ---------------------------------------------------------------------------
    def result(self) -> dict[str, Any]:
        """Return every metric as a JSON-ready dict: ``train``, ``couplers``, ``vehicles``."""
        self.flush()
        return {'train': self.flat(), 'couplers': self._coupler_rows(),
                'vehicles': self._vehicle_rows(), 'crossings': self.crossings(),
                'settings': {'comfort_window': self.window, 'stop_speed': self.stop_speed,
                             'coupler_force_limit': self.force_crossings.limit,
                             'jerk_limit': self.jerk_crossings.limit}}

    def crossings(self) -> list[dict]:
        """Return every limit crossing: coupler force ones, then jerk ones, each by start time."""
        self.flush()
        return ([dict(e, kind='coupler_force') for e in self.force_crossings.all()]
                + [dict(e, kind='jerk') for e in self.jerk_crossings.all()])

    def flat(self) -> dict[str, Any]:
        """Return the train-level metrics (:data:`FLAT_KEYS`), SI units, None if undefined."""
        self.flush()
        if self._last is None:
            return dict.fromkeys(FLAT_KEYS) | {'samples': 0, 'stopped': False}
        jt, jc = int(np.argmax(self.tension.value)), int(np.argmax(self.compression.value))
        jd, jj = int(np.argmax(self.decel.value)), int(np.argmax(self.jerk.value))
        elastic = None
        if self.elastic_energy is not None:
            elastic = float(np.sum(self.elastic_energy(self._last['y'])))
        out = {
            'max_tension': float(self.tension.value[jt]),
            'max_tension_coupler': jt + 1, 'max_tension_time': _num(self.tension.t[jt]),
            'max_compression': float(self.compression.value[jc]),
            'max_compression_coupler': jc + 1,
            'max_compression_time': _num(self.compression.t[jc]),
            'max_tension_every_step': None, 'max_compression_every_step': None,
            'stopped': self.stop_time is not None,
            'stopping_time': _sub(self.stop_time, self.t_start),
            'stopping_distance': _sub(self.stop_x, self.x_start),
            'brake_onset_time': None if self.brake_onset is None else self.brake_onset[0],
            'stopping_time_from_brake': None, 'stopping_distance_from_brake': None,
            'final_speed': float(np.max(np.abs(self._last['v']))),
            'max_deceleration': float(self.decel.value[jd]), 'max_deceleration_vehicle': jd + 1,
            'peak_deceleration': float(np.max(self.peak_decel.value)),
            'max_jerk': float(self.jerk.value[jj]), 'max_jerk_vehicle': jj + 1,
            'max_jerk_time': _num(self.jerk.t[jj]),
            'brake_energy': float(np.sum(self.brake_energy)),
            'coupler_work': float(np.sum(self.coupler_work)),
            'coupler_dissipated': None if elastic is None else float(
                np.sum(self.coupler_work)) - elastic,
            'blocking_count': int(np.sum(self.blockings)),
            'max_blocking_overrun': float(np.max(self.overrun.value)),
            'impact_count': int(np.sum(self.impacts)),
            'max_impact_speed': float(np.max(self.impact_speed.value)),
            'limit_crossings': len(self.force_crossings.all()) + len(self.jerk_crossings.all()),
            'samples': self.samples, 't_end': self._last['t'], 'stop_error': None}
        if self.target is not None and out['final_speed'] <= self.stop_speed:
            out['stop_error'] = self.track_origin + self._last['x1'] - self.target
        if self.envelope is not None:
            out['max_tension_every_step'] = float(np.max(self.envelope[0]))
            out['max_compression_every_step'] = float(np.max(self.envelope[1]))
        if self.sliding is not None:
            it, ix = int(np.argmax(self.sliding[0])), int(np.argmax(self.sliding[1]))
            out.update(zip(SLIDING_KEYS, (float(self.sliding[0][it]), it + 1,
                                          float(self.sliding[1][ix]), ix + 1)))
        if self.brake_onset is not None and self.stop_time is not None:
            out['stopping_time_from_brake'] = self.stop_time - self.brake_onset[0]
            out['stopping_distance_from_brake'] = self.stop_x - self.brake_onset[1]
        return out

    def _coupler_rows(self) -> list[dict]:
        env = self.envelope
        return [{'name': name, 'max_tension': float(self.tension.value[j]),
                 'max_tension_time': _num(self.tension.t[j]),
                 'max_compression': float(self.compression.value[j]),
                 'max_compression_time': _num(self.compression.t[j]),
                 'max_tension_every_step': None if env is None else float(env[0][j]),
                 'max_compression_every_step': None if env is None else float(env[1][j]),
                 'work': float(self.coupler_work[j]),
                 'blocking_count': int(self.blockings[j]),
                 'max_blocking_overrun': float(self.overrun.value[j]),
                 'max_blocking_overrun_time': _num(self.overrun.t[j]),
                 'impact_count': int(self.impacts[j]),
                 'max_impact_speed': float(self.impact_speed.value[j]),
                 'max_impact_speed_time': _num(self.impact_speed.t[j])}
                for j, name in enumerate(self.coupler_names)]

    def _vehicle_rows(self) -> list[dict]:
        slide = self.sliding
        extra = [{} if slide is None else {
            'sliding_time': float(slide[0][i]), 'sliding_distance': float(slide[1][i])}
            for i in range(self.n)]
        return [{'name': name, 'max_deceleration': float(self.decel.value[i]),
                 'max_deceleration_time': _num(self.decel.t[i]),
                 'peak_deceleration': float(self.peak_decel.value[i]),
                 'peak_deceleration_time': _num(self.peak_decel.t[i]),
                 'max_jerk': float(self.jerk.value[i]), 'max_jerk_time': _num(self.jerk.t[i]),
                 'brake_energy': float(self.brake_energy[i]), **extra[i]}
                for i, name in enumerate(self.vehicle_names)]

    def diagnostic(self) -> tuple[str, str, list[tuple[str, str]]]:
        """
        Return (level, message, key-values) for the node's ``/diagnostics``.

        Level ``OK`` or ``WARN`` (a limit crossed: the message names the worst crossing,
        coupler or vehicle, value and time); the values are the running maxima (SI units).
        """
        f = self.flat()
        values = [(k, _fmt(f[k])) for k in (
            'max_tension', 'max_tension_coupler', 'max_tension_time', 'max_compression',
            'max_compression_coupler', 'max_compression_time', 'max_tension_every_step',
            'max_compression_every_step', 'max_deceleration',
            'max_jerk', 'max_jerk_vehicle', 'blocking_count', 'impact_count',
            'limit_crossings')]
        # wheelsets: the longest sliding time and distance so far, with their vehicles
        values += [(k, _fmt(f[k])) for k in SLIDING_KEYS if k in f]
        cross = self.crossings()
        if not cross:
            return 'OK', 'no limit crossed', values
        worst = max(cross, key=lambda e: abs(e['value']) / e['limit'])
        unit = 'N' if worst['kind'] == 'coupler_force' else 'm/s^3'
        what = 'force' if worst['kind'] == 'coupler_force' else 'jerk'
        return 'WARN', (f'{len(cross)} limit crossing(s); worst: {worst["name"]} {what} '
                        f'{worst["value"]:.4g} {unit} (limit {worst["limit"]:.4g}) at t = '
                        f'{worst["t"]:.3f} s'), values

    @classmethod
    def for_run(cls, cfg: Any, sim: Any = None, **kwargs: Any) -> 'RunMetrics':
        """
        Return the accumulator for a run of ``cfg`` (limits, strokes, slacks, stiffness).

        Strokes and slacks are taken, per coupler, from ``sim`` (attributes
        ``buffer_stroke`` ...) or else from ``cfg``'s consist (:meth:`Consist.coupler`, the
        reader the simulator builds its couplers with: a consist's ends in series), or else
        from ``cfg``'s parameters of the same names when present and > 0; the elastic energy
        from ``sim``'s coupler constants (paper eqs. 2-3), else the consist's, else ``cfg``'s
        uniform ones.
        """
        values = getattr(cfg, 'values', {})
        consist = getattr(cfg, 'consist', None)
        opts: dict[str, Any] = {
            'coupler_force_limit': float(values.get('coupler_force_limit', 0.0) or 0.0),
            'jerk_limit': float(values.get('jerk_limit', 0.0) or 0.0)}
        for name in ('buffer_stroke', 'draw_gear_stroke', 'buffer_slack', 'draw_gear_slack'):
            value = getattr(sim, name, None) if sim is not None else None
            if value is None and consist is not None:
                value = consist.coupler(name)
            if value is None and _positive(values.get(name)):
                value = values[name]
            opts[name] = value
        if sim is not None and hasattr(sim, 'ke'):
            ke, kec = np.asarray(sim.ke), np.asarray(sim.kec)
        elif consist is not None:
            ke = consist.coupler('buffer_stiffness')
            kec = consist.coupler('draw_gear_stiffness')
        else:
            ke = np.asarray(float(values.get('buffer_stiffness', 0.0)))
            kec = np.asarray(float(values.get('draw_gear_stiffness', 0.0)))
        if np.all(ke > 0) and np.all(kec > 0):
            opts['elastic_energy'] = lambda y: couplers.elastic_energy(
                y, np.broadcast_to(ke, y.shape), np.broadcast_to(kec, y.shape))
        target = values.get('target_stop_position') or []
        opts.update(target_stop_position=float(target[0]) if len(target) else None,
                    track_origin=float(values.get('initial_position', 0.0)))
        opts.update(kwargs)
        return cls(int(cfg.n_coaches), **opts)


def _labels(names: Sequence[str] | None, count: int, what: str) -> list[str]:
    """Return ``count`` labels: ``names`` (checked) or ``<what> 1`` ... by position."""
    if names is None:
        return [f'{what} {k}' for k in range(1, count + 1)]
    if len(names) != count:
        raise ValueError(f'{len(names)} {what} names for {count} {what}s')
    return list(names)


def _positive(value: Any) -> bool:
    try:
        return value is not None and float(value) > 0.0
    except (TypeError, ValueError):
        return False


def _num(value: float) -> float | None:
    return None if value is None or not math.isfinite(value) else float(value)


def _sub(a: float | None, b: float | None) -> float | None:
    return None if a is None or b is None else a - b


def _fmt(value: Any) -> str:
    if value is None:
        return 'n/a'
    if isinstance(value, float):
        return f'{value:.6g}'
    return str(value)
