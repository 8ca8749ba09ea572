"""
Rosbag2 directories written with the ``rosbags`` library (no rosbag2 / ``ros2`` CLI).

:class:`BagRecorder` writes a rosbag2 directory (format version 9, MCAP storage), readable by
``rosbags`` and by ``ros2 bag``. Messages go in either as raw CDR bytes
(``rclpy.serialization.serialize_message(msg)``, or the encoders of
:mod:`train_dynamics.recording.cdr`), as ``rosbags`` message objects (built with
:mod:`train_dynamics.recording.messages`), or as rows of pre-encoded records
(:class:`~train_dynamics.recording.mcap_rows.RecordBlock`, the offline command's outputs).

Robustness. The ``rosbags`` MCAP writer keeps the current chunk (up to 1 MiB) in memory and
writes the MCAP summary/footer and ``metadata.yaml`` only in ``close()``; a writer killed
before ``close()`` (SIGKILL, power loss, crash of the interpreter) leaves an MCAP file that
no reader accepts and no ``metadata.yaml``: everything would be lost. The recorder therefore

* writes ``metadata.yaml`` at once (an empty but valid bag), and
* with ``split_seconds`` set, closes the current MCAP file and starts a new one whenever the
  bag time of a message is ``split_seconds`` or more away from the first message of the
  current file (rosbag2's own file splitting: one bag directory, files
  ``<name>_0.mcap``, ``<name>_1.mcap``, ...), rewriting ``metadata.yaml`` atomically to list
  every completed file (:mod:`train_dynamics.recording.bag_metadata`).

So after a SIGKILL the bag holds every completed file: at most the last ``split_seconds`` of
bag time are lost (the unfinished file is left under ``<bag>/.staging/`` and ignored by
readers). Without ``split_seconds`` (one file) a SIGKILL loses the whole recording, but the
bag directory still opens as an empty bag. SIGINT/SIGTERM handled by the caller with
``close()`` lose nothing. The files carry no wall-clock time: the same messages give
byte-identical bags.

Reading is :mod:`train_dynamics.recording.bag_read` (:func:`bag_info`, :func:`read_topics`,
:class:`BagError`); this module re-exports those names, the names a user of bags imports.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
import errno
import os
from pathlib import Path
import shutil
import threading
from typing import Any

import numpy as np
from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin

from train_dynamics.recording.bag_metadata import (BagMetadata, finished_segment, offered_qos,
                                                   ROS_DISTRO)
from train_dynamics.recording.bag_read import (bag_info, BagError, BagInfo, read_topics,
                                               shared_reader)
from train_dynamics.recording.mcap_rows import BlockWriter, RecordBlock
from train_dynamics.recording.messages import time_to_ns, typestore

#: errors of a write that found no room
DISK_FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)

__all__ = ['bag_info', 'BagError', 'BagInfo', 'BagRecorder', 'offered_qos', 'read_topics',
           'RecordBlock', 'recording_failed', 'ROS_DISTRO', 'shared_reader']


def _remove_stale_partials(parent: Path, name: str) -> None:
    """Remove ``.<name>.partial-<pid>`` directories of atomic writers that were killed."""
    try:
        candidates = list(parent.glob(f'.{name}.partial-*'))
    except OSError:
        return
    for cand in candidates:
        pid_text = cand.name.rsplit('-', 1)[-1]
        if not pid_text.isdigit() or int(pid_text) == os.getpid():
            continue
        try:
            os.kill(int(pid_text), 0)
            continue                                # the writer still runs: leave it alone
        except ProcessLookupError:
            shutil.rmtree(cand, ignore_errors=True)
        except (PermissionError, OverflowError, OSError):
            continue


def recording_failed(path: str | os.PathLike, error: str, held: int, given: int,
                     until_ns: int = 0) -> str:
    """
    Return the line that reports a recording that failed: what the bag holds, of what it got.

    One wording for the node's ``record_bag`` and the offline command: ``held`` messages in
    the bag (finished files, what a reader sees) of the ``given`` recorded, up to bag time
    ``until_ns`` [ns].
    """
    upto = f', up to t = {until_ns * 1e-9:.3f} s' if held else ''
    return (f'recording to {path} failed ({error}): the bag holds {held} of the {given} '
            f'messages recorded{upto}')


@dataclass
class _Open:
    writer: Any
    name: str
    connections: dict[str, Any] = field(default_factory=dict)
    first_ns: int | None = None


class BagRecorder:
    """
    Write a rosbag2 (version 9, MCAP) with ``rosbags``.

    ``BagRecorder(path)`` refuses an existing ``path`` (:class:`FileExistsError`).
    ``split_seconds``: start a new MCAP file when a message's bag time is that far from the
    first message of the current file (limits the loss on SIGKILL, see the module doc); None
    = one file. ``atomic``: write into a hidden sibling directory ``.<name>.partial-<pid>``
    and rename it to ``path`` in :meth:`close` (nothing appears under ``path`` before the bag
    is complete; :meth:`abort` removes everything; leftovers of killed writers are removed by
    the next atomic writer of the same name). ``file_stem``: base name of the MCAP files (default
    ``path``'s name). Thread-safe. Also a context manager (abort on an exception).
    """

    def __init__(self, path: str | os.PathLike, *, split_seconds: float | None = None,
                 atomic: bool = False, file_stem: str | None = None) -> None:
        self.path = Path(path)
        if self.path.exists() or self.path.is_symlink():
            raise FileExistsError(f'{self.path} exists already, not overwriting')
        if split_seconds is not None and not split_seconds > 0:
            raise ValueError(f'split_seconds must be > 0, got {split_seconds}')
        self._split_ns = None if split_seconds is None else time_to_ns(split_seconds)
        self._atomic = atomic
        self._stem = file_stem or self.path.name
        self._lock = threading.RLock()
        self._topics: dict[str, str] = {}          # topic -> msgtype, in order of addition
        self._qos: dict[str, Qos] = {}             # topic -> offered QoS (when known)
        self._open: _Open | None = None
        self._block: RecordBlock | None = None
        self._closed = False
        self.given = 0                             # messages given to be written
        if atomic:
            parent = self.path.parent if str(self.path.parent) else Path('.')
            _remove_stale_partials(parent, self.path.name)
            self._dir = parent / f'.{self.path.name}.partial-{os.getpid()}'
            if self._dir.exists():
                shutil.rmtree(self._dir)
        else:
            self._dir = self.path
        self._meta = BagMetadata(self._dir)
        self._staging = self._dir / '.staging'
        try:
            self._dir.mkdir(parents=True)
            self._write_metadata()
        except OSError as exc:
            shutil.rmtree(self._dir, ignore_errors=True)
            raise BagError(f'cannot create bag {self.path}: {exc.strerror or exc}') from None

    # -- public API ---------------------------------------------------------------------------
    @property
    def topics(self) -> dict[str, str]:
        """Return the registered topics -> message types."""
        return dict(self._topics)

    @property
    def closed(self) -> bool:
        return self._closed

    @property
    def saved(self) -> int:
        """
        Return the messages in finished MCAP files: what the bag holds if it stops now.

        Read without the lock (never waits for a write in progress).
        """
        return self._meta.count

    def add_topic(self, topic: str, msgtype: str, qos: Qos | None = None) -> None:
        """
        Register ``topic`` with ``msgtype`` (e.g. ``sensor_msgs/msg/JointState``).

        ``qos``: the profile its publisher offered (the metadata's ``offered_qos_profiles``).

        Idempotent; a different type for a known topic raises :class:`ValueError`, an
        unknown type :class:`KeyError`.
        """
        with self._lock:
            self._check_open()
            known = self._topics.get(topic)
            if known is not None:
                if known != msgtype:
                    raise ValueError(f'topic {topic!r} already has type {known}, not {msgtype}')
                return
            if msgtype not in typestore().types:
                raise KeyError(f'unknown message type {msgtype!r}')
            self._topics[topic] = msgtype
            if qos is not None:
                self._qos[topic] = qos
            if self._open is not None:
                self._add_connection(self._open, topic, msgtype)

    def attach(self, block: RecordBlock | None) -> None:
        """
        Write the rows of ``block`` from now on (its topics must be added); None: detach.

        The rows filled so far (of the block attached before) are written first. A row
        (:meth:`row`) must be filled before the next call to the recorder, from the same
        thread: the rows are written as they are then.
        """
        with self._lock:
            self._check_open()
            self._write_rows()
            if block is not None:
                missing = [t for t in block.topics if t not in self._topics]
                if missing:
                    raise KeyError(f'topics {missing} were not added (call add_topic first)')
                block.count = 0
            self._block = block

    def row(self, t_ns: int) -> int:
        """Return a new row of the attached block at bag time ``t_ns`` [ns] to fill now."""
        with self._lock:
            self._check_open()
            block = self._block
            t_ns = int(t_ns)
            if not 0 <= t_ns < 2 ** 63:
                raise ValueError(f'bag time must be in [0, 2^63) ns, got {t_ns}')
            if self._split_ns is not None:          # a new file from this row: now, as write()
                seg = self._open
                first = seg.first_ns if seg is not None and seg.first_ns is not None else (
                    int(block.times[0]) if block.count else None)
                if first is not None and abs(t_ns - first) >= self._split_ns:
                    self._write_rows()
                    if self._open is not None:
                        self._finish_segment()
            if block.full:
                self._write_rows()
            self.given += len(block.topics)
            return block.next_row(t_ns)

    def write(self, topic: str, t_ns: int, data: bytes | bytearray | memoryview) -> None:
        """Write one message as raw CDR bytes at bag time ``t_ns`` [ns]; topic must be added."""
        with self._lock:
            self._check_open()
            if topic not in self._topics:
                raise KeyError(f'topic {topic!r} was not added (call add_topic first)')
            t_ns = int(t_ns)
            if not 0 <= t_ns < 2 ** 63:
                raise ValueError(f'bag time must be in [0, 2^63) ns, got {t_ns}')
            self._write_rows()
            seg = self._open
            if seg is not None and self._split_ns is not None and seg.first_ns is not None \
                    and abs(t_ns - seg.first_ns) >= self._split_ns:
                self._finish_segment()
                seg = None
            if seg is None:
                seg = self._start_segment()
            if seg.first_ns is None:
                seg.first_ns = t_ns
            self.given += 1
            seg.writer.write(seg.connections[topic], t_ns, bytes(data))

    def _write_rows(self) -> None:
        """Write the filled rows of the attached block (splitting files as :meth:`write`)."""
        block = self._block
        if block is None or not block.count:
            return
        times = block.times[:block.count]
        start = 0
        while start < block.count:
            seg = self._open
            if seg is None:
                seg = self._start_segment()
            if seg.first_ns is None:
                seg.first_ns = int(times[start])
            end = block.count
            if self._split_ns is not None:
                far = np.flatnonzero(np.abs(times[start:] - seg.first_ns) >= self._split_ns)
                if far.size:
                    end = start + int(far[0])
            if end > start:
                rows = block.finish([seg.connections[t].id for t in block.topics], start, end)
                seg.writer.write_rows([seg.connections[t] for t in block.topics],
                                      block.record_offsets, times[start:end], rows)
            if end < block.count:
                self._finish_segment()
            start = end
        block.count = 0

    def write_msg(self, topic: str, t_ns: int, msg: Any) -> None:
        """Write a rosbags message object; adds the topic with the message's type if needed."""
        with self._lock:
            if topic not in self._topics:
                self.add_topic(topic, msg.__msgtype__)
            elif self._topics[topic] != msg.__msgtype__:
                raise ValueError(f'topic {topic!r} has type {self._topics[topic]}, '
                                 f'not {msg.__msgtype__}')
            self.write(topic, t_ns, typestore().serialize_cdr(msg, msg.__msgtype__))

    def set_custom_data(self, key: str, value: str) -> None:
        """Store ``key: value`` (strings) in the bag's ``metadata.yaml`` ``custom_data``."""
        self.update_custom_data({key: value})

    def update_custom_data(self, items: Mapping[str, str]) -> None:
        """Store every ``key: value`` of ``items`` (strings), writing ``metadata.yaml`` once."""
        if not all(isinstance(k, str) and isinstance(v, str) for k, v in items.items()):
            raise TypeError('custom data keys and values must be strings')
        with self._lock:
            self._check_open()
            self._meta.custom.update(items)
            self._write_metadata()

    def flush(self) -> None:
        """Finish the current MCAP file now (readable at once); later messages start a new one."""
        with self._lock:
            self._check_open()
            self._write_rows()
            if self._open is not None:
                self._finish_segment()

    def close(self) -> None:
        """
        Finish the bag (idempotent). With ``atomic``, the bag appears at ``path`` now.

        A full disk (:data:`DISK_FULL`) while finishing keeps the finished files as a closed,
        incomplete bag (:meth:`keep`); any other failure aborts (:meth:`abort`); both raise.
        """
        with self._lock:
            if self._closed:
                return
            try:
                self._write_rows()
                if self._open is not None or not self._meta.segments:
                    if self._open is None:
                        self._start_segment()      # an empty bag still records its topics
                    self._finish_segment()
                shutil.rmtree(self._staging, ignore_errors=True)
                self._move_into_place()
            except OSError as exc:
                if exc.errno in DISK_FULL:
                    self.keep(f'{exc.strerror or exc} while finishing the bag')
                else:
                    self.abort()
                raise
            except BaseException:
                self.abort()
                raise
            self._closed = True

    def _move_into_place(self) -> None:
        """With ``atomic``: rename the finished bag directory to ``path`` (never over one)."""
        if self._atomic:
            if self.path.exists() or self.path.is_symlink():
                raise FileExistsError(f'{self.path} exists already, not overwriting')
            os.rename(self._dir, self.path)

    @property
    def finished_files(self) -> int:
        """Return the number of finished MCAP files (read without the lock)."""
        return len(self._meta.segments)

    @property
    def saved_until_ns(self) -> int:
        """Return the bag time [ns] of the last message in finished MCAP files (0: none)."""
        return max((s.end_ns for s in list(self._meta.segments) if s.count), default=0)

    def keep(self, note: str = '') -> None:
        """
        Stop after a failed write (a full disk), keeping the finished MCAP files.

        The current file is dropped (freeing its space), ``metadata.yaml`` lists the finished
        files (``note`` in ``custom_data`` ``incomplete``); with ``atomic`` the directory
        then appears at ``path``: a closed, readable bag of what was finished. Raises (and
        aborts, removing everything with ``atomic``) if even that cannot be written.
        """
        with self._lock:
            if self._closed:
                return
            seg, self._open = self._open, None
            if self._block is not None:
                self._block.count = 0               # rows not written: dropped with the file
            if seg is not None:
                try:
                    seg.writer.abort()
                except Exception:  # noqa: BLE001 - best effort: the file is dropped anyway
                    pass
            try:
                shutil.rmtree(self._staging, ignore_errors=True)
                if note:
                    self._meta.custom['incomplete'] = note
                self._write_metadata()
                self._move_into_place()
            except BaseException:
                self.abort()
                raise
            self._closed = True

    def abort(self) -> None:
        """
        Stop without finishing the current file.

        With ``atomic``, remove everything; otherwise the finished files stay, listed in
        ``metadata.yaml`` (a readable bag), and the unfinished one (``.staging``) is removed.
        """
        with self._lock:
            if self._closed:
                return
            self._closed = True
            seg, self._open = self._open, None
            if seg is not None:
                try:
                    seg.writer.abort()
                except Exception:  # noqa: BLE001 - best effort
                    pass
            if self._atomic:
                shutil.rmtree(self._dir, ignore_errors=True)
            else:           # the finished files and their metadata.yaml stay: a readable bag
                shutil.rmtree(self._staging, ignore_errors=True)

    def __enter__(self) -> 'BagRecorder':
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False

    # -- internals ----------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise BagError(f'bag {self.path} is closed')

    def _add_connection(self, seg: _Open, topic: str, msgtype: str) -> None:
        qos = self._qos.get(topic)
        seg.connections[topic] = seg.writer.add_connection(
            topic, msgtype, typestore=typestore(), offered_qos_profiles=[qos] if qos else ())

    def _start_segment(self) -> _Open:
        name = f'{self._stem}_{len(self._meta.segments)}'
        self._staging.mkdir(exist_ok=True)
        seg_dir = self._staging / name
        if seg_dir.exists():
            shutil.rmtree(seg_dir)
        writer = BlockWriter(seg_dir, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.open()
        seg = _Open(writer, name)
        for topic, msgtype in self._topics.items():
            self._add_connection(seg, topic, msgtype)
        self._open = seg
        return seg

    def _finish_segment(self) -> None:
        seg, self._open = self._open, None
        assert seg is not None
        writer = seg.writer
        writer.close()
        seg_dir = writer.path
        segment = finished_segment(seg.name, seg_dir)
        mcap = self._dir / f'{seg.name}.mcap'
        os.replace(seg_dir / f'{seg.name}.mcap', mcap)
        shutil.rmtree(seg_dir, ignore_errors=True)
        self._meta.add(segment)
        try:
            self._write_metadata()
        except BaseException:
            # not listed, not held: the bag holds what its metadata.yaml lists, no more
            self._meta.drop_last()
            mcap.unlink(missing_ok=True)
            raise

    def _write_metadata(self) -> None:
        """Write ``metadata.yaml`` for the finished files (atomically)."""
        self._meta.write()
