"""
Brake blending metrics of a recorded run (``blending: builtin``), for ``train-dynamics report``.

From the bag's ``brake_blending`` and ``brake_demand/state`` (written by the offline command
and the node's ``record_bag``, the rows of :mod:`train_dynamics.recording.output_specs`) and
``coaches`` (x_i, v_i), all samples on the output grid (trapezoid rule in time):

- ``energy_regenerated`` [J]: the work of the ED brakes, integral of sum ED_i |v_i| dt;
- ``energy_friction`` [J]: dissipated in the friction brakes, integral of sum Fb_i |v_i| dt;
- ``energy_track_brake`` [J]: dissipated by the magnetic track brakes;
- ``friction_share`` [-]: friction over the three together;
- ``max_jerk`` [m/s^3] (with a demand state): the largest |d a / dt| of the achieved
  deceleration (brake forces over the inertial mass) between samples while the train moves;
- ``max_tracking_error``, ``rms_tracking_error`` [m/s^2]: |achieved - demanded deceleration|
  while a demand is applied and the train moves;
- ``stopping_time`` [s], ``stopping_distance`` [m]: from the first sample with a demand > 0
  (or the first emergency track brake force) to the first sample at rest (coach_1's x).

Returns None for a bag without those topics (a run without blending).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.recording.bags import read_topics


#: the keys of the blending section, in order (``summary.json``'s ``blending``)
BLENDING_KEYS = ('energy_regenerated', 'energy_friction', 'energy_track_brake',
                 'friction_share', 'max_jerk', 'max_tracking_error', 'rms_tracking_error',
                 'stopping_time', 'stopping_distance')


def _arrays(bag: str, topic: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return t [s], position, velocity, effort (samples x joints) of a JointState topic."""
    t, p, v, e = [], [], [], []
    for _, t_ns, m in read_topics(bag, [topic]):
        t.append(t_ns * 1e-9)
        p.append(np.array(m.position))
        v.append(np.array(m.velocity))
        e.append(np.array(m.effort))
    return np.array(t), np.array(p), np.array(v), np.array(e)


def _integral(t: np.ndarray, y: np.ndarray) -> float:
    """Return the trapezoid integral of y over t."""
    return float(np.sum(0.5 * (y[1:] + y[:-1]) * np.diff(t))) if len(t) > 1 else 0.0


def blending_metrics(bag: str, namespace: str = '') -> dict[str, Any] | None:
    """
    Return the blending metrics of the run in ``bag`` (see the module); None: none.

    Without ``brake_demand/state`` (``blending: external``: the controller under test holds
    the demand) the demand and deceleration metrics are None and the stop counts from the
    first brake force.
    """
    ns = namespace.strip('/')

    def name(topic):
        return f'{ns}/{topic}' if ns else topic
    try:
        tb, ed, fb, track = _arrays(bag, name(topics.BRAKE_BLENDING_TOPIC))
        if not len(tb):                 # no blending: the coaches are not read again
            return None
        tc, x, v, _ = _arrays(bag, name(topics.COACHES_TOPIC))
    except Exception:  # noqa: BLE001 - a bag without the topics: no blending metrics
        return None
    if len(tc) != len(tb):
        return None
    try:
        ts, demand, _, _ = _arrays(bag, name(topics.BRAKE_DEMAND_STATE_TOPIC))
    except Exception:  # noqa: BLE001 - no such topic (blending external)
        ts = np.zeros(0)
    has_demand = len(ts) == len(tb)
    speed = np.abs(v)
    regen = _integral(tb, np.sum(ed * speed, axis=1))
    friction = _integral(tb, np.sum(fb * speed, axis=1))
    track_e = _integral(tb, np.sum(track * speed, axis=1))
    total = regen + friction + track_e
    moving = speed.max(axis=1) > 0.0
    out: dict[str, Any] = {
        'energy_regenerated': regen,
        'energy_friction': friction,
        'energy_track_brake': track_e,
        'friction_share': friction / total if total > 0.0 else 0.0,
        'max_jerk': None, 'max_tracking_error': None, 'rms_tracking_error': None,
        'stopping_time': None, 'stopping_distance': None,
    }
    braking = (ed + fb + track).sum(axis=1) > 0.0
    if has_demand:
        a_dem, a_ach = demand[:, 0], demand[:, 1]
        both = moving[1:] & moving[:-1]
        jerk = np.abs(np.diff(a_ach)) / np.diff(ts)
        err = np.abs(a_ach - a_dem)[moving & (a_dem > 0.0)]
        out['max_jerk'] = float(jerk[both].max()) if both.any() else 0.0
        out['max_tracking_error'] = float(err.max()) if err.size else 0.0
        out['rms_tracking_error'] = float(np.sqrt(np.mean(err ** 2))) if err.size else 0.0
        braking = (a_dem > 0.0) | (track.sum(axis=1) > 0.0)
    onset = np.flatnonzero(braking)
    if onset.size:
        k0 = int(onset[0])
        rest = np.flatnonzero(~moving[k0:])
        if rest.size:
            k1 = k0 + int(rest[0])
            out['stopping_time'] = float(tc[k1] - tc[k0])
            out['stopping_distance'] = float(x[k1, 0] - x[k0, 0])
    return out


def blending_markdown(metrics: dict[str, Any] | None) -> list[str]:
    """Return the lines of summary.md's blending section ([] without blending)."""
    if not metrics:
        return []
    lines = ['## Brake blending', '', '| metric | value |', '| --- | --- |']
    for key, value in metrics.items():
        lines.append(f'| {key} | {"-" if value is None else f"{value:.6g}"} |')
    return lines + ['']
