"""
Rosbag2 directories written and read with the ``rosbags`` library (no rosbag2 / ``ros2`` CLI).

Writing: :class:`BagRecorder` writes a rosbag2 directory (format version 9, MCAP storage),
readable by ``rosbags`` and by ``ros2 bag``. Messages go in either as raw CDR bytes
(``rclpy.serialization.serialize_message(msg)``, or the encoders of
:mod:`train_dynamics.recording.cdr`) or as ``rosbags`` message objects (built with
:mod:`train_dynamics.recording.messages`).

Robustness. The ``rosbags`` MCAP writer keeps the current chunk (up to 1 MiB) in memory and
writes the MCAP summary/footer and ``metadata.yaml`` only in ``close()``; a writer killed
before ``close()`` (SIGKILL, power loss, crash of the interpreter) leaves an MCAP file that
no reader accepts and no ``metadata.yaml``: everything would be lost. The recorder therefore

* writes ``metadata.yaml`` at once (an empty but valid bag), and
* with ``split_seconds`` set, closes the current MCAP file and starts a new one whenever the
  bag time of a message is ``split_seconds`` or more away from the first message of the
  current file (rosbag2's own file splitting: one bag directory, files
  ``<name>_0.mcap``, ``<name>_1.mcap``, ...), rewriting ``metadata.yaml`` atomically to list
  every completed file.

So after a SIGKILL the bag holds every completed file: at most the last ``split_seconds`` of
bag time are lost (the unfinished file is left under ``<bag>/.staging/`` and ignored by
readers). Without ``split_seconds`` (one file) a SIGKILL loses the whole recording, but the
bag directory still opens as an empty bag. SIGINT/SIGTERM handled by the caller with
``close()`` lose nothing. The files carry no wall-clock time: the same messages give
byte-identical bags.

Speed. The offline command's outputs have a fixed shape (the same topics at every sample, each
message of a fixed size), so they are not written one message at a time: a
:class:`RecordBlock` holds the MCAP message records of up to about 1 MiB of samples, encoded in
place (:class:`train_dynamics.recording.outputs.OutputRows`), and :meth:`BagRecorder.attach`
writes its rows with one copy into the rosbags writer's chunk (:class:`_BlockMcap`), before
any other message and whenever the block is full. The messages are those of the per-message
path, byte for byte and in the same order (test/test_bag_blocks.py).

Reading: :func:`read_topics` reads MCAP or sqlite3 rosbag2 directories (or a bare ``.mcap`` /
``.db3`` file) through ``rosbags.highlevel.AnyReader`` with the ROS 2 Jazzy typestore for bags
that do not embed their message definitions. Topic names are returned without a leading
``/`` so that bags from ``ros2 bag record`` (``/couplers``) and ours (``couplers``) read alike.
"""
from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from io import BytesIO, StringIO
import os
from pathlib import Path
import shutil
import struct
import threading
from typing import Any

import numpy as np
from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.storage_mcap import McapWriter
from ruamel.yaml import YAML

from train_dynamics.recording.cdr import STAMP_OFFSET
from train_dynamics.recording.messages import time_to_ns, typestore


class BagError(Exception):
    """A bag that cannot be read or written; the message is one line and says why."""


def _one_line(exc: BaseException) -> str:
    text = ' '.join(str(a) for a in exc.args) if exc.args else type(exc).__name__
    return ' '.join(text.split()) or type(exc).__name__


def _norm_topic(topic: str) -> str:
    return topic[1:] if topic.startswith('/') else topic


# -- writing ----------------------------------------------------------------------------------

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


#: MCAP message record (opcode 0x05): opcode u8, record length u64, channel id u16,
#: sequence u32, log time u64, publish time u64, then the message's CDR bytes (MCAP spec,
#: https://mcap.dev/spec#message-op0x05); the offsets of the fields in it
_REC_CHANNEL, _REC_LOG, _REC_PUBLISH, _REC_DATA = 9, 15, 23, 31
#: [bytes] a chunk of the rosbags MCAP writer is closed once it holds more than this
_CHUNK_BYTES = 2 ** 20


class RecordBlock:
    """
    Messages of fixed sizes on fixed topics, one row per sample, encoded in place.

    A row holds one message of each of ``topics`` (in that order), all at the row's bag time;
    each message is an MCAP message record around the CDR bytes of its :class:`Layout`
    template (:mod:`train_dynamics.recording.cdr`), so a row is written to the bag with one
    copy and no per-message Python. ``stamped``: the messages whose header stamp is the bag
    time (set for every row when the block is written). Fill a row with :meth:`next_row` and
    :meth:`field` (views into the rows); :meth:`BagRecorder.attach` writes the rows, in
    order, before any other message and whenever the block is full.
    """

    def __init__(self, topics: Iterable[str], layouts: Iterable[Any], capacity: int | None = None,
                 stamped: Iterable[bool] | None = None) -> None:
        self.topics = tuple(topics)
        layouts = tuple(layouts)
        self.stamped = tuple(stamped) if stamped is not None else (True,) * len(layouts)
        row = bytearray()
        self._at = []                                  # offset of each record in the row
        for layout in layouts:
            self._at.append(len(row))
            size = _REC_DATA + len(layout.template)
            row += b'\x05' + (size - 9).to_bytes(8, 'little') + bytes(_REC_DATA - 9)
            row += layout.template
        self.row_bytes = len(row)
        if capacity is None:                          # about one chunk of the MCAP writer
            capacity = max(1, min(4096, _CHUNK_BYTES // self.row_bytes))
        self.capacity = int(capacity)
        self.rows = np.tile(np.frombuffer(bytes(row), np.uint8), (self.capacity, 1))
        self.times = np.zeros(self.capacity, np.int64)
        self.count = 0
        self._layouts = layouts

    def _column(self, offset: int, dtype: str, n: int = 1) -> np.ndarray:
        """Return a (capacity, n) view of ``n`` values of ``dtype`` at ``offset`` of each row."""
        size = np.dtype(dtype).itemsize
        return np.ndarray((self.capacity, n), dtype, self.rows, offset,
                          (self.row_bytes, size))

    def field(self, message: int, index: int) -> np.ndarray:
        """Return the (capacity, n) float64 view of field ``index`` of message ``message``."""
        layout = self._layouts[message]
        return self._column(self._at[message] + _REC_DATA + layout.fields[index], '<f8',
                            layout.lengths[index])

    def next_row(self, t_ns: int) -> int:
        """Return the index of a new row at bag time ``t_ns`` [ns] (the block must not be full)."""
        k = self.count
        self.times[k] = t_ns
        self.count = k + 1
        return k

    @property
    def full(self) -> bool:
        return self.count >= self.capacity

    def finish(self, ids: Iterable[int], start: int, end: int) -> np.ndarray:
        """
        Set bag times, stamps and channel ``ids`` of rows ``start:end``; return those rows.

        The offsets of the records (:attr:`record_offsets`) are relative to the first row.
        """
        rows = slice(start, end)
        times = self.times[rows]
        sec, nanosec = np.divmod(times, 1_000_000_000)
        for at, cid, stamped in zip(self._at, ids, self.stamped):
            self._column(at + _REC_CHANNEL, '<u2')[rows, 0] = cid
            self._column(at + _REC_LOG, '<u8')[rows, 0] = times
            self._column(at + _REC_PUBLISH, '<u8')[rows, 0] = times
            if stamped:
                self._column(at + _REC_DATA + STAMP_OFFSET, '<i4')[rows, 0] = sec
                self._column(at + _REC_DATA + STAMP_OFFSET + 4, '<u4')[rows, 0] = nanosec
        return self.rows[rows]

    @property
    def record_offsets(self) -> tuple[int, ...]:
        """Return the byte offset of each topic's record in a row."""
        return tuple(self._at)


class _BlockMcap(McapWriter):
    """
    The rosbags MCAP writer, plus rows of pre-encoded message records in one call.

    :meth:`write_rows` appends rows of a :class:`RecordBlock` to the pending chunk and keeps
    the chunk's message index, time range and the channel statistics as rosbags' own
    ``write`` keeps them for each message (rosbags 0.11.9, pinned in requirements.txt; the
    tests compare the bags of both paths message for message).
    """

    def write_rows(self, ids: list[int], offsets: tuple[int, ...], times: np.ndarray,
                   rows: np.ndarray) -> None:
        """
        Append ``rows`` (records at ``offsets`` of each row, channel ``ids``) at ``times``.

        A chunk is closed after the row that takes it past :data:`_CHUNK_BYTES`, as rosbags
        closes it after such a message: chunks stay about 1 MiB (a reader holds one chunk's
        messages at a time).
        """
        size = rows.shape[1]
        start = 0
        while start < len(times):
            room = _CHUNK_BYTES - self.chunk.bio.tell()
            end = min(len(times), start + max(0, room) // size + 1)
            self._append(ids, offsets, times[start:end], rows[start:end])
            if self.chunk.bio.tell() > _CHUNK_BYTES:
                self.close_chunk()
            start = end

    def _append(self, ids: list[int], offsets: tuple[int, ...], times: np.ndarray,
                rows: np.ndarray) -> None:
        """Append ``rows`` to the pending chunk; index them as rosbags' ``write`` does."""
        chunk = self.chunk
        base = chunk.bio.tell()
        chunk.bio.write(memoryview(np.ascontiguousarray(rows)).cast('B'))
        t_first, t_last = int(times.min()), int(times.max())
        self.message_start_time = min(t_first, self.message_start_time)
        self.message_end_time = max(t_last, self.message_end_time)
        chunk.message_start_time = min(t_first, chunk.message_start_time)
        chunk.message_end_time = max(t_last, chunk.message_end_time)
        t_list = times.tolist()
        row_at = np.arange(len(t_list), dtype=np.int64) * rows.shape[1] + base
        for cid, at in zip(ids, offsets):
            chunk.msgs[cid].extend(zip(t_list, (row_at + at).tolist()))
            self.channel_stats[cid] += len(t_list)

    def close_chunk(self) -> None:
        """
        Write the pending chunk, its message indexes and keep its chunk index.

        The records of rosbags' own ``close_chunk`` (MCAP spec: Chunk op 0x06, Message Index
        op 0x07, Chunk Index op 0x08), with the chunk's bytes written without the copies and
        each message index packed by numpy instead of 16 bytes at a time.
        """
        chunk = self.chunk
        comp = self.compression.encode()
        out = self.bio
        with chunk.bio.getbuffer() as data:
            size = len(data)
            payload = self.compressor(bytes(data)) if self.compression else data
            head = struct.pack('<QQQI', chunk.message_start_time, chunk.message_end_time,
                               size, 0) + struct.pack('<I', len(comp)) + comp + struct.pack(
                '<Q', len(payload))
            chunk_start = out.tell()
            out.write(b'\x06' + struct.pack('<Q', len(head) + len(payload)) + head)
            out.write(payload)
            stored = len(payload)
            del payload
        chunk_end = out.tell()
        offsets: list[tuple[int, int]] = []
        for cid, msgs in chunk.msgs.items():
            offsets.append((cid, out.tell()))
            index = np.asarray(msgs, dtype='<u8').tobytes()
            out.write(b'\x07' + struct.pack('<QHI', 6 + len(index), cid, len(index)) + index)
        rec = BytesIO()
        rec.write(struct.pack('<QQQQI', chunk.message_start_time, chunk.message_end_time,
                              chunk_start, chunk_end - chunk_start, len(offsets) * 10))
        for cid, offset in offsets:
            rec.write(struct.pack('<HQ', cid, offset))
        rec.write(struct.pack('<QI', out.tell() - chunk_end, len(comp)) + comp)
        rec.write(struct.pack('<QQ', stored, size))
        self.chunks.append(rec)
        self.chunk = type(chunk)(2 ** 63 - 1, 0, BytesIO(), defaultdict(list))


class _Writer(Writer):
    """The rosbags rosbag2 writer with :class:`_BlockMcap` storage and :meth:`write_rows`."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: _BlockMcap}

    def write_rows(self, connections: list[Any], offsets: tuple[int, ...], times: np.ndarray,
                   rows: np.ndarray) -> None:
        """Write rows of records on ``connections`` (counted as rosbags' ``write`` counts)."""
        self.storage.write_rows([c.id for c in connections], offsets, times, rows)
        for c in connections:
            self.counts[c.id] += len(times)
        self.min_timestamp = min(int(times.min()), self.min_timestamp)
        self.max_timestamp = max(int(times.max()), self.max_timestamp)


@dataclass
class _Segment:
    """One finished MCAP file of the bag."""

    name: str
    start_ns: int
    end_ns: int
    count: int
    topics: list[dict[str, Any]]      # topics_with_message_count entries of that file


@dataclass
class _Open:
    writer: Any
    name: str
    connections: dict[str, Any] = field(default_factory=dict)
    first_ns: int | None = None


#: the ROS 2 distribution the bags are written for (metadata ``ros_distro``)
ROS_DISTRO = 'jazzy'


def offered_qos(reliable: bool, depth: int) -> Qos:
    """Return the offered QoS profile of a keep-last, volatile publisher, as rosbag2 stores it."""
    zero = QosTime(0, 0)
    return Qos(QosHistory.KEEP_LAST, depth,
               QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.VOLATILE, zero, zero, QosLiveliness.AUTOMATIC, zero, False)


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
        self._segments: list[_Segment] = []
        self._custom: dict[str, str] = {}
        self._open: _Open | None = None
        self._block: RecordBlock | None = None
        self._closed = False
        if atomic:
            parent = self.path.parent if str(self.path.parent) else Path('.')
            _remove_stale_partials(parent, self.path.name)
            self._dir = parent / f'.{self.path.name}.partial-{os.getpid()}'
            if self._dir.exists():
                shutil.rmtree(self._dir)
        else:
            self._dir = self.path
        try:
            self._dir.mkdir(parents=True)
            self._staging = self._dir / '.staging'
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
        """Return the messages in finished MCAP files: what the bag holds if it stops now."""
        with self._lock:
            return sum(s.count for s in self._segments)

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
            self._custom.update(items)
            self._write_metadata()

    def flush(self) -> None:
        """Finish the current MCAP file now (readable at once); later messages start a new one."""
        with self._lock:
            self._check_open()
            self._write_rows()
            if self._open is not None:
                self._finish_segment()

    def close(self) -> None:
        """Finish the bag (idempotent). With ``atomic``, the bag appears at ``path`` now."""
        with self._lock:
            if self._closed:
                return
            try:
                self._write_rows()
                if self._open is not None or not self._segments:
                    if self._open is None:
                        self._start_segment()      # an empty bag still records its topics
                    self._finish_segment()
                shutil.rmtree(self._staging, ignore_errors=True)
                self._move_into_place()
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
    def saved_until_ns(self) -> int:
        """Return the bag time [ns] of the last message in finished MCAP files (0: none)."""
        with self._lock:
            return max((s.end_ns for s in self._segments if s.count), default=0)

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
                    self._custom['incomplete'] = note
                self._write_metadata()
                self._move_into_place()
            except BaseException:
                self.abort()
                raise
            self._closed = True

    def abort(self) -> None:
        """Stop without finishing the current file. With ``atomic``, remove everything."""
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
        name = f'{self._stem}_{len(self._segments)}'
        self._staging.mkdir(exist_ok=True)
        seg_dir = self._staging / name
        if seg_dir.exists():
            shutil.rmtree(seg_dir)
        writer = _Writer(seg_dir, version=9, storage_plugin=StoragePlugin.MCAP)
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
        meta = YAML(typ='safe').load((seg_dir / 'metadata.yaml').read_text())
        info = meta['rosbag2_bagfile_information']
        src = seg_dir / f'{seg.name}.mcap'
        os.replace(src, self._dir / f'{seg.name}.mcap')
        shutil.rmtree(seg_dir, ignore_errors=True)
        count = int(info['message_count'])
        start = int(info['starting_time']['nanoseconds_since_epoch']) if count else 0
        self._segments.append(_Segment(
            seg.name, start, start + int(info['duration']['nanoseconds']) if count else 0,
            count, list(info['topics_with_message_count'])))
        self._write_metadata()

    def _write_metadata(self) -> None:
        """Write ``metadata.yaml`` for the finished files (atomically)."""
        segs = self._segments
        nonempty = [s for s in segs if s.count]
        start = min((s.start_ns for s in nonempty), default=0)
        end = max((s.end_ns for s in nonempty), default=0)
        count = sum(s.count for s in segs)
        topics: dict[tuple[str, str], dict[str, Any]] = {}
        for s in segs:
            for entry in s.topics:
                tm = entry['topic_metadata']
                key = (tm['name'], tm['type'])
                if key in topics:
                    topics[key]['message_count'] += int(entry['message_count'])
                else:
                    topics[key] = {'topic_metadata': dict(tm),
                                   'message_count': int(entry['message_count'])}
        info = {
            'version': 9,
            'storage_identifier': 'mcap',
            'relative_file_paths': [f'{s.name}.mcap' for s in segs],
            'duration': {'nanoseconds': end - start},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': list(topics.values()),
            'compression_format': '',
            'compression_mode': '',
            'files': [{'path': f'{s.name}.mcap',
                       'starting_time': {'nanoseconds_since_epoch': s.start_ns},
                       'duration': {'nanoseconds': s.end_ns - s.start_ns},
                       'message_count': s.count} for s in segs],
            'custom_data': dict(self._custom) or None,
            'ros_distro': ROS_DISTRO,
        }
        yaml = YAML(typ='safe')
        yaml.default_flow_style = False
        text = StringIO()
        yaml.dump({'rosbag2_bagfile_information': info}, text)
        tmp = self._dir / 'metadata.yaml.tmp'
        tmp.write_text(text.getvalue(), encoding='utf-8')
        os.replace(tmp, self._dir / 'metadata.yaml')


# -- reading ----------------------------------------------------------------------------------

@dataclass(frozen=True)
class BagInfo:
    """What a bag holds: topic (without leading '/') -> (msgtype, message count)."""

    path: Path
    topics: dict[str, tuple[str, int]]
    start_ns: int          # time of the earliest message [ns] (0 for an empty bag)
    end_ns: int            # time of the latest message [ns]
    message_count: int
    custom_data: dict[str, str] = field(default_factory=dict)   # metadata.yaml custom_data

    @property
    def duration(self) -> float:
        """Bag duration [s]."""
        return (self.end_ns - self.start_ns) * 1e-9


def _open_reader(path: str | os.PathLike):
    p = Path(path)
    if not p.exists():
        raise BagError(f'bag not found: {p}')
    if p.is_dir() and not (p / 'metadata.yaml').exists():
        # A bare storage file inside a directory without metadata (e.g. copied from elsewhere).
        files = sorted(list(p.glob('*.mcap')) + list(p.glob('*.db3')))
        if len(files) == 1:
            p = files[0]
        else:
            raise BagError(f'not a rosbag2 bag (no metadata.yaml): {p}')
    from rosbags.highlevel import AnyReader         # here: a writer's start-up skips it

    try:
        reader = AnyReader([p], default_typestore=typestore())
        reader.open()
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags raises many kinds; all mean unreadable
        raise BagError(f'cannot read bag {path}: {_one_line(exc)}') from None
    return reader


def _custom_data(path: Path) -> dict[str, str]:
    meta = path / 'metadata.yaml'
    if not meta.is_file():
        return {}
    try:
        info = YAML(typ='safe').load(meta.read_text(encoding='utf-8'))
        custom = info['rosbag2_bagfile_information'].get('custom_data') or {}
        return {str(k): str(v) for k, v in custom.items()}
    except Exception:  # noqa: BLE001 - custom data is optional decoration
        return {}


def bag_info(path: str | os.PathLike) -> BagInfo:
    """Open a bag and describe it; raises :class:`BagError` (one line) if it is unreadable."""
    reader = _open_reader(path)
    try:
        topics: dict[str, tuple[str, int]] = {}
        for name, info in reader.topics.items():
            key = _norm_topic(name)
            old = topics.get(key)
            topics[key] = (info.msgtype or '', info.msgcount + (old[1] if old else 0))
        count = reader.message_count
        start = reader.start_time if count else 0
        end = reader.end_time - 1 if count else 0
        return BagInfo(Path(path), topics, start, end, count, _custom_data(Path(path)))
    except Exception as exc:  # noqa: BLE001
        raise BagError(f'cannot read bag {path}: {_one_line(exc)}') from None
    finally:
        reader.close()


def read_topics(path: str | os.PathLike, topics: Iterable[str] | None = None
                ) -> Iterator[tuple[str, int, Any]]:
    """
    Yield ``(topic, t_ns, msg)`` in bag-time order; ``msg`` deserialised with rosbags.

    ``topics``: names to read, with or without a leading '/' (None = all). Returned topic
    names have no leading '/'. Raises :class:`BagError` (one line) for a missing or corrupt
    bag, also when the corruption is found part-way.
    """
    wanted = None if topics is None else {_norm_topic(t) for t in topics}
    reader = _open_reader(path)
    try:
        conns = [c for c in reader.connections
                 if wanted is None or _norm_topic(c.topic) in wanted]
        if not conns:
            return
        for conn, t_ns, raw in reader.messages(connections=conns):
            try:
                msg = reader.deserialize(raw, conn.msgtype)
            except Exception as exc:  # noqa: BLE001
                raise BagError(f'cannot decode a {conn.msgtype} message on {conn.topic} in '
                               f'{path}: {_one_line(exc)}') from None
            yield _norm_topic(conn.topic), t_ns, msg
    except BagError:
        raise
    except Exception as exc:  # noqa: BLE001
        raise BagError(f'cannot read bag {path}: {_one_line(exc)}') from None
    finally:
        reader.close()
