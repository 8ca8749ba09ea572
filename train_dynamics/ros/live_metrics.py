"""
The run metrics of ``sim_node``, computed off the simulation thread.

The simulation thread hands each published sample over (:meth:`LiveMetrics.put`: a deque
append, no computation) and folds the queued samples into the run's
:class:`train_dynamics.physics.metrics.RunMetrics` in its idle time, right after an output,
when :data:`FOLD_BATCH` have gathered and the next output is at least :data:`FOLD_SLACK` away
(:meth:`LiveMetrics.fold_if_idle`, called by the pacing outside the simulation lock); the
diagnostics callback folds what is left (:meth:`LiveMetrics.diagnostic`). Folding a second of
samples at once costs ~3-5 ms with 300 vehicles (vectorised, but the comfort windows keep 2 s
of history): done by the diagnostics callback under the simulation lock, as before, it
delayed the next output by as much once a second. ``bench/node.py``, 300 vehicles at 100 Hz,
interleaved 40 s runs: p99 output jitter 4.5-9.7 ms before, 1.0-3.8 ms after (folding in the
executor thread without the simulation lock still held the GIL: 3.9 ms).

Lock discipline: ``_queue`` is a ``collections.deque`` (append and popleft are atomic); the
metrics and the queue's replacement are guarded by ``_lock``. :meth:`put` is called with the
simulation lock held, :meth:`start` too (a reset), so no sample of an old run reaches a new
run's metrics. When the queue grows past :data:`MAX_PENDING` samples (the simulation runs
faster than real time, or nothing asks for diagnostics), :meth:`put` folds them in itself:
the memory stays bounded, at the cost of the simulation thread's time, which is then not
paced.
"""
from __future__ import annotations

from collections import deque
import threading
from typing import Any

from train_dynamics.physics.metrics import RunMetrics

#: samples waiting to be folded in at most; more are folded by the simulation thread
MAX_PENDING = 512
#: samples folded at once in the simulation thread's idle time (~1.5 ms at 300 vehicles)
FOLD_BATCH = 25
#: [s wall] the next output at least this far away: time to fold
FOLD_SLACK = 0.004


class LiveMetrics:
    """The node's run metrics: samples queued by the simulation thread, folded elsewhere."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._queue: deque = deque()
        self._metrics: RunMetrics | None = None

    def start(self, metrics: RunMetrics | None) -> None:
        """Begin a run's metrics (``None``: none); samples of the last run are dropped."""
        with self._lock:
            self._metrics = metrics
            self._queue = deque()

    def put(self, sim: Any) -> None:
        """Queue the present sample of ``sim`` (simulation lock held): copies, no computation."""
        if self._metrics is None:
            return
        queue = self._queue
        sliding = ((sim.sliding_time, sim.sliding_distance)
                   if getattr(sim, 'counts_sliding', False) else None)
        queue.append((sim.t, sim.y, sim.ydot, sim.coupler_force, sim.x, sim.v, sim.brake_force,
                      sim.coupler_force_envelope, sliding))
        if len(queue) > MAX_PENDING:
            self.fold()

    def fold_if_idle(self, slack: float) -> None:
        """Fold the queued samples if a batch has gathered and ``slack`` [s wall] allows."""
        if slack >= FOLD_SLACK and len(self._queue) >= FOLD_BATCH:
            self.fold()

    def fold(self) -> None:
        """Fold the queued samples into the run's metrics."""
        with self._lock:
            self._fold()

    def _fold(self) -> None:
        queue, metrics = self._queue, self._metrics
        envelope = sliding = None
        while queue:
            *sample, envelope, sliding = queue.popleft()
            metrics.add(*sample)
        if envelope is not None:        # running extremes: the latest holds the others
            metrics.set_envelope(*envelope)
        if sliding is not None:         # running sums: the latest holds the others
            metrics.set_sliding(*sliding)

    def set_limits(self, coupler_force_limit: float, jerk_limit: float) -> None:
        """Change the limits of the run's metrics (0 = off)."""
        with self._lock:
            if self._metrics is not None:
                self._metrics.set_limits(coupler_force_limit, jerk_limit)

    def diagnostic(self) -> tuple[str, str, list[tuple[str, str]]] | None:
        """Fold the queued samples in; return the metrics' /diagnostics status (None: none)."""
        with self._lock:
            if self._metrics is None:
                return None
            self._fold()
            return self._metrics.diagnostic()
