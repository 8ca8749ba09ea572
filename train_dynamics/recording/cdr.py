"""
Direct CDR encoding of the messages the simulator writes most (no ``rosbags`` needed).

:func:`encode_joint_state`, :class:`JointStateEncoder` (names encoded once) and
:func:`encode_fluid_pressure` build the little-endian CDR bytes of ``sensor_msgs/JointState``
and ``sensor_msgs/FluidPressure`` by hand: the very bytes ``rosbags`` serialisation gives
(zero padding; test/recording/test_bagio.py compares them), about ten times faster. The
output encoding of :mod:`train_dynamics.recording.outputs` and the offline command's bag use
them.
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


def _cdr_doubles(out: bytearray, values) -> int:
    """Append a float64 sequence; return the offset of its first value (of its count if empty)."""
    arr = np.ascontiguousarray(values if values is not None else (), dtype='<f8').reshape(-1)
    _cdr_align(out, 4)
    out += struct.pack('<I', arr.shape[0])
    if arr.shape[0]:
        _cdr_align(out, 8)
    at = len(out)
    out += arr.tobytes()
    return at


def _joint_state(t_ns: int, names: Sequence[str], arrays, frame_id: str
                 ) -> tuple[bytearray, list[int]]:
    """Return the CDR bytes of a JointState and the offsets of its three float64 arrays."""
    out = bytearray(_ENCAPSULATION)
    _cdr_header(out, t_ns, frame_id)
    _cdr_align(out, 4)
    out += struct.pack('<I', len(names))
    for name in names:
        _cdr_string(out, name)
    return out, [_cdr_doubles(out, values) for values in arrays]


def encode_joint_state(t_ns: int, names: Sequence[str], position=None, velocity=None,
                       effort=None, frame_id: str = '') -> bytes:
    """
    Return the CDR bytes of a ``sensor_msgs/msg/JointState`` stamped ``t_ns`` [ns].

    ``position``, ``velocity``, ``effort``: float64 arrays, ``None`` = empty.
    """
    return bytes(_joint_state(t_ns, names, (position, velocity, effort), frame_id)[0])


#: byte offset of the header stamp (int32 sec, uint32 nanosec) in every stamped message
STAMP_OFFSET = 4


class Layout:
    """
    The fixed byte layout of a message whose sequences have fixed lengths.

    ``template``: the CDR bytes stamped 0 with every value 0; ``fields``: the byte offset of
    each float64 field (of the first value of an array), in the message's order; ``lengths``:
    the number of values of each (1 for a scalar). Writing a stamp at :data:`STAMP_OFFSET`
    and the values at their offsets gives the bytes of the encoders above, byte for byte.
    """

    __slots__ = ('template', 'fields', 'lengths')

    def __init__(self, template: bytes, fields: Sequence[int], lengths: Sequence[int]) -> None:
        self.template, self.fields, self.lengths = bytes(template), tuple(fields), tuple(lengths)


def joint_state_layout(names: Sequence[str], lengths: Sequence[int],
                       frame_id: str = '') -> Layout:
    """Return the :class:`Layout` of a JointState of ``names`` with arrays of ``lengths``."""
    out, fields = _joint_state(0, names, [np.zeros(n) for n in lengths], frame_id)
    return Layout(out, fields, lengths)


def fluid_pressure_layout(frame_id: str = '') -> Layout:
    """Return the :class:`Layout` of a FluidPressure: fields fluid_pressure, variance."""
    data = encode_fluid_pressure(0, 0.0, 0.0, frame_id)
    return Layout(data, (len(data) - 16, len(data) - 8), (1, 1))


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
