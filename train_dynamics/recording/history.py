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

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import re

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.config import PARAMETERS
from train_dynamics.recording.bags import bag_info, BagError, read_topics

#: samples of a topic kept for the figures before min/max decimation sets in
MAX_PLOT_SAMPLES = 20000
#: messages of a topic converted at once (numpy on blocks)
BLOCK_ROWS = 4096

#: [Pa]; converts FluidPressure (absolute) to gauge: the simulator's default
ATMOSPHERIC_PRESSURE = float(PARAMETERS['atmospheric_pressure'].default)

#: topics read by :func:`load_history` -> the last part of their message type
_HISTORY_TOPICS = {name: msgtype.rsplit('/', 1)[-1] for name, msgtype in (
    (topics.COUPLERS_TOPIC, topics.JOINT_STATE), (topics.COACHES_TOPIC, topics.JOINT_STATE),
    (topics.BRAKE_CYLINDERS_TOPIC, topics.JOINT_STATE),
    (topics.BRAKE_RESERVOIRS_TOPIC, topics.JOINT_STATE),
    (topics.VEHICLE_FORCES_TOPIC, topics.JOINT_STATE),
    (topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE))}


class MalformedMessage(BagError):
    """A message that does not carry what its topic must (one line: topic, message, why)."""


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
    decimated: list[str] = field(default_factory=list)    # topics drawn as min/max bins
    non_finite: dict[str, str] = field(default_factory=dict)  # topic -> its NaN / inf values


def natural_key(name: str) -> list:
    """Return the sort key of a joint name in natural order (coupler_2 before coupler_10)."""
    return [int(p) if p.isdigit() else p for p in re.split(r'(\d+)', name)]


def _stamp_s(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


class Envelope:
    """
    Curves for the figures in bounded memory: every sample, or min/max per time bin.

    ``m`` columns of ``fields`` quantities. Rows are kept as they come while there are at most
    ``limit`` (None: no limit); past it, each quantity is kept as its minimum and maximum over
    ``limit / 2`` equal time bins (min/max decimation: the figure shows the envelope of the
    full curve; a 1800-pixel-wide axis cannot show more). With ``expected`` > ``limit`` the
    bins cover [0, ``duration``] from the start (``compare``: the run's length is known);
    otherwise they are set up when the rows overflow, over the time the rows spanned, scaled
    to ``count_hint`` rows (a bag's message count), and a time past the last bin merges bins
    pairwise (twice as wide) until it fits. Columns can be added (:meth:`widen`): missing
    values are NaN.
    """

    def __init__(self, m: int, duration: float = 0.0, expected: int | None = None, *,
                 fields: int = 3, limit: int | None = MAX_PLOT_SAMPLES,
                 count_hint: int | None = None) -> None:
        self.m, self.fields, self.limit = m, fields, limit
        self.count_hint = count_hint
        self.rows = 0
        self._t: list[np.ndarray] = []               # blocks of times (K,)
        self._q: list[np.ndarray] = []               # blocks of quantities (K, fields, m_k)
        self.exact = True
        if limit is not None and expected is not None and expected > limit:
            self._bins(0.0, duration / (limit // 2))

    @property
    def decimated(self) -> bool:
        """Return True once the curves are kept as min/max bins."""
        return not self.exact

    def _bins(self, t0: float, width: float) -> None:
        self.exact = False
        self.bins = self.limit // 2
        self.t0, self.width = t0, width if width > 0 else 1.0
        shape = (self.bins, self.fields, self.m)
        self.lo = np.full(shape, np.inf)
        self.hi = np.full(shape, -np.inf)
        self.seen = np.zeros(self.bins, dtype=bool)
        self.t_first, self.t_last = math.inf, -math.inf      # [s] of the samples binned

    def widen(self, k: int) -> None:
        """Add ``k`` columns (NaN before now)."""
        if k <= 0:
            return
        self.m += k
        if not self.exact:
            pad = np.where(self.seen[:, None, None], np.nan, np.inf)
            pad = np.broadcast_to(pad, (self.bins, self.fields, k))
            self.lo = np.concatenate([self.lo, pad], axis=2)
            self.hi = np.concatenate([self.hi, -pad], axis=2)

    def add(self, t: np.ndarray, q: np.ndarray) -> None:
        """Add a block: times ``t`` (K,) increasing, quantities ``q`` (K, fields, m)."""
        if self.exact:
            self._t.append(t)
            self._q.append(q)
            self.rows += t.shape[0]
            if self.limit is not None and self.rows > self.limit:
                self._overflow()
            return
        self.rows += t.shape[0]
        if t.size:
            self.t_first = min(self.t_first, float(t[0]))
            self.t_last = max(self.t_last, float(t[-1]))
        idx = np.floor((t - self.t0) / self.width)
        while idx.size and idx.max() > self.bins:
            self._coarsen()
            idx = np.floor((t - self.t0) / self.width)
        b = np.clip(idx, 0, self.bins - 1).astype(np.int64)
        np.minimum.at(self.lo, b, q)
        np.maximum.at(self.hi, b, q)
        self.seen[b] = True

    def _overflow(self) -> None:
        """Turn the rows kept so far into bins (past ``limit`` rows)."""
        t, q = self._rows()
        self._t, self._q = [], []
        rows = t.shape[0]
        span = float(t[-1] - t[0])
        expect = max(self.count_hint or 0, rows)
        self._bins(float(t[0]), span * (expect - 1) / max(rows - 1, 1) / (self.limit // 2))
        self.rows = 0
        self.add(t, q)

    def _coarsen(self) -> None:
        """Merge the bins pairwise: twice as wide, the second half empty."""
        half = self.bins // 2
        for arr, op in ((self.lo, np.minimum), (self.hi, np.maximum)):
            arr[:half] = op(arr[0:2 * half:2], arr[1:2 * half:2])
            if self.bins % 2:
                arr[half] = arr[self.bins - 1]
            arr[half + self.bins % 2:] = np.inf if op is np.minimum else -np.inf
        seen = self.seen[0:2 * half:2] | self.seen[1:2 * half:2]
        last = self.seen[self.bins - 1] if self.bins % 2 else None
        self.seen[:] = False
        self.seen[:half] = seen
        if last is not None:
            self.seen[half] = last
        self.width *= 2

    def _rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the kept rows: t (K,), q (K, fields, m) (columns added later: NaN)."""
        if not self._t:
            return np.zeros(0), np.zeros((0, self.fields, self.m))
        if len(self._t) == 1 and self._q[0].shape[2] == self.m:
            return self._t[0], self._q[0]
        q = np.full((self.rows, self.fields, self.m), np.nan)
        k = 0
        for block in self._q:
            q[k:k + block.shape[0], :, :block.shape[2]] = block
            k += block.shape[0]
        return np.concatenate(self._t), q

    def curves(self) -> tuple[np.ndarray, np.ndarray]:
        """
        Return t (K,) and the quantities (K, fields, m): the rows, or each bin's min and max.

        A bin's pair is drawn at its middle; the first and the last at the first and the last
        sample's time (so the curves span the run).
        """
        if self.exact:
            return self._rows()
        idx = np.nonzero(self.seen)[0]
        t = np.repeat(self.t0 + (idx + 0.5) * self.width, 2)
        if t.size:              # the curves span the samples' times (the axes' limits)
            t[:2], t[-2:] = self.t_first, self.t_last
        q = np.empty((2 * idx.size, self.fields, self.m))
        q[0::2], q[1::2] = self.lo[idx], self.hi[idx]
        return t, q

    def series(self, names: list[str]) -> tuple[JointSeries, bool]:
        """Return the curves (3 fields) as a JointSeries and whether they are decimated."""
        t, q = self.curves()
        return JointSeries(t.copy(), names, q[:, 0], q[:, 1], q[:, 2]), self.decimated


#: the fields of :func:`_joint_values`, in order
_FIELD_NAMES = ('position', 'velocity', 'effort')

#: JointState topics read -> the fields (indices into :data:`_FIELD_NAMES`) every message
#: must carry, one value per joint name: what the outputs carry
#: (:class:`train_dynamics.recording.outputs.OutputEncoder`: ``brake_cylinders`` and
#: ``brake_reservoirs`` leave ``velocity`` empty). Any other field is empty or one value per
#: name (the ``sensor_msgs/JointState`` rule); a message without names is malformed too.
REQUIRED_FIELDS = {topics.COUPLERS_TOPIC: (0, 1, 2), topics.COACHES_TOPIC: (0, 1, 2),
                   topics.BRAKE_CYLINDERS_TOPIC: (0, 2), topics.BRAKE_RESERVOIRS_TOPIC: (0, 2),
                   topics.VEHICLE_FORCES_TOPIC: (0, 1, 2)}


def malformed_joint_state(names: Sequence[str], values: Sequence[Sequence[float]],
                          required: Sequence[int]) -> str | None:
    """
    Return why a JointState does not carry one value per name, or None if it does.

    ``values``: its (position, velocity, effort); ``required``: the fields that must not be
    empty. A field with values has one per name (``sensor_msgs/msg/JointState``: "all arrays
    in this message should have the same size, or be empty").
    """
    n = len(names)
    if not n:
        return 'no joint names'
    for f, v in enumerate(values):
        k = len(v)
        if k != n and (k or f in required):
            return f'{k} {_FIELD_NAMES[f]} value(s) for {n} names'
    return None


def _joint_values(msg) -> tuple[Sequence[str], tuple[Sequence[float], ...]]:
    return msg.name, (msg.position, msg.velocity, msg.effort)


class TopicStream:
    """
    One topic of a bag read message by message into bounded curves (:class:`Envelope`).

    Time is the header stamp; if every stamp is zero the bag time (from the first message) is
    used (zero stamps before the first non-zero one are t = 0; past a block of them the
    topic restarts at the first non-zero one). Stamps that
    run backwards (the simulator was reset during a recording) restart the topic: only the
    last run is kept. Joints are matched by name, columns in natural order (coupler_2 before
    coupler_10). Blocks of :data:`BLOCK_ROWS` messages go to the envelope and to
    ``on_block(topic, t, q, names)`` (``q`` (K, fields, M), ``names`` of the M columns in
    arrival order); ``on_reset(topic)`` is called when the topic restarts. A JointState
    message that does not carry one value per joint name in the fields its topic needs
    (:data:`REQUIRED_FIELDS`, :func:`malformed_joint_state`) raises :class:`MalformedMessage`
    naming the topic and the message: figures or metrics of it would be wrong (an empty
    ``coaches`` read as a train at rest, a short array padded with NaN).
    """

    def __init__(self, topic: str, *, fields: int = 3, values: Callable = _joint_values,
                 limit: int | None = MAX_PLOT_SAMPLES, count_hint: int | None = None,
                 on_block: Callable | None = None, on_reset: Callable | None = None) -> None:
        self.topic, self.fields, self._values = topic, fields, values
        self.limit, self.count_hint = limit, count_hint
        self.on_block, self.on_reset = on_block, on_reset
        self.index: dict[str, int] = {}              # name -> column (arrival order)
        self.total = 0                               # messages read
        self.kept = 0                                # messages of the last run
        self.reset = False
        self.zero_stamps = True                      # every stamp so far is 0
        self._first_ns: int | None = None
        self._last_t = -math.inf
        self._names_cache: tuple[tuple, list[int]] = ((), [])
        self._block: list[tuple[float, list[int], tuple]] = []
        self.envelope = self._new_envelope()
        self.non_finite = 0                          # NaN / inf values given by a message
        self.first_non_finite: tuple[float, int, int, float] | None = None  # t, field, col, v
        #: fields a message must carry (None: no check, e.g. FluidPressure)
        self.required = REQUIRED_FIELDS.get(topic) if values is _joint_values else None

    def _new_envelope(self) -> Envelope:
        return Envelope(len(self.index), fields=self.fields, limit=self.limit,
                        count_hint=self.count_hint)

    def add(self, t_ns: int, msg) -> None:
        """Take one message received at bag time ``t_ns``."""
        if self._first_ns is None:
            self._first_ns = t_ns
        self.total += 1
        t = _stamp_s(msg)
        if self.zero_stamps:
            if t == 0.0:
                t = (t_ns - self._first_ns) * 1e-9
            else:
                self.zero_stamps = False
                self._zero_prefix()
        if t < self._last_t:
            self.reset = True
            self._restart()
        self._last_t = t
        names, vals = self._values(msg)
        if self.required is not None:
            why = malformed_joint_state(names, vals, self.required)
            if why is not None:
                raise MalformedMessage(
                    f'{self.topic}: message {self.total} (t = {t:.6g} s, bag time {t_ns} ns) '
                    f'does not carry one value per joint name ({why}): refused, nothing '
                    'written')
        key = tuple(names)
        if key != self._names_cache[0]:
            idx = [self.index.setdefault(str(n), len(self.index)) for n in names]
            self._names_cache = (key, idx)
        self._block.append((t, self._names_cache[1], vals))
        self.kept += 1
        if len(self._block) >= BLOCK_ROWS:
            self.flush()

    def _zero_prefix(self) -> None:
        """Give the messages with a zero stamp before the first non-zero one t = 0."""
        if self.kept > len(self._block):      # already flushed: a recording without stamps
            self._restart()                   # for a while; drop that part
            return
        self._block = [(0.0, idx, vals) for _, idx, vals in self._block]
        self._last_t = 0.0 if self._block else -math.inf

    def _restart(self) -> None:
        """Drop the run so far (its last block included)."""
        self._block = []
        self.kept = 0
        self.envelope = self._new_envelope()
        self.non_finite, self.first_non_finite = 0, None
        if self.on_reset is not None:
            self.on_reset(self.topic)

    def flush(self) -> None:
        """Put the buffered messages into the curves (and ``on_block``)."""
        if not self._block:
            return
        block, self._block = self._block, []
        m = len(self.index)
        self.envelope.widen(m - self.envelope.m)
        t = np.array([row[0] for row in block])
        q = np.full((len(block), self.fields, m), np.nan)
        given = np.zeros(q.shape, dtype=bool)        # NaN in q is also "no value given"
        k = 0
        while k < len(block):
            # a run of rows with the same joint names (the same list: _names_cache) is
            # copied field by field at once, where every row of it has one value per name
            idx = block[k][1]
            end = k + 1
            while end < len(block) and block[end][1] is idx:
                end += 1
            for f in range(len(block[k][2])):
                col = [row[2][f] for row in block[k:end]]
                if all(len(v) == len(idx) for v in col):
                    q[k:end, f, idx] = np.array(col, dtype=float).reshape(end - k, len(idx))
                    given[k:end, f, idx] = True
                    continue
                for r, v in enumerate(col, k):
                    v = np.asarray(v, dtype=float)
                    if v.shape == (len(idx),):
                        q[r, f, idx] = v
                        given[r, f, idx] = True
            k = end
        self._count_non_finite(t, q, given)
        self.envelope.add(t, q)
        if self.on_block is not None:
            self.on_block(self.topic, t, q, list(self.index))

    def _count_non_finite(self, t: np.ndarray, q: np.ndarray, given: np.ndarray) -> None:
        """Count the NaN / inf values the messages gave; keep the first (time order)."""
        bad = given & ~np.isfinite(q)
        n = int(np.count_nonzero(bad))
        if not n:
            return
        self.non_finite += n
        if self.first_non_finite is None:
            k, f, j = (int(a[0]) for a in np.nonzero(bad))
            self.first_non_finite = (float(t[k]), f, j, float(q[k, f, j]))

    def non_finite_note(self) -> str | None:
        """Return one line on the NaN / inf values the messages gave (None: all finite)."""
        if self.first_non_finite is None:
            return None
        t, f, j, v = self.first_non_finite
        names = {j: n for n, j in self.index.items()}
        field_name = _FIELD_NAMES[f] if self.fields == len(_FIELD_NAMES) else 'value'
        return (f'{self.topic}: {self.non_finite} non-finite value(s), the first {field_name} '
                f'of {names.get(j, "?")} = {v} at t = {t:.6g} s')

    def curves(self) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Return t (K,), q (K, fields, M) and the M names of the last run, natural order."""
        self.flush()
        t, q = self.envelope.curves()
        cols = sorted(self.index, key=natural_key)
        perm = [self.index[n] for n in cols]
        q = q[:, :, perm] if perm != list(range(len(perm))) else q
        return t.copy(), q, cols

    def series(self) -> JointSeries | None:
        """Return the curves of a JointState topic (None: no message)."""
        if not self.total:
            return None
        t, q, cols = self.curves()
        return JointSeries(t, cols, q[:, 0], q[:, 1], q[:, 2])

    def notes(self) -> list[str]:
        """Return what the reader met: zero stamps, a reset."""
        out = []
        if self.total and self.zero_stamps:
            out.append(f'{self.topic}: header stamps are zero, using bag time')
        if self.reset:
            out.append(f'{self.topic}: time runs backwards (reset during recording); '
                       f'plotting the last run only ({self.kept} of {self.total} messages)')
        return out


#: History attributes of the JointState topics, in the order notes are given
_JOINT_ATTRS = ((topics.COUPLERS_TOPIC, 'couplers'), (topics.COACHES_TOPIC, 'coaches'),
                (topics.BRAKE_CYLINDERS_TOPIC, 'cylinders'),
                (topics.BRAKE_RESERVOIRS_TOPIC, 'reservoirs'),
                (topics.VEHICLE_FORCES_TOPIC, 'forces'))


def stream_history(bag: str | os.PathLike, *, namespace: str = '',
                   atmospheric_pressure: float = ATMOSPHERIC_PRESSURE, keep_all: bool = False,
                   on_block: Callable | None = None,
                   on_reset: Callable | None = None,
                   only: Iterable[str] | None = None) -> History:
    """
    Read the output topics of a bag block-wise into bounded curves (:class:`TopicStream`).

    Memory does not depend on the bag's length: each topic keeps at most
    :data:`MAX_PLOT_SAMPLES` rows (``keep_all``: every row), then min/max bins
    (``History.decimated`` says which topics). ``on_block`` /
    ``on_reset`` see every block of every topic (short names: ``couplers``, ...), e.g. to
    compute the run metrics as the bag is read. ``namespace``: the node's namespace if it
    ran in one. ``only``: the short names of the topics to read (None: all of them).
    Raises :class:`train_dynamics.recording.bags.BagError` for an unreadable bag.
    """
    ns = namespace.strip('/')
    prefix = f'{ns}/' if ns else ''
    info = bag_info(bag)
    hist = History(label=Path(bag).name, info=dict(info.custom_data))
    limit = None if keep_all else MAX_PLOT_SAMPLES
    streams: dict[str, TopicStream] = {}
    for short, kind in _HISTORY_TOPICS.items():
        topic = prefix + short
        if topic not in info.topics or (only is not None and short not in only):
            continue
        if not info.topics[topic][0].endswith('/' + kind):
            hist.notes.append(f'{topic}: type {info.topics[topic][0]} ignored')
            continue
        opts = {'limit': limit, 'count_hint': info.topics[topic][1], 'on_block': on_block,
                'on_reset': on_reset}
        if short == topics.HEAD_PIPE_TOPIC:
            streams[topic] = TopicStream(short, fields=1, values=_head_values(
                atmospheric_pressure), **opts)
        else:
            streams[topic] = TopicStream(short, **opts)
    try:
        for topic, t_ns, msg in read_topics(bag, list(streams)):
            streams[topic].add(t_ns, msg)
    except MalformedMessage as exc:
        raise MalformedMessage(f'{bag}: {exc}') from None
    by_short = {s.topic: s for s in streams.values()}
    for short, attr in _JOINT_ATTRS:
        if short in by_short:
            setattr(hist, attr, by_short[short].series())
            hist.notes.extend(by_short[short].notes())
    for s in streams.values():
        note = s.non_finite_note()
        if note is not None:
            hist.non_finite[s.topic] = note
            hist.notes.append(note)

    head = by_short.get(topics.HEAD_PIPE_TOPIC)
    if head is not None and head.total:
        t, q, _ = head.curves()
        hist.head_pressure = (t, q[:, 0, 0])
    hist.decimated = [s.topic for s in streams.values() if s.envelope.decimated]
    return hist


def _head_values(atmospheric_pressure: float) -> Callable:
    """Return the values of a FluidPressure: one column, gauge pressure [Pa]."""
    def values(msg):
        return ('head',), ((msg.fluid_pressure - atmospheric_pressure,),)
    return values


def load_history(bag: str | os.PathLike, *, namespace: str = '',
                 atmospheric_pressure: float = ATMOSPHERIC_PRESSURE) -> History:
    """
    Read ``couplers``, ``coaches``, ``brake_cylinders``, ``vehicle_forces``, the head pipe.

    Every sample, in memory (:func:`stream_history` with ``keep_all``); for long bags use
    :func:`stream_history`. ``namespace``: the node's namespace if it ran in one
    (``/train1`` reads ``/train1/couplers``). Raises
    :class:`train_dynamics.recording.bags.BagError` for an unreadable bag.
    """
    return stream_history(bag, namespace=namespace, atmospheric_pressure=atmospheric_pressure,
                          keep_all=True)


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
