"""
Real-time scheduling of ``sim_node``'s threads (POSIX ``SCHED_FIFO``, Linux ``sched(7)``).

Why and when: :mod:`train_dynamics.ros.pacing` (the simulation thread's ``realtime_priority``).
"""
from __future__ import annotations

import gc
import os
import sys


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


def freeze_startup_heap() -> None:
    """
    Keep the objects that exist after start-up out of every later garbage collection.

    Python's cyclic garbage collector traverses every tracked object in a full (generation 2)
    collection while it holds the interpreter lock (GIL). After the imports (numba, rclpy,
    numpy) and the kernels' loading there are over 100 000 such objects (136 000 after
    importing sim_node and building the paper's simulator, before the node itself): a full
    collection then took 42-70 ms and, triggered by the run's own allocations some 6 s into
    the paper's run, held the simulation thread 70-108 ms behind real time (3 coaches, 100 Hz,
    ``make run``). ``gc.freeze()`` (Python >= 3.7, the ``gc`` module's documentation) moves
    them to a permanent generation that collections skip; objects still freed by reference
    counting are unaffected, cyclic garbage among them is never collected (start-up's, once).
    """
    gc.freeze()


#: Linux PM QoS: the CPU wake-up latency [us] a process asks for while it holds this file open
CPU_DMA_LATENCY = '/dev/cpu_dma_latency'


class CpuWakeLatency:
    """
    Ask the kernel for CPU wake-up latencies of at most ``limit_us`` while held (PM QoS).

    Writing a 32-bit integer [us] to ``/dev/cpu_dma_latency`` and keeping the file open
    keeps idle CPUs in idle states that wake within it (Linux
    ``Documentation/power/pm_qos_interface.rst``; what ``cyclictest`` does by default). In a
    virtual machine with the ``haltpoll`` idle driver, 0 us makes an idle virtual CPU poll
    instead of halting: a halted one woke the simulation thread up to several ms late on a
    quiet 2-core VM. The cost: idle CPUs keep running (power; a VM's host cores) while held.
    ``limit_us`` < 0: no request. Not permitted (the file is root's by default) or not Linux:
    no request, :attr:`status` says why.
    """

    def __init__(self, limit_us: int) -> None:
        self._fd: int | None = None
        self.limit_us = int(limit_us)
        self.status = 'none'
        if self.limit_us < 0:
            return
        try:
            fd = os.open(CPU_DMA_LATENCY, os.O_WRONLY)
        except OSError as exc:
            self.status = f'not granted ({exc.strerror or exc})'
            return
        try:
            os.write(fd, self.limit_us.to_bytes(4, sys.byteorder, signed=True))
        except OSError as exc:
            os.close(fd)
            self.status = f'not granted ({exc.strerror or exc})'
            return
        self._fd = fd
        self.status = f'{self.limit_us} us'

    @property
    def held(self) -> bool:
        """Return True while the request is in force."""
        return self._fd is not None

    def release(self) -> None:
        """End the request (idempotent)."""
        fd, self._fd = self._fd, None
        if fd is not None:
            os.close(fd)
            self.status = 'none'
