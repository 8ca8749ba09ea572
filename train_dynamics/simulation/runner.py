"""
The offline run loop: one simulator, its brake inputs, samples at the output instants.

``train-dynamics simulate`` and ``compare`` (:mod:`train_dynamics.cli`) run the model through
:func:`run_simulation`; ``sim_node`` takes the same output grid (:func:`output_step`) and
input timing (:func:`step_of`). Simulation time advances in integration steps of ``h`` [s]:
an output t_j = j / rate is taken at the nearest step. An input at bag time t acts from t
itself (zero-order hold; the step that spans t is split there, ``TrainSimulator.schedule``)
when the simulator takes inputs at their instants (``exact_inputs``: ``cylinder_per_coach``,
``pipe_per_coach``), else from the first step k with k h >= t. No ROS, no bag I/O: the input
events come from :mod:`train_dynamics.recording.inputs` or a brake-valve model, the samples go
to the sinks of :mod:`train_dynamics.recording.sinks`.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
import math
import time
from typing import Any

from train_dynamics.input_kinds import KINDS
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.simulation.demand import blending_schedule


#: [s wall] period of the ``progress`` callback of :func:`run_simulation`
PROGRESS_PERIOD = 0.1


@dataclass(frozen=True)
class CommandEvent:
    """
    One controller input: from integration step ``step`` on, ``kind`` holds ``value``.

    ``kind``: a row of :data:`train_dynamics.input_kinds.KINDS` (its setter is how the value
    reaches the simulator); ``index``: the 0-based vehicle of a per-vehicle kind (None for
    a train-wide one); ``value`` in the simulator's units (gauge [Pa] for the brake
    pressures, the command as sent otherwise); ``t_ns`` [ns] from the run's start.
    """

    kind: str
    index: int | None
    value: float
    t_ns: int
    step: int
    topic: str                # relative topic name as written to the output
    msg: Any = None           # the message of an input bag (rosbags; None: a schedule)

    @classmethod
    def at(cls, kind: str, index: int | None, value: float, t_ns: int, h: float,
           msg: Any = None) -> CommandEvent:
        """Return the event of ``kind`` at ``t_ns`` [ns] for a run of step ``h`` [s]."""
        topic = KINDS[kind].topic_of(0 if index is None else index)
        return cls(kind, index, value, t_ns, step_of(t_ns, h), topic, msg)


def apply_event(sim: TrainSimulator, e: CommandEvent) -> None:
    """Hand one input event to ``sim`` through its kind's setter (the node's dispatch)."""
    KINDS[e.kind].apply(sim, e.value, e.index)


@dataclass
class InputSchedule:
    """
    The inputs of a run: brake events (sorted) or a brake-valve model; the commands.

    ``events``: the brake-input events of ``mode`` (applied first at an instant);
    ``commands``: every other kind's events (traction, EP, WSP valves, the brake control
    unit's), sorted by time.
    """

    mode: str
    events: list[CommandEvent] = field(default_factory=list)
    valve: Any = None                                  # BrakeValveModel (pipe_head, no bag)
    source: str = ''
    commands: list[CommandEvent] = field(default_factory=list)

    def for_step(self, h: float) -> InputSchedule:
        """Return the same inputs for a run with integration step ``h`` [s] (:func:`step_of`)."""
        if not self.events and not self.commands:
            return self
        return InputSchedule(self.mode,
                             [replace(e, step=step_of(e.t_ns, h)) for e in self.events],
                             self.valve if not self.events else None, self.source,
                             [replace(e, step=step_of(e.t_ns, h)) for e in self.commands])


def _ns(t: float) -> int:
    return int(round(t * 1e9))


def schedule_events(cfg: Any) -> list[CommandEvent]:
    """
    Return the commands of the parameter file's schedules, in time order.

    ``traction_schedule_times`` / ``_commands`` for every locomotive, ``ep_schedule_*`` (the
    EP / ECP train line), and with ``blending: builtin`` the brake control unit's
    ``demand_schedule_*``, ``emergency_schedule_time``, ``ed_trip_schedule_time``
    (simulation/demand.py).
    """
    h = float(cfg.integration_step)
    locos = cfg.consist.commanded if cfg.traction_schedule_times else []
    events = [CommandEvent.at('traction', i, float(c), _ns(t), h)
              for t, c in zip(cfg.traction_schedule_times, cfg.traction_schedule_commands)
              for i in locos]
    events += [CommandEvent.at('ep', None, float(c), _ns(t), h)
               for t, c in zip(cfg.ep_schedule_times, cfg.ep_schedule_commands)]
    if cfg.blending == 'builtin':
        events += [CommandEvent.at(kind, None, value, t_ns, h)
                   for t_ns, kind, value in blending_schedule(cfg)]
    return sorted(events, key=lambda e: e.t_ns)


def command_events(cfg: Any, from_bag: list[CommandEvent]) -> list[CommandEvent]:
    """
    Return the commands of a run: an input bag's, completed by the parameter file's.

    The bag's events of a kind replace the schedule of that kind; in time order (the bag's
    first among equal times).
    """
    have = {e.kind for e in from_bag}
    return sorted(list(from_bag) + [e for e in schedule_events(cfg) if e.kind not in have],
                  key=lambda e: e.t_ns)


def step_of(t_ns: int, h: float) -> int:
    """First integration step k with k*h >= t (t in ns): where an input at t takes effect."""
    h_ns = h * 1e9
    if abs(h_ns - round(h_ns)) < 1e-6:              # a whole number of ns: exact arithmetic
        return max(0, -(-int(t_ns) // int(round(h_ns))))
    return max(0, math.ceil(t_ns / h_ns - 1e-9))


def output_step(j: int, rate: float, h: float) -> int:
    """Integration step of the j-th output, t_j = j / rate [Hz]: the nearest step."""
    return int(math.floor(j / rate / h + 0.5))


def end_step(duration: float, h: float) -> int:
    """Return the last integration step of a run of ``duration`` [s]: the nearest step."""
    return int(math.floor(duration / h + 0.5))


class Sample:
    """What an output sink receives at each output time (views valid during the call)."""

    __slots__ = ('step', 't', 'sim', 'head_gauge')

    def __init__(self, step: int, t: float, sim: TrainSimulator,
                 head_gauge: float | None) -> None:
        self.step, self.t, self.sim, self.head_gauge = step, t, sim, head_gauge


def iter_output_steps(duration: float, rate: float, h: float):
    """
    Yield the integration steps of the samples t_j = j / rate [Hz], 0 <= t_j <= duration.

    Each the nearest step (:func:`output_step`), each step at most once; lazy.
    """
    n = int(math.floor(duration * rate + 1e-9))
    last = None
    for j in range(n + 1):
        k = output_step(j, rate, h)
        if k != last:
            yield k
            last = k


def output_steps(duration: float, rate: float, h: float) -> list[int]:
    """Return :func:`iter_output_steps` as a list."""
    return list(iter_output_steps(duration, rate, h))


def _drive_head(valve: Any, sim: TrainSimulator, k: int, head: float | None,
                k_end: int) -> tuple[float | None, int]:
    """
    Set the head-pipe pressure of the brake valve at step ``k`` [Pa gauge].

    Return the pressure applied and the next step at which the valve's output may change.
    """
    h = sim.h
    # (+1e-9 step: an event due exactly at this step is applied despite rounding of k*h)
    p = valve.advance_to(k * h + 1e-9 * h)
    if p != head:
        sim.set_head_pipe_pressure(p)
        head = p
    if p != valve.target:
        return head, k + 1                              # ramping: follow every step
    pending = valve.pending
    if pending:
        return head, step_of(int(round(pending[0].time * 1e9)), h)
    return head, k_end


class _DueEvents:
    """Input events sorted by step, each applied when its step comes (zero-order hold)."""

    def __init__(self, events: Sequence[Any], apply: Callable[[Any], None],
                 on_input: Callable[[Any], None] | None) -> None:
        self._events = events
        self._apply = apply
        self._on_input = on_input
        self._next = 0

    def apply_until(self, k: int) -> None:
        """Apply (and report to ``on_input``) every event due at step ``k`` or before."""
        events = self._events
        while self._next < len(events) and events[self._next].step <= k:
            self._apply_one(events[self._next])
            self._next += 1

    def schedule_until(self, k: int, sim: TrainSimulator) -> None:
        """Hand ``sim`` every event due by step ``k``, to apply at its own bag time."""
        events = self._events
        while self._next < len(events) and events[self._next].step <= k:
            sim.schedule(events[self._next].t_ns * 1e-9,
                         lambda e=events[self._next]: self._apply_one(e))
            self._next += 1

    def _apply_one(self, event: Any) -> None:
        """Apply ``event`` and report it to ``on_input``."""
        self._apply(event)
        if self._on_input is not None:
            self._on_input(event)

    def next_step(self, default: int) -> int:
        """Return the step of the next event, ``default`` when none is left."""
        return self._events[self._next].step if self._next < len(self._events) else default


def run_simulation(cfg, duration: float, inputs: InputSchedule, *,
                   on_sample: Callable[[Sample], None],
                   on_input: Callable[[CommandEvent], None] | None = None,
                   sample_steps: Sequence[int] | None = None,
                   progress: Callable[[float], None] | None = None):
    """
    Run a fresh TrainSimulator for ``duration`` [s]; return it (check ``sim.fault``).

    ``on_sample`` is called at every output step (default: ``publish_rate``), after the
    inputs due at that step were applied; ``on_input`` for every input event applied;
    ``progress`` with the fraction done (every :data:`PROGRESS_PERIOD` s of wall time, whatever
    the duration; 1.0 at the end).
    """
    sim = TrainSimulator(cfg)
    h = sim.h
    k_end = end_step(duration, h)
    samples = iter(sample_steps) if sample_steps is not None else iter_output_steps(
        duration, float(cfg.publish_rate), h)
    next_sample = next(samples, None)
    events = inputs.events
    valve = inputs.valve
    if valve is not None:
        valve.reset()
    brake_events = _DueEvents(events, lambda e: apply_event(sim, e), on_input)
    traction = _DueEvents(inputs.commands, lambda e: apply_event(sim, e), on_input)
    k = 0
    head: float | None = None
    last_progress = time.monotonic()
    exact = sim.exact_inputs
    while True:
        if exact:
            brake_events.schedule_until(k, sim)
            traction.schedule_until(k, sim)
        else:
            brake_events.apply_until(k)
            traction.apply_until(k)
        valve_next = k_end
        if valve is not None:
            head, valve_next = _drive_head(valve, sim, k, head, k_end)
        while next_sample is not None and next_sample <= k:
            if next_sample <= k_end:
                on_sample(Sample(k, k * h, sim, head))
            next_sample = next(samples, None)
        if k >= k_end:
            break
        nxt = min(k_end, valve_next, next_sample if next_sample is not None else k_end)
        if exact:           # the inputs inside the span go to the simulator, at their instants
            nxt = max(nxt, k + 1)
            brake_events.schedule_until(nxt, sim)
            traction.schedule_until(nxt, sim)
        else:
            nxt = max(min(nxt, brake_events.next_step(k_end), traction.next_step(k_end)),
                      k + 1)
        done = sim.advance(nxt - k)
        if sim.fault is not None or done != nxt - k:
            break
        k = nxt
        if progress is not None:
            now = time.monotonic()
            if now - last_progress >= PROGRESS_PERIOD:
                progress(k / k_end if k_end else 1.0)
                last_progress = now
    if progress is not None:
        progress(1.0)
    return sim
