"""
Real-time scheduling of ``sim_node``'s threads (POSIX ``SCHED_FIFO``, Linux ``sched(7)``).

Why and when: :mod:`train_dynamics.ros.pacing` (the simulation thread's ``realtime_priority``).
"""
from __future__ import annotations

import os


def set_priority(tid: int, priority: int) -> None:
    """
    Schedule thread ``tid`` (0: the calling one) at SCHED_FIFO ``priority``; 0: normally.

    Raises ``OSError`` where not permitted (no CAP_SYS_NICE, ``ulimit -r`` 0), and
    ``AttributeError`` where the platform has no ``os.sched_setscheduler``.
    """
    if priority:
        os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(priority))
    else:
        os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))


def normal_priority() -> None:
    """Schedule the calling thread normally (a thread inherits its starter's policy)."""
    try:
        set_priority(0, 0)
    except (AttributeError, OSError):   # not Linux
        pass
