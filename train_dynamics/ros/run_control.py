"""
How far ``sim_node`` may integrate: pause, resume and step, and the lock-step with a controller.

Services (``std_srvs/srv/Trigger``, beside ``~/reset``):

- ``~/pause``: the simulation time stops where it is (mid-period too); outputs stop;
- ``~/resume``: it goes on (paced from now at ``real_time_factor``: no catching up);
- ``~/step``: advance ``step_periods`` output periods (publishing that many outputs), then
  stay paused; a running simulation is paused first. The response returns at once, with the
  simulation time it starts from and the output number it stops at.

``sync_mode`` ``lockstep``: the node holds t = 0 until the controller is connected both ways
(a publisher on every input topic ``lockstep_inputs`` declares, and a subscriber on one of the
JointState outputs, on ``/clock`` with ``lockstep_answer`` clock; with clock then
:data:`CONNECT_SETTLE` s for the other direction's discovery), publishes the outputs of t = 0,
and advances to the next output only once every declared input has answered the last output
(:meth:`LockstepInputs.unanswered
<train_dynamics.ros.lockstep_inputs.LockstepInputs.unanswered>`):

- ``brake`` (default): every active brake-input topic has delivered a message whose
  ``header.stamp`` equals the stamp of the last output (a controller with nothing new to say
  answers with its last command re-stamped: that is "ready"); with ``lockstep_answer``
  ``clock``: stamped at or after it (the node publishes ``/clock`` at every output; a
  controller on ``use_sim_time`` answers from its timer; no wait at t = 0, whose outputs get
  :data:`CONNECT_SETTLE` s to reach it; ``lockstep_period``: wait only every that many
  seconds);
- ``traction``: every locomotive that takes a command (``coach_<i>/traction/command``), and
  ``ep``: ``brake_ep/command`` (``brake_system`` ep or ecp), has delivered one command after
  that output was published (``std_msgs/Float64`` has no stamp; the controller sends one per
  output, its last one again for "ready").

A declared input the train does not have is a configuration error (the node refuses it). Answers
take effect at that output's instant, so the closed loop does not depend on the wall clock: its
outputs, inputs and bag are the same on every run, at any ``real_time_factor`` (0: as fast as
both sides can go; > 0: at most that fast). Every wait has a bound: without the controller's
connection at t = 0, or without an answer, for ``lockstep_timeout`` wall seconds the node says
so (a warning naming what is missing, ``/diagnostics`` WARN and the count
``lockstep_timeouts``), then keeps waiting (``lockstep_on_timeout`` ``wait``) or ends the run
(``stop``: ``sim_node`` exits with status :data:`EXIT_LOCKSTEP_TIMEOUT`). A second publisher or
a best-effort one on a declared input (found before t = 0, and before each release while the
declared topics are at most :data:`~train_dynamics.ros.lockstep_inputs.CHEAP_TOPICS`) ends
the run with an error and the same status; a second answer to one output is not used, counted.

Threads: the services run on the executor thread and take the simulation lock; :meth:`limit`
and :meth:`hold_start` run on the simulation thread under it. Every attribute is guarded by
the simulation lock.
"""
from __future__ import annotations

from typing import Any, Callable

from std_srvs.srv import Trigger

from train_dynamics.physics.train import TrainSimulator
from train_dynamics.ros.controller_inputs import ControllerInputs
from train_dynamics.ros.lockstep_inputs import CHEAP_TOPICS
from train_dynamics.ros.publishers import Outputs

CONNECT_SETTLE = 0.3       # [s wall] lock-step start: pause after both directions matched
EXIT_LOCKSTEP_TIMEOUT = 4  # sim_node's exit status after a lock-step timeout with ``stop``
WAIT_POLL = 0.05           # [s wall] longest sleep of a waiting simulation thread
CLOCK_REPEAT = 0.5         # [s wall] lockstep_answer clock: /clock again while a period waits
PROBE_PERIOD = 0.5         # [s wall] lock-step start: the input publishers' QoS looked at


class RunControl:
    """Pause/resume/step and the lock-step gate of one node (see the module documentation)."""

    def __init__(self, node: Any, lock: Any, inputs: ControllerInputs, outputs: Outputs,
                 wake: Callable[[], None]) -> None:
        self._lock = lock
        self._inputs = inputs
        self._outputs = outputs
        self._wake = wake
        self._log = node.get_logger()
        self.sync_mode = 'free'
        self.waits_for: tuple[str, ...] = ('brake',)    # lockstep_inputs
        self.timeout = 5.0              # [s wall] lockstep_timeout, 0 = never
        self.on_timeout = 'wait'
        self.step_periods = 1
        self.paused = False
        self.step_to: int | None = None     # paused: run until this many outputs are out
        self.sim: TrainSimulator | None = None
        self.stop_requested = False     # lock-step timeout with ``stop``: end the run
        self.stop_reason = ''           # why (the run's last log line)
        self.clock = False              # lockstep_answer clock
        self.every = 0.0                # [s] lockstep_period, 0 = every output period
        self._clock_sent = 0.0          # [s wall] /clock last repeated
        self._probed = -PROBE_PERIOD    # [s wall] publishers' QoS last looked at
        self._connected_since: float | None = None
        self._waiting_since: float | None = None
        self._timed_out = False
        self._counted = 0               # outputs whose answer is counted
        self.timeouts = 0
        self.periods = 0                # lock-step periods answered in this run
        self.round_trip_sum = 0.0       # [s wall] output published -> answer applied
        self.round_trip_max = 0.0
        for name, callback in (('pause', self._on_pause), ('resume', self._on_resume),
                               ('step', self._on_step)):
            node.create_service(Trigger, f'~/{name}', callback)

    @property
    def lockstep(self) -> bool:
        """Return True in ``sync_mode`` lockstep."""
        return self.sync_mode == 'lockstep'

    def configure(self, sync_mode: str, timeout: float, on_timeout: str,
                  step_periods: int, waits_for: tuple[str, ...] = ('brake',),
                  answer: str = 'echo', every: float = 0.0) -> None:
        """Take the parameters (lock held)."""
        self.sync_mode = sync_mode
        self.waits_for = tuple(waits_for)
        self.clock = answer == 'clock'
        self.every = float(every)
        self._inputs.configure_lockstep(self.waits_for if self.lockstep else (), self.clock)
        self.timeout = float(timeout)
        self.on_timeout = on_timeout
        self.step_periods = int(step_periods)
        self._wake()

    def start(self, sim: TrainSimulator) -> None:
        """Begin a run at t = 0 (lock held): a paused node stays paused."""
        self.sim = sim
        self.step_to = None
        self.stop_requested = False
        self.stop_reason = ''
        self._probed = -PROBE_PERIOD
        self._connected_since = None
        self._waiting_since = None
        self._timed_out = False
        self._counted = 0               # outputs whose answer is counted
        self.timeouts = 0
        self.periods = 0
        self.round_trip_sum = 0.0
        self.round_trip_max = 0.0

    # -- the simulation thread (lock held) --------------------------------------------------
    def _unconnected(self) -> list[str]:
        """Return what the lock-step start still misses: input publishers, an output reader."""
        missing = [f'a publisher on {name}'
                   for name in self._inputs.unconnected(self.waits_for)]
        if self.clock and not self._outputs.clock_subscribed():
            missing.append('a subscriber on /clock')
        elif not self.clock and not self._outputs.subscribed():
            missing.append('a subscriber on the outputs')
        return missing

    def hold_start(self, now: float) -> bool:
        """Lock-step: return True while t = 0 waits for the controller (both directions)."""
        if not self.lockstep:
            return False
        if self._waiting_since is None:
            self._waiting_since = now
            self._timed_out = False
        missing = self._unconnected()
        if missing:
            if self._connected_since is None and now == self._waiting_since:
                self._log.info(f'lockstep: waiting for the controller ({", ".join(missing[:5])})'
                               ' before t = 0')
            self._connected_since = None
            if now - self._probed >= PROBE_PERIOD:      # an unmatched (best-effort) publisher?
                self._probed = now
                problems = self._inputs.publisher_problems(self.waits_for, qos=True)
                if problems:
                    self._fail('before t = 0: ' + '; '.join(problems))
                    return True
            self._check_timeout(now, lambda: 'the controller to connect: '
                                + ', '.join(missing[:5]))
            return True
        if self._connected_since is None:
            self._connected_since = now
        # echo answers: no settle. The answer to t = 0 is the event that the controller has
        # the outputs; the reliable writer keeps them for a reader it matched until that
        # reader acknowledges, also one that discovers the writer later
        if self.clock and now - self._connected_since < CONNECT_SETTLE:
            return True
        problems = self._inputs.publisher_problems(self.waits_for, qos=True)
        if problems:
            self._fail('before t = 0: ' + '; '.join(problems))
            return True
        self._waiting_since = None
        self._log.info('lockstep: controller connected; starting')
        return False

    def _fail(self, what: str) -> None:
        """End the run: the lock-step cannot be deterministic (exit status 4)."""
        if not self.stop_requested:
            self._log.error(f'lockstep refused {what}; ending the run (its loop would not be '
                            'the same on every run)')
            self.stop_requested = True
            self.stop_reason = 'lockstep refused'

    def _every(self, out: Outputs) -> int:
        """Return the output periods between two waits (``lockstep_period``)."""
        return max(1, round(self.every * out.rate)) if self.every > 0 else 1

    def _waits_at(self, out: Outputs) -> bool:
        """Return True if the last output published is one the controller must answer."""
        if not self.clock:
            return True
        if out.last_t_ns <= 0:
            return False            # a timer fires one period after it starts: none at t = 0
        return (out.published - 1) % self._every(out) == 0

    def limit(self, now: float) -> int | None:
        """Return the integration step the run may reach now (None: no limit)."""
        sim, out = self.sim, self._outputs
        lim = None
        if self.lockstep and self.clock and out.published == 1 and sim.steps == out.last_step \
                and now - out.last_wall < CONNECT_SETTLE:
            return sim.steps    # t = 0: the controller takes its first outputs before t_1's
        if self.lockstep and out.published and sim.steps == out.last_step \
                and self._waits_at(out):
            if not self._inputs.answered(out.last_t_ns, self.waits_for):
                self._wait(now)
                return sim.steps
            if self._counted != out.published:
                cheap = self._inputs.lockstep_topics(self.waits_for) <= CHEAP_TOPICS
                problems = self._inputs.publisher_problems(self.waits_for, scanned=not cheap)
                if problems:
                    self._fail(f'at t = {sim.t:.6f} s: ' + '; '.join(problems))
                    return sim.steps
                self._counted = out.published
                self._answered(now)
            lim = out.next_step
        if self.paused:
            if self.step_to is None or out.published >= self.step_to:
                self.step_to = None
                return sim.steps
            lim = out.next_step if lim is None else min(lim, out.next_step)
        return lim

    def _wait(self, now: float) -> None:
        if self._waiting_since is None:
            self._waiting_since = now
            self._clock_sent = now
            self._timed_out = False
            return
        if self.clock and now - self._clock_sent > CLOCK_REPEAT:
            self._clock_sent = now      # /clock is best-effort at the controller: once more
            self._outputs.repeat_clock()
        self._check_timeout(now, self._unanswered)

    def _unanswered(self) -> str:
        """Return what the period waits for: the output and its inputs that did not answer."""
        missing = self._inputs.unanswered(self._outputs.last_t_ns, self.waits_for)
        return (f'the answer to the output of t = {self.sim.t:.6f} s on ' + ', '.join(missing[:5])
                + (f' (and {len(missing) - 5} more)' if len(missing) > 5 else '')
                + (' (stamped at or after it)' if self.clock else ''))

    def _check_timeout(self, now: float, what: Callable[[], str]) -> None:
        """After ``lockstep_timeout`` of waiting for ``what()``: warn once, then wait or stop."""
        if self.timeout > 0 and not self._timed_out and now - self._waiting_since > self.timeout:
            self._timed_out = True
            self.timeouts += 1
            stop = self.on_timeout == 'stop'
            self._log.warning(f'lockstep: {self.timeout:g} s without {what()}; '
                              + ('stopping the run' if stop else 'still waiting'))
            if stop:
                self.stop_requested = True
                self.stop_reason = 'lockstep timeout'

    def _answered(self, now: float) -> None:
        """Count an answered period and its round trip (output published -> answer seen)."""
        rtt = max(now - self._outputs.last_wall, 0.0)
        self.periods += 1
        self.round_trip_sum += rtt
        self.round_trip_max = max(self.round_trip_max, rtt)
        self._waiting_since = None

    def waiting(self, now: float) -> str:
        """Return why the simulation waits for the controller ('' when it does not)."""
        if not self.lockstep or self._waiting_since is None:
            return ''
        if not self._outputs.published:
            what = 'the controller to connect: ' + ', '.join(self._unconnected()[:5])
        else:
            missing = self._inputs.unanswered(self._outputs.last_t_ns, self.waits_for)
            what = (f'the answer to the output of t = {self.sim.t:.6f} s'
                    + (f' on {", ".join(missing[:5])}' if missing else ''))
        return f'lockstep: waiting {now - self._waiting_since:.1f} s for {what}'

    def summary(self) -> str:
        """Return the lock-step figures of the run ('' in free mode): periods, round trip."""
        if not self.lockstep:
            return ''
        mean = self.round_trip_sum / self.periods if self.periods else 0.0
        return (f'lockstep: {self.periods} periods answered, round trip mean '
                f'{mean * 1e3:.3f} ms, max {self.round_trip_max * 1e3:.3f} ms, '
                f'{self._inputs.duplicates} duplicate answers not used')

    def report(self) -> dict[str, str]:
        """Return the ``/diagnostics`` values of the run control."""
        mean = self.round_trip_sum / self.periods if self.periods else 0.0
        return {'sync_mode': self.sync_mode, 'lockstep_inputs': ','.join(self.waits_for),
                'paused': str(self.paused).lower(),
                'lockstep_periods': str(self.periods),
                'lockstep_timeouts': str(self.timeouts),
                'lockstep_answer': 'clock' if self.clock else 'echo',
                'lockstep_duplicate_answers': str(self._inputs.duplicates),
                'lockstep_round_trip_mean_ms': f'{mean * 1e3:.3f}',
                'lockstep_round_trip_max_ms': f'{self.round_trip_max * 1e3:.3f}'}

    # -- services (executor thread) ---------------------------------------------------------
    def _on_pause(self, request: Trigger.Request, response: Trigger.Response):
        with self._lock.held():
            already = self.paused
            self.paused = True
            self.step_to = None
            t = self.sim.t
        response.success = True
        response.message = f'{"already " if already else ""}paused at t = {t:.6f} s'
        self._log.info(f'pause service: {response.message}')
        return response

    def _on_resume(self, request: Trigger.Request, response: Trigger.Response):
        with self._lock.held():
            was = self.paused
            self.paused = False
            self.step_to = None
            t = self.sim.t
            self._wake()
        response.success = True
        response.message = f'resumed at t = {t:.6f} s' if was else f'running (t = {t:.6f} s)'
        self._log.info(f'resume service: {response.message}')
        return response

    def _on_step(self, request: Trigger.Request, response: Trigger.Response):
        with self._lock.held():
            self.paused = True
            base = self._outputs.published if self.step_to is None else self.step_to
            self.step_to = base + self.step_periods
            t = self.sim.t
            self._wake()
        response.success = True
        response.message = (f'stepping {self.step_periods} output period(s) from t = {t:.6f} s '
                            f'(until output {self.step_to}), then paused')
        self._log.info(f'step service: {response.message}')
        return response
