"""
Throttled log messages, decided before the logger is called.

rclpy's ``throttle_duration_sec`` is decided inside the logger, after it has located its
caller: ``rclpy.impl.rcutils_logger._find_caller`` runs ``inspect.getframeinfo``, which reads
the calling file's source and ``realpath``s it, on every call. That is about 0.5 ms of
interpreter-lock time per suppressed message here (uncontended; more while the executor
thread competes for the lock). The pacing loop warns because the simulation is behind, and
those calls kept it behind: a 4-coach ECP node at ``real_time_factor`` 2, flooded in-process
with 8 000-19 000 commands a second, simulated 0.33 s in 8 s of wall time; with :class:`Throttle`,
which keeps such calls away from the logger until one is due, 1.25 s (the flood itself still
takes the machine's two cores).
"""
from __future__ import annotations

from typing import Any

WARN_PERIOD = 5.0        # [s wall] at most one repeated warning per key and period


class Throttle:
    """At most one message per key and period; counts what it suppressed."""

    def __init__(self, period: float = WARN_PERIOD) -> None:
        self.period = period
        self._last: dict[Any, float] = {}
        self._suppressed: dict[Any, int] = {}

    def __call__(self, key: Any, now: float) -> int | None:
        """Return None to stay quiet, else the number suppressed since the last message."""
        last = self._last.get(key)
        if last is not None and now - last < self.period:
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return None
        self._last[key] = now
        return self._suppressed.pop(key, 0)
