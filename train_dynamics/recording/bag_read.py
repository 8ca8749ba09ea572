"""
Rosbag2 directories read with the ``rosbags`` library (no rosbag2 / ``ros2`` CLI).

:func:`read_topics` reads MCAP or sqlite3 rosbag2 directories (or a bare ``.mcap`` /
``.db3`` file) through ``rosbags.highlevel.AnyReader`` with the ROS 2 Jazzy typestore for bags
that do not embed their message definitions; :func:`bag_info` says what a bag holds. Topic
names are returned without a leading ``/`` so that bags from ``ros2 bag record``
(``/couplers``) and ours (``couplers``) read alike. Every failure is a :class:`BagError` of one
line.

Opening a bag costs: ``rosbags`` parses ``metadata.yaml`` and, in every MCAP file of the
bag, the offered QoS of every channel (YAML, 0.1-0.15 s for a 60 s recording of 13 vehicles
split in 7 files). A reader that asks a bag several things (the report: what it holds, the
outputs, the distance to go, the blending topics) opens it once inside
:func:`shared_reader`.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator
import contextlib
from dataclasses import dataclass, field
import os
from pathlib import Path
import threading
from typing import Any

from ruamel.yaml import YAML

from train_dynamics.recording.messages import typestore


class BagError(Exception):
    """A bag that cannot be read or written; the message is one line and says why."""


def one_line(exc: BaseException) -> str:
    text = ' '.join(str(a) for a in exc.args) if exc.args else type(exc).__name__
    return ' '.join(text.split()) or type(exc).__name__


def norm_topic(topic: str) -> str:
    return topic[1:] if topic.startswith('/') else topic


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


#: this thread's bags opened by :func:`shared_reader`: absolute path -> [reader, BagInfo]
_SHARED = threading.local()


@contextlib.contextmanager
def shared_reader(path: str | os.PathLike) -> Iterator[None]:
    """
    Within the block, :func:`bag_info` and :func:`read_topics` of ``path`` share one reader.

    The bag is opened at the first call (an unreadable bag raises there, as without this
    block), described once, and closed when the block ends. Same thread only; the reads must
    be one after another (a :func:`read_topics` generator run to its end or dropped before
    the next starts), as they are anyway.
    """
    shared = getattr(_SHARED, 'bags', None)
    if shared is None:
        shared = _SHARED.bags = {}
    key = os.path.abspath(path)
    if key in shared:                       # nested: the outer block owns it
        yield
        return
    shared[key] = [None, None]
    try:
        yield
    finally:
        reader = shared.pop(key)[0]
        if reader is not None:
            reader.close()


@contextlib.contextmanager
def _reader(path: str | os.PathLike) -> Iterator[Any]:
    """Yield an open reader of ``path``: the shared one, else one closed at the end."""
    entry = getattr(_SHARED, 'bags', {}).get(os.path.abspath(path))
    if entry is None:
        reader = _open_reader(path)
        try:
            yield reader
        finally:
            reader.close()
        return
    if entry[0] is None:
        entry[0] = _open_reader(path)
    yield entry[0]


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
        raise BagError(f'cannot read bag {path}: {one_line(exc)}') from None
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
    entry = getattr(_SHARED, 'bags', {}).get(os.path.abspath(path))
    if entry is not None and entry[1] is not None:
        return entry[1]
    with _reader(path) as reader:
        try:
            topics: dict[str, tuple[str, int]] = {}
            for name, info in reader.topics.items():
                key = norm_topic(name)
                old = topics.get(key)
                topics[key] = (info.msgtype or '', info.msgcount + (old[1] if old else 0))
            count = reader.message_count
            start = reader.start_time if count else 0
            end = reader.end_time - 1 if count else 0
            info = BagInfo(Path(path), topics, start, end, count, _custom_data(Path(path)))
        except Exception as exc:  # noqa: BLE001
            raise BagError(f'cannot read bag {path}: {one_line(exc)}') from None
    if entry is not None:
        entry[1] = info
    return info


def read_topics(path: str | os.PathLike, topics: Iterable[str] | None = None
                ) -> Iterator[tuple[str, int, Any]]:
    """
    Yield ``(topic, t_ns, msg)`` in bag-time order; ``msg`` deserialised with rosbags.

    ``topics``: names to read, with or without a leading '/' (None = all). Returned topic
    names have no leading '/'. Raises :class:`BagError` (one line) for a missing or corrupt
    bag, also when the corruption is found part-way.
    """
    wanted = None if topics is None else {norm_topic(t) for t in topics}
    with _reader(path) as reader:
        try:
            conns = [c for c in reader.connections
                     if wanted is None or norm_topic(c.topic) in wanted]
            if not conns:
                return
            for conn, t_ns, raw in reader.messages(connections=conns):
                try:
                    msg = reader.deserialize(raw, conn.msgtype)
                except Exception as exc:  # noqa: BLE001
                    raise BagError(f'cannot decode a {conn.msgtype} message on {conn.topic} '
                                   f'in {path}: {one_line(exc)}') from None
                yield norm_topic(conn.topic), t_ns, msg
        except BagError:
            raise
        except Exception as exc:  # noqa: BLE001
            raise BagError(f'cannot read bag {path}: {one_line(exc)}') from None
