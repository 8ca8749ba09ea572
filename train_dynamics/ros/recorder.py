"""
``record_bag``: the bags of a ``sim_node`` run and the thread that writes them.

Topics are recorded under the node's resolved names (namespace and remapping applied, e.g.
``/train1/couplers``), the node's own publications with the QoS they offer. Inputs (raw CDR as
received, bag time = simulation time of the step at which the message took
effect, so ``train-dynamics simulate --input BAG`` replays the run) and outputs (bag time =
header stamp) go to a rosbag2 (MCAP) written by :class:`BagWriter` on its own thread: bag I/O
never delays the simulation. The MCAP file is finished every ``record_flush_period`` s (wall):
a SIGKILL loses at most that much; in ``sync_mode`` lockstep every ``record_flush_period`` s of
simulation time instead (at the first message at or after each multiple), so that the files of a
lock-step run are the same on every run, whatever the machine's speed. SIGINT and SIGTERM
close the bag completely. When writing fails (a full disk), nothing more is recorded; the bag
keeps its finished files, the node reports how many messages it holds
(:meth:`BagWriter.closed_message`, never more than what is on disk) and exits with status 1.
A ``reset`` continues in a new bag ``<record_bag>_reset<k>`` (:func:`reset_bag_path`; each bag
is one run from t = 0).
"""
from __future__ import annotations

from collections import deque
from pathlib import Path
import shutil
import threading
import time
from typing import Any, Callable, Mapping

from train_dynamics.physics.config import SimConfig
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.output_specs import output_type
from train_dynamics.recording.outputs import output_topics, parameters_json, run_metadata
from train_dynamics.ros.scheduling import normal_priority

#: messages queued for the bag writer before the simulation waits (the disk cannot keep up)
MAX_RECORD_BACKLOG = 20000
#: [bytes] queued for the bag writer before the simulation waits: 64 MiB, ~1 s of the outputs
#: of 20000 coaches at 100 Hz (~0.8 MB per output instant)
MAX_RECORD_BACKLOG_BYTES = 64 << 20


def check_bag_path(path: str) -> None:
    """Raise ``FileExistsError`` if ``path`` exists (a bag is never overwritten)."""
    p = Path(path)
    if p.exists() or p.is_symlink():
        raise FileExistsError(f'record_bag: {path} exists already, not overwriting')


def reset_bag_path(base: str, k: int) -> Path:
    """Return the first free ``<base>_reset<j>``, j >= ``k``: the bag after the k-th reset."""
    while True:
        path = Path(f'{str(base).rstrip("/")}_reset{k}')
        if not (path.exists() or path.is_symlink()):
            return path
        k += 1


def open_bag(path: Path, cfg: SimConfig, node_name: str, logger: Any,
             flush_period: float, resolve: Callable[[str], str] = str,
             offered: Mapping[str, Any] | None = None,
             sim_time_split: bool = False) -> BagWriter:
    """
    Create the bag of a run of ``cfg`` (metadata, output topics) and its writer thread.

    ``sim_time_split`` (lockstep): files finished at multiples of ``flush_period`` in
    simulation time, not wall time.
    ``resolve``: a topic's name as recorded (the node's resolved name: namespace and
    remapping applied); ``offered``: topic (as the node writes it) -> the QoS its publisher
    offers, for the topics the node publishes.
    """
    rec = BagRecorder(path)
    offered = dict(offered or {})
    try:
        info = run_metadata(cfg, 'sim_node', node=node_name, parameters=parameters_json(cfg))
        for key, value in info.items():
            rec.set_custom_data(key, value)
        for topic in output_topics(cfg):
            rec.add_topic(resolve(topic), output_type(topic), offered.get(topic))
    except Exception:
        rec.abort()
        raise
    return BagWriter(rec, logger, flush_period, resolve, offered,
                     sim_time_split=sim_time_split)


class BagWriter:
    """
    Write recorded messages to a BagRecorder on a thread of its own.

    Threads: :meth:`write` is called by whoever records (the simulation thread, the executor
    thread for diagnostics; both under the simulation lock); everything else in here belongs
    to the writer thread. ``written`` and ``error`` are written by the writer thread only and
    read by others for the diagnostics (a stale read is harmless). The queue (``_items``,
    ``_bytes``, ``_stop``) is guarded by ``_cond``.

    The backlog is bounded in BYTES (:data:`MAX_RECORD_BACKLOG_BYTES`) and in messages
    (:data:`MAX_RECORD_BACKLOG`): when the disk cannot keep up, :meth:`write` waits (the
    simulation falls behind and says so in ``/diagnostics``) rather than the queue eating the
    memory; a single message larger than the bound is still queued when the queue is empty.
    """

    def __init__(self, recorder: BagRecorder, logger: Any, flush_period: float,
                 resolve: Callable[[str], str] = str,
                 offered: Mapping[str, Any] | None = None,
                 sim_time_split: bool = False) -> None:
        self.recorder = recorder
        # lockstep: files split at multiples of the period in bag (simulation) time
        self._split_ns = int(round(float(flush_period) * 1e9)) if sim_time_split else 0
        self._next_split_ns = self._split_ns
        self._resolve = resolve
        self._offered = dict(offered or {})
        self._names: dict[str, str] = {}      # topic as written -> as recorded
        self.path = Path(recorder.path)
        self.written = 0
        self.error: str | None = None
        self._logger = logger
        self._flush_period = float(flush_period)
        self._cond = threading.Condition()
        self._items: deque[tuple[str, str, int, bytes]] = deque()
        self._bytes = 0
        self._stop = False
        self._discard = False
        self._thread = threading.Thread(target=self._run, name='train_dynamics_bag',
                                        daemon=True)
        self._thread.start()

    def write(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        """Queue raw CDR bytes; wait while the backlog is full (the writer catches up)."""
        size = len(data)
        with self._cond:
            while self._items and not self._stop and self._thread.is_alive() and (
                    self._bytes + size > MAX_RECORD_BACKLOG_BYTES
                    or len(self._items) >= MAX_RECORD_BACKLOG):
                self._cond.wait(0.5)
            self._items.append((topic, msgtype, t_ns, data))
            self._bytes += size
            self._cond.notify_all()

    @property
    def backlog(self) -> int:
        """Return the number of messages queued, not yet written."""
        return len(self._items)

    @property
    def backlog_bytes(self) -> int:
        """Return the bytes queued, not yet written."""
        return self._bytes

    def close(self, timeout: float | None = 30.0) -> None:
        """Write what is queued, finish the bag (idempotent)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread.is_alive():
            self._thread.join(timeout)

    def discard(self) -> None:
        """Stop without writing what is queued and remove the bag (a run that never started)."""
        with self._cond:
            self._discard = True
            self._items.clear()
            self._bytes = 0
        self.close()
        shutil.rmtree(self.path, ignore_errors=True)

    @property
    def saved(self) -> int:
        """Return the messages the bag holds (in finished files; all of them once closed)."""
        return self.recorder.saved

    def closed_message(self) -> str:
        """Return the line that reports the closed bag: its messages, or the failure."""
        saved = self.saved
        if self.error is None:
            return f'bag closed: {self.path} ({saved} messages)'
        return (f'recording to {self.path} failed ({self.error[:200]}): the bag holds {saved} '
                f'of the {self.written} messages recorded')

    def _fail(self, exc: Exception, more: str = '') -> None:
        self.error = f'{type(exc).__name__}: {exc}'.splitlines()[0]
        self._logger.error(f'recording to {self.path} failed: {self.error[:200]}{more}')

    def _store(self, item: tuple[str, str, int, bytes]) -> None:
        topic, msgtype, t_ns, data = item
        name = self._names.get(topic)
        if name is None:
            name = self._names[topic] = self._resolve(topic)
            qos = self._offered.get(topic)
            if qos is None:
                self.recorder.add_topic(name, msgtype)
            else:
                self.recorder.add_topic(name, msgtype, qos)
        self.recorder.write(name, t_ns, data)
        self.written += 1

    def _next(self) -> tuple[tuple[str, str, int, bytes] | None, bool]:
        """Return (the next item or None after 0.5 s idle, whether to stop)."""
        with self._cond:
            if not self._items and not self._stop:
                self._cond.wait(0.5)
            if not self._items:
                return None, self._stop
            item = self._items.popleft()
            self._bytes -= len(item[3])
            self._cond.notify_all()
            return item, False

    def _run(self) -> None:
        normal_priority()     # started by a real-time thread (reset): bag I/O stays normal
        last_flush = time.monotonic()
        unflushed = False
        try:
            while True:
                item, stop = self._next()
                if stop:
                    break
                if item is not None and self.error is None:
                    try:
                        if self._split_ns and item[2] >= self._next_split_ns:
                            if unflushed:
                                self.recorder.flush()
                                unflushed = False
                            self._next_split_ns = (item[2] // self._split_ns + 1) * self._split_ns
                        self._store(item)
                        unflushed = True
                    except Exception as exc:  # noqa: BLE001 - disk full, closed bag, ...
                        self._fail(exc, '; no further messages are recorded')
                now = time.monotonic()
                if (unflushed and self.error is None and not self._split_ns
                        and now - last_flush >= self._flush_period):
                    try:
                        self.recorder.flush()
                    except Exception as exc:  # noqa: BLE001
                        self._fail(exc)
                    last_flush, unflushed = now, False
        finally:
            try:
                if self._discard:
                    self.recorder.abort()
                else:
                    self.recorder.close()
            except Exception as exc:  # noqa: BLE001 - e.g. ENOSPC finishing the last file
                if self.error is None:
                    self._fail(exc)
