"""
The ``metadata.yaml`` of a rosbag2 directory written in MCAP files (rosbag2 format version 9).

A bag of :class:`train_dynamics.recording.bags.BagRecorder` is a list of finished MCAP files
(:class:`Segment`, one per file, read back from the ``metadata.yaml`` the ``rosbags`` writer
writes for it: :func:`finished_segment`); :class:`BagMetadata` lists them in the bag's own
``metadata.yaml``, rewritten atomically after every finished file (rosbag2's file layout:
``relative_file_paths``, ``files``, ``topics_with_message_count`` summed over the files; the
keys and their order as rosbag2 Jazzy writes them, format version 9). The offered QoS of a
topic is stored as rosbag2 stores it (:func:`offered_qos`).

Cost. A recorder that finishes a file every 0.1 s (``record_flush_period``) writes thousands
of files in a run, and the file list is rewritten each time: the text of each file's entry is
made once, when the file is finished, with libyaml (PyYAML's C emitter), and joined; a rewrite
costs a join, not a YAML emission of the whole list (which grows with the run: ruamel.yaml
took 0.25 s for 200 files, more than a 0.1 s flush period).
"""
from __future__ import annotations

from dataclasses import dataclass
import os
from pathlib import Path
from typing import Any

from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
import yaml

#: the ROS 2 distribution the bags are written for (metadata ``ros_distro``)
ROS_DISTRO = 'jazzy'
#: libyaml's emitter and parser when PyYAML was built with it (else PyYAML's own)
_DUMPER = getattr(yaml, 'CSafeDumper', yaml.SafeDumper)
_LOADER = getattr(yaml, 'CSafeLoader', yaml.SafeLoader)


@dataclass
class Segment:
    """One finished MCAP file of the bag."""

    name: str
    start_ns: int
    end_ns: int
    count: int
    topics: list[dict[str, Any]]      # topics_with_message_count entries of that file


def offered_qos(reliable: bool, depth: int) -> Qos:
    """Return the offered QoS profile of a keep-last, volatile publisher, as rosbag2 stores it."""
    zero = QosTime(0, 0)
    return Qos(QosHistory.KEEP_LAST, depth,
               QosReliability.RELIABLE if reliable else QosReliability.BEST_EFFORT,
               QosDurability.VOLATILE, zero, zero, QosLiveliness.AUTOMATIC, zero, False)


def finished_segment(name: str, seg_dir: Path) -> Segment:
    """Return the file ``name`` as the ``metadata.yaml`` of its closed writer in ``seg_dir``."""
    meta = yaml.load((seg_dir / 'metadata.yaml').read_text(encoding='utf-8'), Loader=_LOADER)
    info = meta['rosbag2_bagfile_information']
    count = int(info['message_count'])
    start = int(info['starting_time']['nanoseconds_since_epoch']) if count else 0
    return Segment(name, start, start + int(info['duration']['nanoseconds']) if count else 0,
                   count, list(info['topics_with_message_count']))


def _dump(value: Any, indent: str = '  ') -> str:
    """Return ``value`` as block YAML, every line indented by ``indent``."""
    text = yaml.dump(value, Dumper=_DUMPER, default_flow_style=False, sort_keys=False,
                     allow_unicode=True)
    return ''.join(indent + line for line in text.splitlines(keepends=True))


class BagMetadata:
    """
    The finished files of a bag and its ``custom_data``, written as its ``metadata.yaml``.

    :meth:`add` a finished file, :meth:`write` the file (atomically: a temporary file renamed
    over the old one; a failed write leaves the old one and no temporary file).
    """

    def __init__(self, bag_dir: Path) -> None:
        self.bag_dir = bag_dir
        self.segments: list[Segment] = []
        self.custom: dict[str, str] = {}
        self._paths: list[str] = []                  # each file's relative_file_paths item
        self._files: list[str] = []                  # each file's files item
        #: (name, type) -> [the item's text without its count, message count]
        self._topics: dict[tuple[str, str], list[Any]] = {}

    @property
    def count(self) -> int:
        """Return the messages in the finished files."""
        return sum(s.count for s in list(self.segments))

    def add(self, seg: Segment) -> None:
        """Add a finished file (its entries' text is made here, once)."""
        self.segments.append(seg)
        self._paths.append(_dump([f'{seg.name}.mcap']))
        self._files.append(_dump([{
            'path': f'{seg.name}.mcap',
            'starting_time': {'nanoseconds_since_epoch': seg.start_ns},
            'duration': {'nanoseconds': seg.end_ns - seg.start_ns},
            'message_count': seg.count}]))
        for entry in seg.topics:
            tm = entry['topic_metadata']
            item = self._topics.get((tm['name'], tm['type']))
            if item is None:
                item = self._topics[(tm['name'], tm['type'])] = [
                    _dump([{'topic_metadata': dict(tm)}]), 0]
            item[1] += int(entry['message_count'])

    def drop_last(self) -> None:
        """Forget the file added last (its listing could not be written)."""
        seg = self.segments.pop()
        self._paths.pop()
        self._files.pop()
        for entry in seg.topics:
            tm = entry['topic_metadata']
            self._topics[(tm['name'], tm['type'])][1] -= int(entry['message_count'])

    def text(self) -> str:
        """Return the ``metadata.yaml`` text of the finished files."""
        nonempty = [s for s in self.segments if s.count]
        start = min((s.start_ns for s in nonempty), default=0)
        end = max((s.end_ns for s in nonempty), default=0)
        parts = ['rosbag2_bagfile_information:\n', _dump({
            'version': 9, 'storage_identifier': 'mcap',
            'duration': {'nanoseconds': end - start},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': self.count})]
        listed = [(text, n) for text, n in self._topics.values()]
        parts.append('  topics_with_message_count:' + ('\n' if listed else ' []\n'))
        parts.extend(f'{text}    message_count: {n}\n' for text, n in listed)
        parts.append(_dump({'compression_format': '', 'compression_mode': ''}))
        parts.append('  relative_file_paths:' + ('\n' if self._paths else ' []\n'))
        parts.extend(self._paths)
        parts.append('  files:' + ('\n' if self._files else ' []\n'))
        parts.extend(self._files)
        parts.append(_dump({'custom_data': dict(self.custom) or None, 'ros_distro': ROS_DISTRO}))
        return ''.join(parts)

    def write(self) -> None:
        """Write ``metadata.yaml`` (atomically); raises OSError, leaving the old file as it was."""
        tmp = self.bag_dir / 'metadata.yaml.tmp'
        try:
            tmp.write_text(self.text(), encoding='utf-8')
            os.replace(tmp, self.bag_dir / 'metadata.yaml')
        except BaseException:
            try:
                tmp.unlink()
            except OSError:
                pass
            raise
