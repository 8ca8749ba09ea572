"""
Direct CDR encoding of the messages the simulator writes most (no ``rosbags`` needed).

:func:`encode_joint_state`, :class:`JointStateEncoder` (names encoded once) and
:func:`encode_fluid_pressure` build the little-endian CDR bytes of ``sensor_msgs/JointState``
and ``sensor_msgs/FluidPressure`` by hand: the very bytes ``rosbags`` serialisation gives
(zero padding; test/test_bagio.py compares them), about ten times faster. The output encoding
of :mod:`train_dynamics.recording.outputs` and the offline command's bag use them.
"""
from __future__ import annotations

from collections.abc import Sequence
import struct

import numpy as np

#: CDR encapsulation header: little-endian plain CDR
_ENCAPSULATION = b'\x00\x01\x00\x00'


def _cdr_align(out: bytearray, n: int) -> None:
    pad = (-(len(out) - 4)) % n          # alignment counts from the end of the 4-byte header
    if pad:
        out += bytes(pad)


def _cdr_string(out: bytearray, text: str) -> None:
    data = text.encode('utf-8')
    _cdr_align(out, 4)
    out += struct.pack('<I', len(data) + 1)
    out += data
    out += b'\x00'


def _cdr_header(out: bytearray, t_ns: int, frame_id: str) -> None:
    sec, nanosec = divmod(int(t_ns), 1_000_000_000)
    _cdr_align(out, 4)
    out += struct.pack('<iI', sec, nanosec)
    _cdr_string(out, frame_id)


def _cdr_doubles(out: bytearray, values) -> None:
    arr = np.ascontiguousarray(values if values is not None else (), dtype='<f8').reshape(-1)
    _cdr_align(out, 4)
    out += struct.pack('<I', arr.shape[0])
    if arr.shape[0]:
        _cdr_align(out, 8)
        out += arr.tobytes()


def encode_joint_state(t_ns: int, names: Sequence[str], position=None, velocity=None,
                       effort=None, frame_id: str = '') -> bytes:
    """
    Return the CDR bytes of a ``sensor_msgs/msg/JointState`` stamped ``t_ns`` [ns].

    ``position``, ``velocity``, ``effort``: float64 arrays, ``None`` = empty.
    """
    out = bytearray(_ENCAPSULATION)
    _cdr_header(out, t_ns, frame_id)
    _cdr_align(out, 4)
    out += struct.pack('<I', len(names))
    for name in names:
        _cdr_string(out, name)
    for values in (position, velocity, effort):
        _cdr_doubles(out, values)
    return bytes(out)


class JointStateEncoder:
    """
    Encode JointState messages with fixed ``names`` (the same bytes as rosbags).

    ``enc(t_ns, position, velocity, effort)`` -> bytes; arrays of float64 (None = empty).
    """

    def __init__(self, names: Sequence[str], frame_id: str = '') -> None:
        head = bytearray(_ENCAPSULATION)
        _cdr_header(head, 0, frame_id)
        self._stamp_at = 4                          # sec, nanosec follow the encapsulation
        _cdr_align(head, 4)
        head += struct.pack('<I', len(names))
        for name in names:
            _cdr_string(head, name)
        self._head = bytes(head)
        self._frame_id = frame_id

    def __call__(self, t_ns: int, position=None, velocity=None, effort=None) -> bytes:
        """Return the CDR bytes of one message stamped ``t_ns`` [ns]."""
        sec, nanosec = divmod(int(t_ns), 1_000_000_000)
        out = bytearray(self._head)
        struct.pack_into('<iI', out, 4, sec, nanosec)
        for values in (position, velocity, effort):
            if values is None:
                n = 0
            else:
                data = np.asarray(values, dtype='<f8').tobytes()
                n = len(data) >> 3
            pad = (-(len(out) - 4)) % 4
            if pad:
                out += bytes(pad)
            out += struct.pack('<I', n)
            if n:
                pad = (-(len(out) - 4)) % 8
                if pad:
                    out += bytes(pad)
                out += data
        return bytes(out)


def encode_fluid_pressure(t_ns: int, pressure: float, variance: float = 0.0,
                          frame_id: str = '') -> bytes:
    """Return the CDR bytes of a ``sensor_msgs/msg/FluidPressure`` (ABSOLUTE [Pa])."""
    out = bytearray(_ENCAPSULATION)
    _cdr_header(out, t_ns, frame_id)
    _cdr_align(out, 8)
    out += struct.pack('<dd', float(pressure), float(variance))
    return bytes(out)


def encode_float64(value: float) -> bytes:
    """Return the CDR bytes of a ``std_msgs/msg/Float64`` (e.g. a traction command)."""
    return _ENCAPSULATION + struct.pack('<d', float(value))
