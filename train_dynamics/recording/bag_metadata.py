"""
The ``metadata.yaml`` of a rosbag2 directory written in MCAP files (rosbag2 format version 9).

A bag of :class:`train_dynamics.recording.bags.BagRecorder` is a list of finished MCAP files
(:class:`Segment`, one per file, read back from the ``metadata.yaml`` the ``rosbags`` writer
writes for it: :func:`finished_segment`); :func:`write_metadata` lists them in the bag's own
``metadata.yaml``, written atomically (rosbag2's file layout: ``relative_file_paths``,
``files``, ``topics_with_message_count`` summed over the files; the format of rosbag2's
``metadata.yaml``, version 9, as rosbag2 Jazzy writes it). The offered QoS of a topic is stored
as rosbag2 stores it (:func:`offered_qos`).
"""
from __future__ import annotations

from dataclasses import dataclass
from io import StringIO
import os
from pathlib import Path
from typing import Any

from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
from ruamel.yaml import YAML

#: the ROS 2 distribution the bags are written for (metadata ``ros_distro``)
ROS_DISTRO = 'jazzy'


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
    meta = YAML(typ='safe').load((seg_dir / 'metadata.yaml').read_text())
    info = meta['rosbag2_bagfile_information']
    count = int(info['message_count'])
    start = int(info['starting_time']['nanoseconds_since_epoch']) if count else 0
    return Segment(name, start, start + int(info['duration']['nanoseconds']) if count else 0,
                   count, list(info['topics_with_message_count']))


def write_metadata(bag_dir: Path, segs: list[Segment], custom: dict[str, str]) -> None:
    """Write ``metadata.yaml`` of ``bag_dir`` listing the finished files ``segs`` (atomically)."""
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
        'custom_data': dict(custom) or None,
        'ros_distro': ROS_DISTRO,
    }
    yaml = YAML(typ='safe')
    yaml.default_flow_style = False
    text = StringIO()
    yaml.dump({'rosbag2_bagfile_information': info}, text)
    tmp = bag_dir / 'metadata.yaml.tmp'
    tmp.write_text(text.getvalue(), encoding='utf-8')
    os.replace(tmp, bag_dir / 'metadata.yaml')
