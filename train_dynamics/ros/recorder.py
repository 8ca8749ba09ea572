"""
``record_bag``: the bags of a ``sim_node`` run and the thread that writes them.

Topics are recorded under the node's resolved names (namespace and remapping applied, e.g.
``/train1/couplers``), the node's own publications with the QoS they offer. Inputs (raw CDR as
received, bag time = simulation time of the step at which the message took
effect, so ``train-dynamics simulate --input BAG`` replays the run) and outputs (bag time =
header stamp) go to a rosbag2 (MCAP) written by :class:`BagWriter` on its own thread: bag I/O
never delays the simulation. The MCAP file is finished ``record_flush_period`` s (wall) after
the previous one was (the period counts from the end of a flush, so flushes never follow each
other back to back however long one takes, and messages are written in between): a SIGKILL
loses about that much; in ``sync_mode`` lockstep every ``record_flush_period`` s of simulation
time instead (at the first message at or after each multiple), so that the files of a
lock-step run are the same on every run, whatever the machine's speed. SIGINT and SIGTERM
close the bag completely: :meth:`BagWriter.close` waits until every message given is written
(as long as the writer makes progress). When writing fails (a full disk), or the writer stops
making progress while closing, or the bag holds fewer messages than it was given, nothing more
is recorded; the bag keeps its finished files (no ``.staging`` left), the node reports how many
messages it holds of those recorded (:meth:`BagWriter.closed_message`, the offline command's
wording: :func:`~train_dynamics.recording.bags.recording_failed`; never more than what is on
disk) and exits with status 1.
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
from train_dynamics.recording.bags import BagRecorder, recording_failed
from train_dynamics.recording.output_specs import output_type
from train_dynamics.recording.outputs import output_topics, parameters_json, run_metadata
from train_dynamics.ros.scheduling import normal_priority

#: messages queued for the bag writer before the simulation waits (the disk cannot keep up)
MAX_RECORD_BACKLOG = 20000
#: [bytes] queued for the bag writer before the simulation waits: 64 MiB, ~1 s of the outputs
#: of 20000 coaches at 100 Hz (~0.8 MB per output instant)
MAX_RECORD_BACKLOG_BYTES = 64 << 20
#: [s] wall time without a message written or a file finished after which closing gives up
#: (a disk that no longer answers); the bag is then reported incomplete (exit 1)
CLOSE_STALL_TIMEOUT = 60.0


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
        self.given = 0                        # messages given to write() (the run's record)
        self.written = 0                      # of those, handed to the recorder
        self.late = 0                         # messages given after close() began (dropped)
        self.flushes = 0                      # files finished by the writer thread
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
        """
        Queue raw CDR bytes; wait while the backlog is full (the writer catches up).

        After :meth:`close` began, a message is not recorded (counted in :attr:`late`).
        """
        size = len(data)
        with self._cond:
            while self._items and not self._stop and self._thread.is_alive() and (
                    self._bytes + size > MAX_RECORD_BACKLOG_BYTES
                    or len(self._items) >= MAX_RECORD_BACKLOG):
                self._cond.wait(0.5)
            if self._stop:          # also when close() began while this call waited
                self.late += 1
                return
            self._items.append((topic, msgtype, t_ns, data))
            self._bytes += size
            self.given += 1
            self._cond.notify_all()

    @property
    def backlog(self) -> int:
        """Return the number of messages queued, not yet written."""
        return len(self._items)

    @property
    def backlog_bytes(self) -> int:
        """Return the bytes queued, not yet written."""
        return self._bytes

    def close(self, stall_timeout: float = CLOSE_STALL_TIMEOUT) -> None:
        """
        Write everything queued, finish the bag (idempotent); check that it holds it all.

        Waits as long as the writer makes progress (messages written, files finished); after
        ``stall_timeout`` s [wall] without any, gives up. Either way, a bag that does not hold
        every message given sets :attr:`error` (the node then exits 1).
        """
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        progress = None
        last = time.monotonic()
        while self._thread.is_alive():
            self._thread.join(0.2)
            now = time.monotonic()
            state = (self.written, self.flushes, self.backlog)
            if state != progress:
                progress, last = state, now
            elif now - last >= stall_timeout:
                if self.error is None:
                    self._fail(TimeoutError(
                        f'closing: no progress for {stall_timeout:g} s with {self.backlog} '
                        'message(s) still queued'), '; gave up on them')
                return
        if self.error is None and not self._discard and self.saved != self.given:
            self._fail(RuntimeError(f'{self.given - self.saved} message(s) not written'))

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
        late = (f'; {self.late} message(s) given after closing were not recorded'
                if self.late else '')
        if self.error is None:
            return f'bag closed: {self.path} ({saved} messages){late}'
        return recording_failed(self.path, self.error[:200], saved, self.given,
                                self.recorder.saved_until_ns) + late

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
        last_flush = time.monotonic()         # the end of the last flush
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
                                self.flushes += 1
                            self._next_split_ns = (item[2] // self._split_ns + 1) * self._split_ns
                        self._store(item)
                        unflushed = True
                    except Exception as exc:  # noqa: BLE001 - disk full, closed bag, ...
                        self._fail(exc, '; no further messages are recorded')
                if (unflushed and self.error is None and not self._split_ns
                        and time.monotonic() - last_flush >= self._flush_period):
                    try:
                        self.recorder.flush()
                    except Exception as exc:  # noqa: BLE001
                        self._fail(exc, '; no further messages are recorded')
                    # from the END of this flush: a flush longer than the period is followed
                    # by a period of writing, never by another flush at the next message
                    last_flush, unflushed = time.monotonic(), False
                    self.flushes += 1
        finally:
            try:
                if self._discard:
                    self.recorder.abort()
                elif self.error is not None:      # the file being written may be damaged
                    self.recorder.keep(self.error[:200])
                else:
                    self.recorder.close()
            except Exception as exc:  # noqa: BLE001 - e.g. ENOSPC finishing the last file
                if self.error is None:
                    self._fail(exc)
