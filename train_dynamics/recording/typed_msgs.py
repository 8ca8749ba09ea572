"""
The typed messages of ``train_dynamics_msgs`` without rclpy: their definitions and byte layout.

The ``.msg`` files of the interface package (``msgs/train_dynamics_msgs/msg/`` in the
repository; ``share/train_dynamics_msgs/msg/`` once colcon installed it) are the one
definition of the typed messages. Here they are found (:func:`definition_folder`), parsed by
``rosbags`` and registered in the typestore of :mod:`train_dynamics.recording.messages`
(:func:`register`), so that the offline command writes, and every reader reads, bags with the
typed topics as it does the standard ones; the node's rclpy classes come from the package
built by ``tools/build_msgs.sh``.

The typed state messages are a ``std_msgs/Header`` and float64 arrays of one value per
vehicle (or coupler), or empty: :func:`stamped_arrays_layout` gives their
:class:`~train_dynamics.recording.cdr.Layout` (CDR: the encoding rosbags and rclpy give,
checked by test/recording/test_typed_msgs.py).
"""
from __future__ import annotations

import functools
import os
from pathlib import Path
import re
import sys
from typing import Sequence

import numpy as np

from train_dynamics import topics
from train_dynamics.recording.cdr import _cdr_doubles, _cdr_header, _ENCAPSULATION, Layout

#: the interface package's folder in a source checkout (this file: train_dynamics/recording/)
SOURCE_FOLDER = Path(__file__).resolve().parents[2] / 'msgs' / topics.MSGS_PACKAGE / 'msg'
#: a float64 array field of a .msg: ``float64[] name``
_ARRAY_FIELD = re.compile(r'^\s*float64\[\]\s+(\w+)', re.M)


def _prefixes() -> list[Path]:
    """Return the install prefixes to look in: ``AMENT_PREFIX_PATH``, then this Python's."""
    ament = [Path(p) for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    return ament + [Path(sys.prefix)]


@functools.cache
def definition_folder() -> Path | None:
    """
    Return the folder of the package's ``.msg`` files, None where there is none.

    The source checkout's first (the files under review are the ones used), then
    ``<prefix>/share/train_dynamics_msgs/msg`` of each install prefix.
    """
    for folder in [SOURCE_FOLDER] + [p / 'share' / topics.MSGS_PACKAGE / 'msg'
                                     for p in _prefixes()]:
        if folder.is_dir() and any(folder.glob('*.msg')):
            return folder
    return None


@functools.cache
def definitions() -> dict[str, str]:
    """Return message type (``train_dynamics_msgs/msg/Name``) -> its ``.msg`` text."""
    folder = definition_folder()
    if folder is None:
        return {}
    return {f'{topics.MSGS_PACKAGE}/msg/{path.stem}': path.read_text(encoding='utf-8')
            for path in sorted(folder.glob('*.msg'))}


def available() -> bool:
    """Return whether the typed messages' definitions were found (typed topics exist)."""
    return bool(definitions())


def array_fields(msgtype: str) -> tuple[str, ...]:
    """Return the names of the float64 array fields of ``msgtype``, in their order."""
    return tuple(_ARRAY_FIELD.findall(definitions().get(msgtype, '')))


def register(store) -> None:
    """Register every typed message in the rosbags typestore ``store`` (no-op without them)."""
    from rosbags.typesys import get_types_from_msg
    types: dict = {}
    for msgtype, text in definitions().items():
        types.update(get_types_from_msg(text, msgtype))
    if types:
        store.register(types)


def stamped_arrays_layout(names: Sequence[str], fields: Sequence[str]) -> Layout:
    """
    Return the layout of a typed state message: header, then one float64 array per field.

    Each array has ``len(names)`` values, or none where the field's meaning is '' (empty);
    header frame ``track`` (:data:`~train_dynamics.topics.TRACK_FRAME`), stamp 0.
    """
    out = bytearray(_ENCAPSULATION)
    _cdr_header(out, 0, topics.TRACK_FRAME)
    lengths = [len(names) if meaning else 0 for meaning in fields]
    at = [_cdr_doubles(out, np.zeros(n)) for n in lengths]
    return Layout(out, at, lengths)


def typed_bytes(t_ns: int, arrays: Sequence[Sequence[float] | None]) -> bytes:
    """Return the CDR bytes of a typed state message stamped ``t_ns`` [ns] (None: empty)."""
    out = bytearray(_ENCAPSULATION)
    _cdr_header(out, t_ns, topics.TRACK_FRAME)
    for values in arrays:
        _cdr_doubles(out, values)
    return bytes(out)


__all__ = ['array_fields', 'available', 'definition_folder', 'definitions', 'register',
           'stamped_arrays_layout', 'typed_bytes']
