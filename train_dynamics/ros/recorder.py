"""
``record_bag``: the bags of a ``sim_node`` run and the thread that writes them.

Inputs (raw CDR as received, bag time = simulation time of the step at which the message took
effect, so ``train-dynamics simulate --input BAG`` replays the run) and outputs (bag time =
header stamp) go to a rosbag2 (MCAP) written by :class:`BagWriter` on its own thread: bag I/O
never delays the simulation. The MCAP file is finished every ``record_flush_period`` s (wall):
a SIGKILL loses at most that much; SIGINT and SIGTERM close the bag completely. A ``reset``
continues in a new bag ``<record_bag>_reset<k>`` (:func:`reset_bag_path`; each bag is one run
from t = 0).
"""
from __future__ import annotations

from pathlib import Path
import queue
import threading
import time
from typing import Any

from train_dynamics import topics
from train_dynamics.physics.parameters import SimConfig
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.outputs import output_topics, parameters_json, run_metadata

#: messages queued for the bag writer before the simulation waits (the disk cannot keep up)
MAX_RECORD_BACKLOG = 20000


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
             flush_period: float) -> BagWriter:
    """Create the bag of a run of ``cfg`` (metadata, output topics) and its writer thread."""
    rec = BagRecorder(path)
    try:
        info = run_metadata(cfg, 'sim_node', node=node_name, parameters=parameters_json(cfg))
        for key, value in info.items():
            rec.set_custom_data(key, value)
        for topic in output_topics(cfg):
            rec.add_topic(topic, topics.JOINT_STATE)
    except Exception:
        rec.abort()
        raise
    return BagWriter(rec, logger, flush_period)


class BagWriter:
    """
    Write recorded messages to a BagRecorder on a thread of its own.

    Threads: :meth:`write` is called by whoever records (the simulation thread, the executor
    thread for diagnostics; both under the simulation lock); everything else in here belongs
    to the writer thread. ``written`` and ``error`` are written by the writer thread only and
    read by others for the diagnostics (a stale read is harmless).
    """

    def __init__(self, recorder: BagRecorder, logger: Any, flush_period: float) -> None:
        self.recorder = recorder
        self.path = Path(recorder.path)
        self.written = 0
        self.error: str | None = None
        self._logger = logger
        self._flush_period = float(flush_period)
        # Bounded: when the disk cannot keep up, the simulation waits (and says it is behind)
        # rather than the queue eating the memory.
        self._q: queue.Queue = queue.Queue(maxsize=MAX_RECORD_BACKLOG)
        self._known: set[str] = set()
        self._thread = threading.Thread(target=self._run, name='train_dynamics_bag',
                                        daemon=True)
        self._thread.start()

    def write(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        """Queue raw CDR bytes."""
        self._q.put((topic, msgtype, t_ns, data))

    @property
    def backlog(self) -> int:
        """Return the number of messages queued, not yet written."""
        return self._q.qsize()

    def close(self, timeout: float | None = 30.0) -> None:
        """Write what is queued, finish the bag (idempotent)."""
        if self._thread.is_alive():
            self._q.put(None)
            self._thread.join(timeout)

    def _fail(self, exc: Exception, more: str = '') -> None:
        self.error = f'{type(exc).__name__}: {exc}'.splitlines()[0]
        self._logger.error(f'recording to {self.path} failed: {self.error}{more}')

    def _store(self, item: tuple[str, str, int, bytes]) -> None:
        topic, msgtype, t_ns, data = item
        if topic not in self._known:
            self.recorder.add_topic(topic, msgtype)
            self._known.add(topic)
        self.recorder.write(topic, t_ns, data)
        self.written += 1

    def _run(self) -> None:
        last_flush = time.monotonic()
        unflushed = False
        try:
            while True:
                try:
                    item = self._q.get(timeout=0.5)
                except queue.Empty:
                    item = ()
                if item is None:
                    break
                if item and self.error is None:
                    try:
                        self._store(item)
                        unflushed = True
                    except Exception as exc:  # noqa: BLE001 - disk full, closed bag, ...
                        self._fail(exc, '; no further messages are recorded')
                now = time.monotonic()
                if unflushed and self.error is None and now - last_flush >= self._flush_period:
                    try:
                        self.recorder.flush()
                    except Exception as exc:  # noqa: BLE001
                        self._fail(exc)
                    last_flush, unflushed = now, False
        finally:
            try:
                self.recorder.close()
            except Exception as exc:  # noqa: BLE001
                self._logger.error(f'closing the bag {self.path} failed: {exc}')
