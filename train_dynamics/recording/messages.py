"""
ROS 2 messages as ``rosbags`` objects: the Jazzy typestore, builders, (de)serialisation.

Builders of the message types the package reads and writes (:func:`joint_state`,
:func:`fluid_pressure`, :func:`clock`, :func:`diagnostic_array`, ...), stamps and CDR
(de)serialisation through the ``rosbags`` typestore of ROS 2 Jazzy. The hot output path uses
the hand-written encoders of :mod:`train_dynamics.recording.cdr` instead.
"""
from __future__ import annotations

from collections.abc import Iterable, Sequence
import functools
import math
from typing import Any

import numpy as np
from rosbags.typesys import get_typestore, Stores

from train_dynamics import topics
from train_dynamics.recording.typed_msgs import register


@functools.cache
def typestore():
    """
    Return the ``rosbags`` typestore of ROS 2 Jazzy (built once).

    With the typed messages of ``train_dynamics_msgs`` registered from their ``.msg`` files
    (:func:`train_dynamics.recording.typed_msgs.register`), where they are found.
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    register(store)
    return store


def time_to_ns(t: float) -> int:
    """Return time ``t`` [s] as integer nanoseconds (rounded to the nearest ns)."""
    if not math.isfinite(t):
        raise ValueError(f'time must be finite, got {t}')
    return int(round(float(t) * 1e9))


def stamp(t: float | int, *, ns: bool = False):
    """Return the ``builtin_interfaces/msg/Time`` of time ``t`` [s] (or [ns] if ``ns``)."""
    t_ns = int(t) if ns else time_to_ns(t)
    sec, nanosec = divmod(t_ns, 1_000_000_000)
    return typestore().types['builtin_interfaces/msg/Time'](sec=int(sec), nanosec=int(nanosec))


def stamp_to_sec(msg_stamp: Any) -> float:
    """Return a ``builtin_interfaces/msg/Time`` (rosbags or rclpy) in seconds."""
    return msg_stamp.sec + msg_stamp.nanosec * 1e-9


def header(t: float, frame_id: str = ''):
    """Return a ``std_msgs/msg/Header`` stamped with time ``t`` [s]."""
    return typestore().types['std_msgs/msg/Header'](stamp=stamp(t), frame_id=frame_id)


def _f64(values: Iterable[float] | None) -> np.ndarray:
    if values is None:
        return np.zeros(0, dtype=np.float64)
    return np.array(values, dtype=np.float64).reshape(-1)


def joint_state(t: float, names: Sequence[str], position: Iterable[float] | None = None,
                velocity: Iterable[float] | None = None, effort: Iterable[float] | None = None,
                frame_id: str = ''):
    """Return a ``sensor_msgs/msg/JointState`` at time ``t`` [s]; ``None`` arrays stay empty."""
    return typestore().types[topics.JOINT_STATE](
        header=header(t, frame_id), name=[str(n) for n in names],
        position=_f64(position), velocity=_f64(velocity), effort=_f64(effort))


def fluid_pressure(t: float, pressure: float, variance: float = 0.0, frame_id: str = ''):
    """Return a ``sensor_msgs/msg/FluidPressure`` at time ``t`` [s]; ``pressure`` ABSOLUTE [Pa]."""
    return typestore().types[topics.FLUID_PRESSURE](
        header=header(t, frame_id), fluid_pressure=float(pressure), variance=float(variance))


def clock(t: float):
    """Return a ``rosgraph_msgs/msg/Clock`` for time ``t`` [s]."""
    return typestore().types[topics.CLOCK_TYPE](clock=stamp(t))


def diagnostic_status(name: str, level: int = 0, message: str = '', hardware_id: str = '',
                      values: dict[str, Any] | Sequence[tuple[str, Any]] | None = None):
    """Return a ``diagnostic_msgs/msg/DiagnosticStatus``; level 0 OK, 1 WARN, 2 ERROR, 3 STALE."""
    types = typestore().types
    items = values.items() if isinstance(values, dict) else (values or [])
    kvs = [types['diagnostic_msgs/msg/KeyValue'](key=str(k), value=str(v)) for k, v in items]
    return types['diagnostic_msgs/msg/DiagnosticStatus'](
        level=int(level), name=name, message=message, hardware_id=hardware_id, values=kvs)


def diagnostic_array(t: float, statuses: Sequence[Any]):
    """Return a ``diagnostic_msgs/msg/DiagnosticArray`` at time ``t`` [s] holding ``statuses``."""
    return typestore().types[topics.DIAGNOSTIC_ARRAY](header=header(t), status=list(statuses))


def serialize(msg: Any) -> bytes:
    """Return the CDR bytes of a rosbags message object."""
    return bytes(typestore().serialize_cdr(msg, msg.__msgtype__))


def deserialize(data: bytes, msgtype: str) -> Any:
    """Return a rosbags message object from CDR bytes (Jazzy typestore)."""
    return typestore().deserialize_cdr(data, msgtype)
