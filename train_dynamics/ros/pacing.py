"""
The simulation thread of ``sim_node``: pacing against the wall clock, lag policy, chunking.

A dedicated thread advances the simulator in whole integration steps so that simulation
time = start + ``real_time_factor`` * (wall time since start); each step is computed when its
wall time arrives (at most every :data:`MIN_SLEEP` s) and outputs are published the moment
their wall time arrives. Behind schedule it catches up as fast as it can (warning after
:data:`BEHIND_WARN` s); more than :data:`MAX_LAG` s behind, it stops catching up: the pacing
restarts from the current state, the dropped wall time is counted (``lag_dropped_s``) and
logged, and the simulation then runs that much behind the wall clock. ``real_time_factor`` 0:
as fast as possible, in chunks of at most :data:`CHUNK_BUDGET` s so that subscriptions,
parameters and services stay responsive.

Numerical fault (``sim.fault``): integration stops, the last good state stays, an error log
line says why, ``reset`` recovers. With ``duration`` set the node then exits (status 3).

Scheduling: the work of an output period is far below the period (0.15 core for 150 vehicles
with the pneumatic brake at 100 Hz), so the output timing is set by how late the thread wakes
up, i.e. by the operating system's scheduler. At normal priority, on a machine whose cores are
busy with other processes (load 7-8 on 2 cores), the wake-ups were 9 ms late at the 99th
percentile and the outputs' p99 jitter 7.5 ms; at ``SCHED_FIFO`` the same wake-ups were 0.15 ms
late and the jitter 0.7 ms (garbage collection: 0.06 ms per collection, a few per second; the
/diagnostics callback: 0.2 ms under the lock). The thread therefore asks for ``SCHED_FIFO`` at
``realtime_priority`` (POSIX real-time scheduling; Linux ``sched(7)``) while it keeps up, and
drops back to normal scheduling while it integrates without pausing (catching up,
``real_time_factor`` 0), so that a simulation that cannot keep up never holds a core away from
the rest of the machine. The executor thread of ``sim_node``'s ``main`` (callbacks,
/diagnostics: a few ms of Python a second) follows one priority below: the simulation thread
needs the interpreter lock (GIL) that thread holds, and a normal-priority holder preempted by
other processes would delay it by their time slice (priority inversion through the GIL).
Threads these two start (the bag writer) return to normal scheduling. Where that priority is
not permitted (no ``CAP_SYS_NICE``, ``ulimit -r`` 0) the thread stays at normal priority and
says so once. On a quiet machine the remaining delay is an idle CPU's wake-up: the node's
``cpu_wake_latency`` (:class:`train_dynamics.ros.scheduling.CpuWakeLatency`). A full garbage
collection holds the GIL for as long as it traverses every object: ``main`` freezes start-up's
objects out of them (:func:`train_dynamics.ros.scheduling.freeze_startup_heap`).
"""
from __future__ import annotations

import contextlib
import math
import sys
import threading
import time
from typing import Any, Iterator

from train_dynamics.physics.train import TrainSimulator
from train_dynamics.ros.controller_inputs import ControllerInputs
from train_dynamics.ros.publishers import Outputs
from train_dynamics.ros.run_control import EXIT_LOCKSTEP_TIMEOUT, WAIT_POLL
from train_dynamics.ros.scheduling import normal_priority, set_priority
from train_dynamics.ros.throttle import Throttle
from train_dynamics.simulation.runner import end_step

MIN_SLEEP = 0.001        # [s wall] shortest pause between two pacing iterations
CHUNK_BUDGET = 0.005     # [s wall] longest stretch the simulation thread integrates in one go
BEHIND_WARN = 0.05       # [s wall] behind schedule by more: throttled warning
MAX_LAG = 1.0            # [s wall] behind schedule by more: stop catching up (drop the lag)
IDLE = 0.1               # [s wall] pause of a finished or faulted run
YIELD = 0.0002           # [s wall] pause that lets a waiting thread take the lock
#: [s] the interpreter's GIL switch interval in the node (Python's default 0.005): a
#: waiting thread gets the GIL within about this; 40 s runs of bench/node.py, p99 output
#: jitter 4.1 / 3.1 / 1.6 ms at the default, 2.4 / 1.6 / 1.7 ms at 0.5 ms (interleaved)
GIL_SWITCH_INTERVAL = 0.0005


class SimulationLock:
    """
    The simulation lock: guards the simulator and the run state of every part of the node.

    The simulation thread holds it for each pacing iteration (``with lock:``) and lets go in
    between, briefly when another thread is waiting for it (:attr:`waiting`). Other threads
    take it with :meth:`held`.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._waiting = 0     # threads in held() waiting for the lock

    def __enter__(self) -> SimulationLock:
        self._lock.acquire()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._lock.release()

    @property
    def waiting(self) -> bool:
        """Return True while another thread waits for the lock."""
        return self._waiting > 0

    @contextlib.contextmanager
    def held(self) -> Iterator[None]:
        """Hold the lock (threads other than the simulation thread, which yields to them)."""
        self._waiting += 1
        try:
            self._lock.acquire()
        finally:
            self._waiting -= 1
        try:
            yield
        finally:
            self._lock.release()


class Pacer:
    """
    Run the simulation thread: the run's simulator, paced, with its end and its faults.

    Lock discipline: every attribute is guarded by the :class:`SimulationLock`. The simulation
    thread holds it for each iteration; other threads change the pacing only through
    :meth:`start`, :meth:`set_real_time_factor`, :meth:`set_duration` and
    :meth:`measure_rtf`, holding it. ``sim``, ``finished`` and ``exit_code`` are also read
    without the lock by the spin loop and the node's read-only properties (single attribute
    reads; a stale value is at most one iteration old).
    """

    def __init__(self, lock: SimulationLock, logger: Any, context: Any, inputs: ControllerInputs,
                 outputs: Outputs) -> None:
        self.lock = lock
        self._log = logger
        self._context = context
        self._inputs = inputs
        self._outputs = outputs
        self._stop = threading.Event()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self.sim: TrainSimulator | None = None
        self.real_time_factor = 1.0
        self.duration = 0.0             # [s simulated], 0 = no end
        self.end_step: int | None = None
        self.finished = False
        self.exit_code = 0
        self.behind = 0.0               # [s wall] behind schedule at the last iteration
        self.lag_dropped = 0.0          # [s wall] dropped by the lag policy, in total
        self.lag_events = 0
        self.achieved_rtf = float('nan')
        self._rtf_window = (time.monotonic(), 0.0)
        self._h = 0.0
        self._step_cost = 1e-5          # [s wall per step], running estimate
        self._anchor_wall = 0.0         # wall time at which ...
        self._anchor_sim = 0.0          # ... the simulation was at this time
        self._need_anchor = True
        self._fault_reported = False
        self.fallback_periods = 0       # output periods over the integration_max_steps budget
        self._output_slack = 0.0        # [s wall] to the next output at the last iteration
        #: how far the run may go (pause, step, lock-step): set by the node before the thread
        #: starts (:class:`train_dynamics.ros.run_control.RunControl`)
        self.control: Any = None
        self._held_records: list[tuple[str, str, int, bytes]] = []   # :meth:`_record_input`
        self._held = False              # the control held the run at the last iteration
        self._throttle = Throttle()     # repeated warnings (simulation thread)
        #: SCHED_FIFO priority asked for while keeping up (0: normal scheduling)
        self.realtime_priority = 0
        self._priority_now = (0, 0)     # simulation thread only: (priority, executor_tid) set
        self._priority_denied = -1      # the priority last refused (not asked again)
        #: the executor thread, which follows this one's priority (0: none; set by ``main``:
        #: a node created inside another program leaves that program's threads alone)
        self.executor_tid = 0
        self.scheduling = 'normal'      # what the thread runs at (/diagnostics, log)
        self.cpu_wake_latency = 'none'  # the node's PM QoS request (/diagnostics)

    def wake(self) -> None:
        """Wake the simulation thread (an input arrived, the run control changed)."""
        self._wake.set()

    # -- control (other threads, lock held) -------------------------------------------------
    def start(self, sim: TrainSimulator, real_time_factor: float) -> None:
        """Pace a new run of ``sim`` from its t = 0."""
        self.sim = sim
        self._h = sim.h
        self._held_records = []         # (a reset: the last run's bag is closed)
        self.real_time_factor = float(real_time_factor)
        self.finished = False
        self.exit_code = 0
        self._fault_reported = False
        self.fallback_periods = 0
        self._update_end_step()
        self.behind = 0.0
        self._step_cost = 1e-5
        self._rtf_window = (time.monotonic(), 0.0)
        self._anchor(time.monotonic())
        self._need_anchor = True        # again after the first output (first publish is slow)
        self._wake.set()

    def set_real_time_factor(self, rtf: float) -> None:
        """Pace at ``rtf`` from now on."""
        self.real_time_factor = float(rtf)
        self._anchor(time.monotonic())
        self._wake.set()

    def set_duration(self, duration: float) -> None:
        """End the run at ``duration`` [s simulated] (0: never); may resume a finished one."""
        self.duration = float(duration)
        self._update_end_step()
        if self.finished and (self.end_step is None or self.end_step > self.sim.steps):
            self.finished = False
        self._wake.set()

    def measure_rtf(self, now: float) -> float:
        """Return the achieved real-time factor, measured over >= 0.2 s of wall time."""
        w0, s0 = self._rtf_window
        if now - w0 > 0.2:
            achieved = (self.sim.t - s0) / (now - w0)
            self.achieved_rtf = achieved if achieved >= 0 else float('nan')
            self._rtf_window = (now, self.sim.t)
        return self.achieved_rtf

    def _update_end_step(self) -> None:
        d = self.duration
        self.end_step = end_step(d, self._h) if d > 0 else None

    # -- the thread -------------------------------------------------------------------------
    def start_thread(self) -> None:
        """
        Start the simulation thread; shorten the interpreter's GIL switch interval.

        A thread that wakes up waits for the GIL until its holder (the executor: callbacks,
        /diagnostics) gives it up, by default after up to 5 ms: an output's worth of jitter.
        :data:`GIL_SWITCH_INTERVAL` bounds that wait (process-wide).
        """
        sys.setswitchinterval(GIL_SWITCH_INTERVAL)
        self._thread = threading.Thread(target=self._run, name='train_dynamics_sim',
                                        daemon=True)
        self._thread.start()

    def stop_thread(self, timeout: float = 10.0) -> None:
        """Stop the simulation thread (idempotent)."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout)

    def set_realtime_priority(self, priority: int) -> None:
        """Ask for SCHED_FIFO ``priority`` (0: normal) from the next iteration on."""
        self.realtime_priority = int(priority)
        self._wake.set()

    @contextlib.contextmanager
    def executor_at_normal_priority(self) -> Iterator[None]:
        """
        Run the block with the executor thread (the caller) at normal priority.

        For long work on that thread (a reset builds and warms up a new simulator, which may
        compile kernels): it must not hold a core at real-time priority meanwhile.
        """
        tid = self.executor_tid
        if not tid or tid != threading.get_native_id():
            yield
            return
        with self.lock.held():
            self.executor_tid = 0          # the simulation thread leaves it alone
            normal_priority()
        try:
            yield
        finally:
            with self.lock.held():
                self.executor_tid = tid    # set again at the next iteration

    def _schedule(self, busy: bool) -> None:
        """
        Set the simulation thread's scheduling (that thread, simulation lock held).

        ``busy``: the thread integrates without pausing; it then runs at normal priority.
        """
        want = 0 if busy else self.realtime_priority
        tid = self.executor_tid
        if (want, tid) == self._priority_now or (want and want == self._priority_denied):
            return
        self._priority_now = (want, tid)
        try:
            set_priority(0, want)
            if tid:      # one below: this thread preempts it, other processes do not
                set_priority(tid, max(want - 1, 1) if want else 0)
        except (AttributeError, OSError) as exc:   # not permitted, or not Linux
            normal_priority()
            if want:
                self._priority_denied = want
                self._log.info(
                    f'realtime_priority {want}: SCHED_FIFO not granted ({type(exc).__name__}: '
                    f'{exc}); the simulation thread runs at normal priority, its output timing '
                    "then depends on the machine's load (needs CAP_SYS_NICE or ulimit -r)")
            self.scheduling = 'normal'
            self._priority_now = (0, tid)
            return
        self.scheduling = f'SCHED_FIFO {want}' if want else 'normal'

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                with self.lock:
                    wake = self._iterate()
                    self._schedule(busy=wake is None)
            except Exception as exc:  # noqa: BLE001
                if self._stop.is_set() or not self._context.ok():
                    break            # shut down under our feet (SIGINT/SIGTERM)
                self._log.error(f'simulation thread: {type(exc).__name__}: {exc}')
                with self.lock:
                    self.finished = True
                    self.exit_code = 1
                wake = time.monotonic() + IDLE
            if wake is None:
                if self.lock.waiting:
                    time.sleep(YIELD)
                continue
            delay = wake - time.monotonic()
            if delay > 0:
                self._outputs.metrics.fold_if_idle(self._output_slack)   # its own lock
                delay = wake - time.monotonic()
            if delay > 0:
                self._wake.wait(delay)
                self._wake.clear()
            elif self.lock.waiting:
                time.sleep(YIELD)

    def _iterate(self) -> float | None:
        """Do one pacing iteration; return the wall time to wake up at (None: at once)."""
        sim = self.sim
        now = time.monotonic()
        self._output_slack = 0.0
        if self.finished or sim.fault is not None:
            self._inputs.discard_records()     # nothing acts any more: nothing to record
            return now + IDLE
        if self.control.stop_requested:
            self._finish(self.control.stop_reason, code=EXIT_LOCKSTEP_TIMEOUT)
            return now + IDLE
        self._inputs.apply(now, sim, self._record_input)
        if not self._outputs.published and self.control.hold_start(now):
            return now + WAIT_POLL / 2         # lock-step: t = 0 waits for the controller
        self._outputs.publish_due(sim)         # t = 0 (and right after a reset)
        if self._need_anchor:
            if self._inputs.hold_for_input(now):
                return now + 0.02
            self._need_anchor = False
            now = time.monotonic()
            self._anchor(now)
            self._rtf_window = (now, sim.t)
        if self._held:
            if self.control.limit(now) == sim.steps:
                self.behind = 0.0              # paused or waiting: nothing to pace, no lag
                return now + WAIT_POLL         # an input or a service wakes it
            self._held = False                 # released: pace from here, no catching up
            self._anchor(now)
        done = self._integrate(self._target_step(now), now + CHUNK_BUDGET)
        if self.finished or sim.fault is not None:
            return now + IDLE
        if self._held:
            return now + WAIT_POLL             # paused or waiting: an input or service wakes
        if not done or self.real_time_factor <= 0.0:
            return None
        # Next wake-up: the next output's wall time, or the next step's (>= MIN_SLEEP away).
        now = time.monotonic()
        nxt = max(self._wall_of_step(sim.steps + 1), now + MIN_SLEEP)
        out = self._wall_of_step(self._outputs.next_step)
        self._output_slack = out - now      # idle time before the next output [s wall]
        return min(nxt, out)

    def _target_step(self, now: float) -> int | None:
        """Return the step the wall clock asks for (None: no limit); apply the lag policy."""
        rtf = self.real_time_factor
        if rtf <= 0.0:
            self.behind = 0.0
            return None
        sim = self.sim
        target = int(math.floor(((now - self._anchor_wall) * rtf + self._anchor_sim)
                                / self._h + 0.5))
        behind = now - self._wall_of_step(sim.steps + 1)
        if behind > MAX_LAG:
            self.lag_dropped += behind
            self.lag_events += 1
            if self._throttle('lag dropped', now) is not None:
                self._log.warning(
                    f'cannot keep up with real_time_factor {rtf:g}: {behind:.2f} s behind '
                    f'at t = {sim.t:.3f} s; dropping the lag (the simulation now runs '
                    f'{self.lag_dropped:.2f} s behind the wall clock in total; achieved rtf '
                    f'{self.achieved_rtf:.3g})')
            self._anchor(now)
            target = sim.steps + 1
        elif behind > BEHIND_WARN and self._throttle('behind', now) is not None:
            self._log.warning(
                f'falling behind real time: {behind * 1000:.0f} ms behind schedule at '
                f't = {sim.t:.3f} s (real_time_factor {rtf:g}, achieved '
                f'{self.achieved_rtf:.3g}); catching up')
        self.behind = max(behind, 0.0)
        return target

    def _integrate(self, target: int | None, deadline: float) -> bool:
        """
        Integrate toward step ``target`` (None: no limit), publishing on the way.

        Stops at the deadline (wall); returns True if the target was reached.
        """
        sim = self.sim
        while True:
            stop = self._outputs.next_step
            if target is not None:
                stop = min(stop, target)
            if self.end_step is not None:
                stop = min(stop, self.end_step)
            limit = self.control.limit(time.monotonic())
            if limit is not None and sim.steps >= limit:
                self._held = True
                return True
            if limit is not None:
                stop = min(stop, limit)
            if sim.steps >= stop:
                if self.end_step is not None and sim.steps >= self.end_step:
                    self._finish('duration reached')
                return target is None or sim.steps >= target
            n = stop - sim.steps
            n = max(1, min(n, int(CHUNK_BUDGET / max(self._step_cost, 1e-9))))
            if self._inputs.by_stamp:   # the inputs stamped inside the coming steps, at their
                self._inputs.schedule_due(sim, (sim.steps + n) * self._h,   # stamps
                                          self._record_input)
            self._flush_inputs()
            t0 = time.monotonic()
            sim.advance(n)
            t1 = time.monotonic()
            self._step_cost = 0.8 * self._step_cost + 0.2 * (t1 - t0) / n
            self._report_fallback(sim)
            if sim.fault is not None:
                self._on_fault()
                return True
            self._outputs.publish_due(sim)
            if t1 >= deadline:
                return False
            self._inputs.apply(t1, sim, self._record_input)

    def _report_fallback(self, sim: TrainSimulator) -> None:
        """
        Warn when output periods ran out of the integration_max_steps work budget.

        Such a period finishes at the fixed integration_step (deterministic: the same
        offline); the count is in /diagnostics (fallback_periods).
        """
        if not sim.adaptive:
            return
        count = sim.integration_stats['fallback_periods']
        if count > self.fallback_periods:
            self.fallback_periods = count
            if self._throttle('fallback', time.monotonic()) is None:
                return
            self._log.warning(
                f'integration_max_steps reached in {count} output period(s) so far (latest '
                f'before t = {sim.t:.3f} s): the rest of such a period runs at the fixed '
                f'integration_step')

    def _anchor(self, now: float) -> None:
        self._anchor_wall = now
        self._anchor_sim = self.sim.steps * self._h if self.sim is not None else 0.0

    def _wall_of_step(self, step: int) -> float:
        return self._anchor_wall + (step * self._h - self._anchor_sim) / self.real_time_factor

    def _on_fault(self) -> None:
        if self._fault_reported:
            return
        self._fault_reported = True
        writer = self._outputs.writer
        self._log.error(
            f'NUMERICAL FAULT: {self.sim.fault}. The simulation keeps its last good state '
            f'(t = {self.sim.t:.4f} s) and stops integrating; call the reset service to '
            'start again' + ('' if writer is None else
                             f'; the recording {writer.path} stays intact'))
        if self.end_step is not None:
            self._finish('numerical fault', code=3)

    def _record_input(self, topic: str, msgtype: str, t_ns: int, data: bytes) -> None:
        """
        Record an input as it acts; in lock-step, held until the simulation moves on.

        The inputs of one instant then go to the bag in one order (time, topic; arrival order
        on one topic) whatever order their answers came in: the bag of a lock-step run is the
        same on every run.
        """
        if self.control is not None and self.control.lockstep:
            self._held_records.append((topic, msgtype, t_ns, data))
        else:
            self._outputs.record(topic, msgtype, t_ns, data)

    def _flush_inputs(self) -> None:
        """Record the held inputs (lock-step), ordered by time and topic."""
        if self._held_records:
            held, self._held_records = self._held_records, []
            for rec in sorted(held, key=lambda r: (r[2], r[0])):
                self._outputs.record(*rec)

    def _finish(self, why: str, code: int = 0) -> None:
        self._flush_inputs()
        if self.finished:
            return
        self.finished = True
        self.exit_code = code
        figures = self.control.summary() if self.control is not None else ''
        self._log.info(f'{why} at t = {self.sim.t:.3f} s ({self.sim.steps} steps); '
                       'simulation stopped' + (f'; {figures}' if figures else ''))
