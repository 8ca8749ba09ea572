"""
Time histories of a run as arrays: what the figures and ``compare`` work on.

:func:`load_history` reads the contract's output topics from a rosbag2 (offline command,
``record_bag`` or ``ros2 bag record``; topic names with or without a leading '/', optionally
under a namespace); time comes from ``header.stamp`` (simulation time). The offline
``compare`` command builds the same :class:`History` from its runs in memory
(:class:`train_dynamics.recording.sinks.ArraySink`). Drawing is in
:mod:`train_dynamics.recording.plots`.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
import os
from pathlib import Path
import re

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.parameters import PARAMETERS
from train_dynamics.recording.bags import bag_info, read_topics

#: [Pa]; converts FluidPressure (absolute) to gauge: the simulator's default
ATMOSPHERIC_PRESSURE = float(PARAMETERS['atmospheric_pressure'].default)

#: topics read by :func:`load_history` -> the last part of their message type
_HISTORY_TOPICS = {name: msgtype.rsplit('/', 1)[-1] for name, msgtype in (
    (topics.COUPLERS_TOPIC, topics.JOINT_STATE), (topics.COACHES_TOPIC, topics.JOINT_STATE),
    (topics.BRAKE_CYLINDERS_TOPIC, topics.JOINT_STATE),
    (topics.BRAKE_RESERVOIRS_TOPIC, topics.JOINT_STATE),
    (topics.VEHICLE_FORCES_TOPIC, topics.JOINT_STATE),
    (topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE))}


@dataclass
class JointSeries:
    """A JointState topic as arrays: row k = message k, column j = joint ``names[j]``."""

    t: np.ndarray                    # (K,) [s]
    names: list[str]
    position: np.ndarray             # (K, M); NaN where a message lacked the value
    velocity: np.ndarray
    effort: np.ndarray

    def __len__(self) -> int:
        return int(self.t.shape[0])


@dataclass
class History:
    """Time histories of one run (what the figures show)."""

    couplers: JointSeries | None = None
    coaches: JointSeries | None = None
    cylinders: JointSeries | None = None            # ``brake_cylinders`` topic
    reservoirs: JointSeries | None = None           # ``brake_reservoirs`` (pneumatic)
    forces: JointSeries | None = None               # ``vehicle_forces`` topic
    head_pressure: tuple[np.ndarray, np.ndarray] | None = None   # t [s], gauge [Pa]
    label: str = ''                                 # e.g. bag name, for titles
    info: dict[str, str] = field(default_factory=dict)   # model description (custom_data)
    notes: list[str] = field(default_factory=list)        # warnings met while loading


def _natural_key(name: str):
    return [int(p) if p.isdigit() else p for p in re.split(r'(\d+)', name)]


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def _last_run(t: np.ndarray) -> tuple[int, bool]:
    """Return where the last monotone run of stamps starts, and whether time ran backwards."""
    back = np.nonzero(np.diff(t) < 0)[0]
    return (int(back[-1]) + 1, True) if back.size else (0, False)


def joint_series(samples: Sequence[tuple[int, object]], topic: str = '',
                 notes: list[str] | None = None) -> JointSeries | None:
    """
    Turn JointState messages ``[(bag_t_ns, msg), ...]`` into a :class:`JointSeries`.

    Time is the header stamp. Joints are matched by name (columns in natural order:
    coupler_2 before coupler_10). If the stamps run backwards (the simulator was reset during
    a recording) only the last run is kept; if every stamp is zero the bag time (from the
    first message) is used.
    """
    if not samples:
        return None
    t = np.array([_stamp_s(m) for _, m in samples])
    if not np.any(t):
        t = (np.array([n for n, _ in samples], dtype=np.int64) - samples[0][0]) * 1e-9
        if notes is not None:
            notes.append(f'{topic}: header stamps are zero, using bag time')
    start, reset = _last_run(t)
    if reset and notes is not None:
        notes.append(f'{topic}: time runs backwards (reset during recording); '
                     f'plotting the last run only ({len(t) - start} of {len(t)} messages)')
    samples = samples[start:]
    t = t[start:]
    names: dict[str, None] = {}
    for _, m in samples:
        for n in m.name:
            names.setdefault(str(n), None)
    cols = sorted(names, key=_natural_key)
    index = {n: j for j, n in enumerate(cols)}
    arrays = {f: np.full((len(samples), len(cols)), np.nan) for f in ('position', 'velocity',
                                                                      'effort')}
    for k, (_, m) in enumerate(samples):
        idx = [index[str(n)] for n in m.name]
        for f, arr in arrays.items():
            vals = np.asarray(getattr(m, f), dtype=float)
            if vals.shape[0] == len(idx):
                arr[k, idx] = vals
    return JointSeries(t, cols, arrays['position'], arrays['velocity'], arrays['effort'])


def load_history(bag: str | os.PathLike, *, namespace: str = '',
                 atmospheric_pressure: float = ATMOSPHERIC_PRESSURE) -> History:
    """
    Read ``couplers``, ``coaches``, ``brake_cylinders``, ``vehicle_forces``, the head pipe.

    ``namespace``: the node's namespace if it ran in one (``/train1`` reads
    ``/train1/couplers``). Raises :class:`train_dynamics.recording.bags.BagError` for an
    unreadable bag.
    """
    ns = namespace.strip('/')
    prefix = f'{ns}/' if ns else ''
    wanted = {prefix + n: n for n in _HISTORY_TOPICS}
    info = bag_info(bag)
    data: dict[str, list] = {n: [] for n in wanted.values()}
    hist = History(label=Path(bag).name, info=dict(info.custom_data))
    usable = []
    for topic, short in wanted.items():
        if topic in info.topics:
            if info.topics[topic][0].endswith('/' + _HISTORY_TOPICS[short]):
                usable.append(topic)
            else:
                hist.notes.append(f'{topic}: type {info.topics[topic][0]} ignored')
    for topic, t_ns, msg in read_topics(bag, usable):
        data[wanted[topic]].append((t_ns, msg))
    for name, attr in ((topics.COUPLERS_TOPIC, 'couplers'), (topics.COACHES_TOPIC, 'coaches'),
                       (topics.BRAKE_CYLINDERS_TOPIC, 'cylinders'),
                       (topics.BRAKE_RESERVOIRS_TOPIC, 'reservoirs'),
                       (topics.VEHICLE_FORCES_TOPIC, 'forces')):
        setattr(hist, attr, joint_series(data[name], name, hist.notes))
    if data[topics.HEAD_PIPE_TOPIC]:
        samples = data[topics.HEAD_PIPE_TOPIC]
        t = np.array([_stamp_s(m) for _, m in samples])
        if not np.any(t):
            t = (np.array([n for n, _ in samples], dtype=np.int64) - samples[0][0]) * 1e-9
        p = np.array([m.fluid_pressure for _, m in samples]) - atmospheric_pressure
        start, _ = _last_run(t)
        hist.head_pressure = (t[start:], p[start:])
    return hist


def sign_changes_per_second(t: np.ndarray, values: np.ndarray, tol: float = 1e-9) -> np.ndarray:
    """
    Count the sign changes per second of each column of ``values``.

    ``|value| <= tol`` counts as 0 and is skipped, so +,0,- is one change.
    """
    values = np.atleast_2d(np.asarray(values, dtype=float).T).T
    span = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    out = np.zeros(values.shape[1])
    for j in range(values.shape[1]):
        s = np.sign(values[:, j])
        s = s[(np.abs(values[:, j]) > tol) & np.isfinite(values[:, j])]
        changes = int(np.count_nonzero(s[1:] != s[:-1]))
        out[j] = changes / span if span > 0 else 0.0
    return out
