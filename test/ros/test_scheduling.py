"""
The simulation thread's scheduling (``realtime_priority``): the policy, not the timing.

:meth:`train_dynamics.ros.pacing.Pacer._schedule` asks for SCHED_FIFO at ``realtime_priority``
while the thread keeps up and for normal scheduling while it integrates without pausing; the
executor thread named by ``main`` follows one priority below; a refused priority is logged
once and not asked for again. The system call is replaced here by a recorder (these tests
never change a real thread's priority); no timing is asserted.
"""
from __future__ import annotations

import sys

import pytest

from train_dynamics.ros import pacing


class _Log:

    def __init__(self):
        self.lines = []

    def info(self, text, **kwargs):
        self.lines.append(text)


@pytest.fixture
def calls(monkeypatch):
    made = []

    def set_priority(tid, priority):
        made.append((tid, priority))

    monkeypatch.setattr(pacing, 'set_priority', set_priority)
    monkeypatch.setattr(pacing, 'normal_priority', lambda: made.append(('normal',)))
    return made


def _pacer(priority, executor_tid=0):
    pacer = pacing.Pacer(pacing.SimulationLock(), _Log(), None, None, None)
    pacer.set_realtime_priority(priority)
    pacer.executor_tid = executor_tid
    return pacer


def test_fifo_while_keeping_up_normal_while_busy(calls):
    pacer = _pacer(20, executor_tid=4321)
    pacer._schedule(busy=False)
    assert calls == [(0, 20), (4321, 19)]          # the executor one below
    assert pacer.scheduling == 'SCHED_FIFO 20'
    pacer._schedule(busy=False)
    assert len(calls) == 2                         # unchanged: no system call
    pacer._schedule(busy=True)                     # catching up: normal, both threads
    assert calls[2:] == [(0, 0), (4321, 0)]
    assert pacer.scheduling == 'normal'
    pacer._schedule(busy=False)
    assert calls[4:] == [(0, 20), (4321, 19)]


def test_executor_named_later_gets_its_priority(calls):
    pacer = _pacer(20)
    pacer._schedule(busy=False)
    assert calls == [(0, 20)]
    pacer.executor_tid = 99                        # main names it after the first iteration
    pacer._schedule(busy=False)
    assert calls[1:] == [(0, 20), (99, 19)]


def test_priority_1_executor_stays_real_time(calls):
    pacer = _pacer(1, executor_tid=7)
    pacer._schedule(busy=False)
    assert calls == [(0, 1), (7, 1)]               # SCHED_FIFO has no priority 0


def test_zero_is_normal_scheduling(calls):
    pacer = _pacer(0, executor_tid=7)
    pacer._schedule(busy=False)
    assert calls == [(0, 0), (7, 0)]
    assert pacer.scheduling == 'normal'


def test_refused_priority_logged_once_and_not_asked_again(monkeypatch):
    asked = []

    def refuse(tid, priority):
        asked.append((tid, priority))
        if priority:
            raise PermissionError(1, 'Operation not permitted')

    monkeypatch.setattr(pacing, 'set_priority', refuse)
    monkeypatch.setattr(pacing, 'normal_priority', lambda: None)
    pacer = _pacer(20)
    for _ in range(5):
        pacer._schedule(busy=False)
    assert asked == [(0, 20)]
    assert pacer.scheduling == 'normal'
    assert len(pacer._log.lines) == 1 and 'not granted' in pacer._log.lines[0]
    pacer.set_realtime_priority(30)                # another value is asked for once
    pacer._schedule(busy=False)
    pacer._schedule(busy=False)
    assert asked[1:] == [(0, 30)]
    assert len(pacer._log.lines) == 2


def test_cpu_wake_latency_request(monkeypatch, tmp_path):
    from train_dynamics.ros import scheduling

    target = tmp_path / 'cpu_dma_latency'
    target.write_bytes(b'')
    monkeypatch.setattr(scheduling, 'CPU_DMA_LATENCY', str(target))
    req = scheduling.CpuWakeLatency(25)
    assert req.held and req.status == '25 us'
    assert len(target.read_bytes()) == 4           # one 32-bit integer [us]
    assert int.from_bytes(target.read_bytes(), sys.byteorder, signed=True) == 25
    req.release()
    req.release()                                  # idempotent
    assert not req.held and req.status == 'none'
    assert scheduling.CpuWakeLatency(-1).status == 'none'      # no request
    monkeypatch.setattr(scheduling, 'CPU_DMA_LATENCY', str(tmp_path / 'missing' / 'x'))
    refused = scheduling.CpuWakeLatency(0)
    assert not refused.held and refused.status.startswith('not granted')


def test_startup_heap_frozen_out_of_full_collections():
    """
    freeze_startup_heap: the objects alive at the call are skipped by every later collection.

    A cycle made before the call survives a full collection (frozen); one made after it is
    collected. (In sim_node's process this keeps the imports' and kernels' objects out of
    the full collections that held the simulation thread 70-108 ms.)
    """
    import gc
    import weakref
    from train_dynamics.ros.scheduling import freeze_startup_heap

    class Node:
        pass

    def cycle():
        a, b = Node(), Node()
        a.other, b.other = b, a
        return weakref.ref(a)

    gc.disable()                         # no automatic collection between the steps
    before = cycle()
    frozen = gc.get_freeze_count()
    freeze_startup_heap()
    try:
        assert gc.get_freeze_count() > frozen
        after = cycle()
        gc.collect()
        assert before() is not None      # frozen: not traversed, not collected
        assert after() is None           # made after the freeze: collected as usual
    finally:
        gc.unfreeze()                    # the rest of the test session collects normally
        gc.enable()
        gc.collect()
    assert before() is None


def test_machine_wide_wake_latency_request_is_opt_in(monkeypatch):
    """The default asks nothing of the kernel: /dev/cpu_dma_latency acts on every CPU."""
    from train_dynamics.ros.node_parameters import SIM_NODE_PARAMETERS
    from train_dynamics.ros import scheduling

    opened = []

    def record_open(path, *args, **kwargs):
        opened.append(path)
        raise PermissionError(13, 'Permission denied')

    monkeypatch.setattr(scheduling.os, 'open', record_open)
    default = SIM_NODE_PARAMETERS['cpu_wake_latency'].default
    req = scheduling.CpuWakeLatency(default)
    assert opened == [] and not req.held and req.status == 'none'
    scheduling.CpuWakeLatency(0)               # asked for explicitly: the request is made
    assert opened == [scheduling.CPU_DMA_LATENCY]
