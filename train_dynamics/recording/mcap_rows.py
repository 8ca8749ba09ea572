"""
Pre-encoded rows of MCAP message records, written into the rosbags MCAP writer in one copy.

The offline command's outputs have a fixed shape (the same topics at every sample, each
message of a fixed size), so they are not written one message at a time: a
:class:`RecordBlock` holds the MCAP message records of up to about 1 MiB of samples, encoded in
place (:class:`train_dynamics.recording.outputs.OutputRows`), and
:meth:`train_dynamics.recording.bags.BagRecorder.attach` writes its rows with one copy into the
rosbags writer's chunk (:class:`BlockMcap`, through :class:`BlockWriter`), before any other
message and whenever the block is full. The messages are those of the per-message path, byte
for byte and in the same order (test/recording/test_bag_blocks.py). Record layout: the MCAP
specification, https://mcap.dev/spec (Message op 0x05, Chunk op 0x06, Message Index op 0x07,
Chunk Index op 0x08).
"""
from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from io import BytesIO
import struct
from typing import Any

import numpy as np
from rosbags.interfaces import ConnectionExtRosbag2
from rosbags.rosbag2 import CompressionMode, StoragePlugin, Writer
from rosbags.rosbag2.metadata import dump_qos_v9
from rosbags.rosbag2.storage_mcap import McapWriter

from train_dynamics.recording.cdr import STAMP_OFFSET
import yaml

#: MCAP message record (opcode 0x05): opcode u8, record length u64, channel id u16,
#: sequence u32, log time u64, publish time u64, then the message's CDR bytes (MCAP spec,
#: https://mcap.dev/spec#message-op0x05); the offsets of the fields in it
_REC_CHANNEL, _REC_LOG, _REC_PUBLISH, _REC_DATA = 9, 15, 23, 31
#: [bytes] a chunk of the rosbags MCAP writer is closed once it holds more than this
CHUNK_BYTES = 2 ** 20


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
            capacity = max(1, min(4096, CHUNK_BYTES // self.row_bytes))
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


class BlockMcap(McapWriter):
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

        A chunk is closed after the row that takes it past :data:`CHUNK_BYTES`, as rosbags
        closes it after such a message: chunks stay about 1 MiB (a reader holds one chunk's
        messages at a time).
        """
        size = rows.shape[1]
        start = 0
        while start < len(times):
            room = CHUNK_BYTES - self.chunk.bio.tell()
            end = min(len(times), start + max(0, room) // size + 1)
            self._append(ids, offsets, times[start:end], rows[start:end])
            if self.chunk.bio.tell() > CHUNK_BYTES:
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


class BlockWriter(Writer):
    """The rosbags rosbag2 writer with :class:`BlockMcap` storage and :meth:`write_rows`."""

    STORAGE_PLUGINS = {**Writer.STORAGE_PLUGINS, StoragePlugin.MCAP: BlockMcap}

    def write_rows(self, connections: list[Any], offsets: tuple[int, ...], times: np.ndarray,
                   rows: np.ndarray) -> None:
        """Write rows of records on ``connections`` (counted as rosbags' ``write`` counts)."""
        self.storage.write_rows([c.id for c in connections], offsets, times, rows)
        for c in connections:
            self.counts[c.id] += len(times)
        self.min_timestamp = min(int(times.min()), self.min_timestamp)
        self.max_timestamp = max(int(times.max()), self.max_timestamp)

    def close(self) -> None:
        """
        Close the file and write its ``metadata.yaml``: rosbags' ``Writer.close``, faster.

        rosbags 0.11.9's ``close`` for this writer's case (format version 9, MCAP, no
        compression) with the metadata (``metadata.yaml`` and the MCAP metadata record
        ``rosbag2``) emitted by libyaml instead of ruamel.yaml: the same data, keys sorted
        alike (libyaml keeps a long value on its key's line where ruamel.yaml folds it;
        test/recording/test_recorder_hostile_inputs.py compares the two), in a few milliseconds
        instead of about 0.05 s: most of a flush when a file is finished every 0.1 s.
        """
        assert self.storage
        if (self.version, self.storage_plugin, self.compression_mode) != (
                9, StoragePlugin.MCAP, CompressionMode.NONE):
            super().close()
            return
        duration = max(0, self.max_timestamp - self.min_timestamp)
        start = self.min_timestamp
        count = sum(self.counts.values())
        name = self.storage.path.name
        info = {
            'version': self.version,
            'storage_identifier': 'mcap',
            'relative_file_paths': [name],
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {'topic_metadata': {
                    'name': x.topic, 'type': x.msgtype,
                    'serialization_format': x.ext.serialization_format,
                    'offered_qos_profiles': dump_qos_v9(x.ext.offered_qos_profiles),
                    'type_description_hash': x.digest},
                 'message_count': self.counts[x.id]}
                for x in self.connections if isinstance(x.ext, ConnectionExtRosbag2)],
            'compression_format': '',
            'compression_mode': '',
            'files': [{'path': name, 'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration}, 'message_count': count}],
            'custom_data': self.custom_data or None,
            'ros_distro': 'rosbags',
        }
        text = _yaml({'rosbag2_bagfile_information': info})
        self.storage.close(self.version, _yaml(info).strip())
        self.storage = None
        tmp = self.metapath.with_suffix('.yaml.tmp')
        tmp.write_text(text, 'utf8')
        tmp.replace(self.metapath)


#: libyaml's emitter when PyYAML was built with it (else PyYAML's own)
_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)


def _yaml(value: Any) -> str:
    """Return ``value`` as block YAML, keys sorted: ruamel.yaml's safe dump, as rosbags uses it."""
    return yaml.dump(value, Dumper=_DUMPER, default_flow_style=False)
