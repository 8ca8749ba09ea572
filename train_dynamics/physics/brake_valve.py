"""
The driver's brake valve, without ROS: handle positions, schedule and pressure rates.

The valve sets the brake-pipe pressure at the head of the train. Its handle selects a target
GAUGE pressure [Pa]; the output moves toward that target at a limited rate (a real valve
vents or charges the pipe through restricted ports):

==================  =========================================================================
handle position     target (gauge)
==================  =========================================================================
``release``         ``pipe_nominal_pressure`` (running position; ``running`` is an alias)
``service_k``       graduated steps, k = 1..``service_steps``: ``service_1`` drops the pipe by
                    ``first_service_drop`` (the distributors' first stage), the last step is
                    full service; the steps in between are evenly spaced
``full_service``    ``full_service_pressure``
``emergency``       0 (pipe vented to atmosphere)
==================  =========================================================================

Rates [Pa/s]: a falling output moves at ``service_rate`` (``emergency_rate`` when the handle
is in ``emergency``), a rising one at ``release_rate``. Between handle changes the output is
piecewise linear, so :meth:`BrakeValveModel.advance` gives the same result for any step size.

The output starts at ``pipe_nominal_pressure`` (a charged pipe, train running) at t = 0.
A schedule is a list of ``"TIME:POSITION"`` strings, times [s] strictly increasing from the
moment the schedule was set (t = 0 for the schedule given at construction).

Used by the ``brake_valve`` node and by the offline command (the ``brake_valve`` section of a
parameter file, :func:`train_dynamics.param_files.valve_params`, builds the head-pipe pressure
when there is no input bag). Never imports rclpy.
"""
from __future__ import annotations

import copy
from dataclasses import dataclass
import math
from typing import Any, Iterable, Mapping

from train_dynamics.physics.config import (ATMOSPHERIC_PRESSURE, DOUBLE, FULL_SERVICE_PRESSURE,
                                           INTEGER, ParamSpec, PIPE_NOMINAL_PRESSURE, STRING,
                                           STRING_ARRAY, validate_value)
from train_dynamics.quoting import quote

#: [s] latest schedule time, ~32 years: a bound against absurd values (a typo of an exponent),
#: not a property of any valve; a guess, far beyond any run
MAX_SCHEDULE_TIME = 1.0e9

#: The valve model's parameters (gauge pressures [Pa], rates [Pa/s]); all change live.
VALVE_PARAMETERS: dict[str, ParamSpec] = {p.name: p for p in [
    ParamSpec('position', 'release', STRING,
              'Handle position: release (alias running), service_1..service_N, full_service '
              'or emergency. Setting it moves the handle now and cancels the rest of the '
              'schedule.', dynamic=True),
    ParamSpec('schedule', [], STRING_ARRAY,
              'Handle schedule, "TIME:POSITION" strings, TIME [s] strictly increasing, '
              f'<= {MAX_SCHEDULE_TIME:g}, '
              'counted from node start (or from the moment the schedule is set live).',
              dynamic=True),
    ParamSpec('pipe_nominal_pressure', PIPE_NOMINAL_PRESSURE, DOUBLE,
              'Brake-pipe running pressure (release position), gauge [Pa].',
              low=1.0e5, high=1.0e6, dynamic=True),
    ParamSpec('full_service_pressure', FULL_SERVICE_PRESSURE, DOUBLE,
              'Brake-pipe pressure at full service, gauge [Pa].',
              low=0.0, high=1.0e6, dynamic=True),
    ParamSpec('first_service_drop', 50000.0, DOUBLE,        # 0.5 bar: the distributors' 1st stage
              'Pipe-pressure drop of the first service step service_1 [Pa].',
              low=1.0e3, high=1.0e6, dynamic=True),
    ParamSpec('service_steps', 7, INTEGER,                  # service_1 .. service_7 = full
              'Number N of graduated service positions service_1..service_N; the last '
              'one equals full service.', low=1, high=50, dynamic=True),
    ParamSpec('service_rate', 27000.0, DOUBLE,              # 5 -> 3.5 bar in 5.6 s
              'Rate at which a service application lowers the pipe pressure [Pa/s].',
              low=1.0, high=1.0e8, dynamic=True),
    ParamSpec('emergency_rate', 400000.0, DOUBLE,           # 5 -> 0 bar in 1.25 s
              'Rate at which the emergency position vents the pipe [Pa/s].',
              low=1.0, high=1.0e8, dynamic=True),
    ParamSpec('release_rate', 50000.0, DOUBLE,              # 0.5 bar/s: 3.5 -> 5 bar in 3 s
              'Rate at which the pipe is recharged toward a higher target [Pa/s].',
              low=1.0, high=1.0e8, dynamic=True),
]}

#: Parameters of the ``brake_valve`` node beyond the model's (all change live).
VALVE_NODE_PARAMETERS: dict[str, ParamSpec] = {p.name: p for p in [
    ParamSpec('publish_rate', 50.0, DOUBLE,
              'Publishing rate of brake_pipe/pressure [Hz] (node clock).',
              low=0.1, high=1000.0, dynamic=True),
    ParamSpec('atmospheric_pressure', ATMOSPHERIC_PRESSURE, DOUBLE,
              'Atmospheric pressure [Pa]: published absolute pressure = gauge + '
              'atmospheric_pressure.', low=50000.0, high=150000.0, dynamic=True),
]}

#: The numeric settings of the model (validated together by :func:`validate_settings`).
SETTING_NAMES = ('pipe_nominal_pressure', 'full_service_pressure', 'first_service_drop',
                 'service_steps', 'service_rate', 'emergency_rate', 'release_rate')

#: Parameters of the ``brake_valve`` node that are not model settings.
NODE_ONLY_PARAMETERS = frozenset({*VALVE_NODE_PARAMETERS, 'frame_id'})


@dataclass(frozen=True)
class ScheduleEntry:
    """Move the handle to ``position`` at ``time`` [s] after the schedule was set."""

    time: float
    position: str


def validate_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """
    Check the numeric settings (all of :data:`SETTING_NAMES`) together; return them normalised.

    Missing ones take their defaults. Raises ``ValueError`` with a one-line reason.
    """
    out: dict[str, Any] = {
        name: validate_value(name, settings.get(name, VALVE_PARAMETERS[name].default),
                             VALVE_PARAMETERS)
        for name in SETTING_NAMES}
    full_drop = out['pipe_nominal_pressure'] - out['full_service_pressure']
    if not full_drop > 0.0:
        raise ValueError('full_service_pressure must be below pipe_nominal_pressure '
                         f'({out["full_service_pressure"]:g} >= '
                         f'{out["pipe_nominal_pressure"]:g})')
    if not out['first_service_drop'] <= full_drop:
        raise ValueError(f'first_service_drop ({out["first_service_drop"]:g} Pa) must not '
                         'exceed pipe_nominal_pressure - full_service_pressure '
                         f'({full_drop:g} Pa)')
    return out


def position_names(service_steps: int) -> list[str]:
    """All valid handle positions for ``service_steps`` graduated service steps."""
    return (['release', 'running'] + [f'service_{k}' for k in range(1, service_steps + 1)]
            + ['full_service', 'emergency'])


def target_pressure(position: str, settings: Mapping[str, Any]) -> float:
    """Target gauge pressure [Pa] of a handle position (``settings`` as validated)."""
    nominal = float(settings['pipe_nominal_pressure'])
    full = float(settings['full_service_pressure'])
    if position in ('release', 'running'):
        return nominal
    if position == 'full_service':
        return full
    if position == 'emergency':
        return 0.0
    n = int(settings['service_steps'])
    if position.startswith('service_'):
        k_text = position[len('service_'):]
        if k_text.isdigit() and str(int(k_text)) == k_text and 1 <= int(k_text) <= n:
            k = int(k_text)
            first = float(settings['first_service_drop'])
            frac = 0.0 if n == 1 else (k - 1) / (n - 1)
            return nominal - (first + frac * ((nominal - full) - first))
    raise ValueError(f'unknown handle position {quote(position)}; valid: release, running, '
                     f'service_1..service_{n}, full_service, emergency')


def validate_position(position: Any, settings: Mapping[str, Any]) -> str:
    """Return ``position`` if it is a valid handle position, else raise ``ValueError``."""
    if not isinstance(position, str):
        raise ValueError(f'position: expected a string, got {type(position).__name__} '
                         f'{quote(position)}')
    target_pressure(position, settings)
    return position


def parse_schedule(entries: Any, settings: Mapping[str, Any] | None = None) -> list[ScheduleEntry]:
    """
    Parse ``["0.0:release", "1.0:emergency", ...]`` into :class:`ScheduleEntry` items.

    Times [s] must be in [0, :data:`MAX_SCHEDULE_TIME`] and strictly increasing; positions
    valid for ``settings`` (defaults if None). Raises ``ValueError`` naming the bad entry.
    """
    settings = validate_settings(settings or {})
    if isinstance(entries, (str, bytes)) or not isinstance(entries, Iterable):
        raise ValueError('schedule: expected a list of "TIME:POSITION" strings, got '
                         f'{quote(entries)}')
    out: list[ScheduleEntry] = []
    for k, item in enumerate(entries):
        if not isinstance(item, str) or ':' not in item:
            raise ValueError(f'schedule[{k}]: expected "TIME:POSITION" (e.g. "1.0:emergency"), '
                             f'got {quote(item)}')
        time_text, position = (part.strip() for part in item.split(':', 1))
        try:
            t = float(time_text)
        except ValueError:
            raise ValueError(
                f'schedule[{k}] {quote(item)}: time {quote(time_text)} is not a number') from None
        if not math.isfinite(t) or not 0.0 <= t <= MAX_SCHEDULE_TIME:
            raise ValueError(f'schedule[{k}] {quote(item)}: time must be finite, >= 0 and <= '
                             f'{MAX_SCHEDULE_TIME:g} s')
        if out and not t > out[-1].time:
            raise ValueError(f'schedule[{k}] {quote(item)}: times must strictly increase '
                             f'({t:g} after {out[-1].time:g})')
        try:
            target_pressure(position, settings)
        except ValueError as exc:
            raise ValueError(f'schedule[{k}] {quote(item)}: {exc}') from None
        out.append(ScheduleEntry(t, position))
    return out


class BrakeValveModel:
    """
    Driver's brake valve: handle position and schedule -> head brake-pipe pressure (gauge Pa).

    >>> m = BrakeValveModel(schedule=['1.0:emergency'])
    >>> m.advance_to(1.0), m.position          # vented from t = 1 s
    (500000.0, 'emergency')
    >>> m.advance(0.5)                         # 0.5 s at 400 kPa/s
    300000.0
    """

    def __init__(self, position: str = VALVE_PARAMETERS['position'].default,
                 schedule: Iterable[str] | Iterable[ScheduleEntry] = (),
                 **settings: Any) -> None:
        unknown = set(settings) - set(SETTING_NAMES)
        if unknown:
            raise ValueError(f'unknown brake valve parameter(s): {", ".join(sorted(unknown))}')
        self.settings = validate_settings(settings)
        self._initial_position = validate_position(position, self.settings)
        self._entries = self._as_entries(schedule)
        self.reset()

    # -- construction ------------------------------------------------------------------
    @classmethod
    def from_params(cls, params: Mapping[str, Any], *, strict: bool = False) -> 'BrakeValveModel':
        """
        Build from ``{name: value}`` (e.g. the node's parameters, or a file's brake-valve section).

        Keys of the node that do not concern the model (``publish_rate``,
        ``atmospheric_pressure``, ``frame_id``) are ignored; other unknown keys too unless
        ``strict``. Raises ``ValueError`` with a one-line reason.
        """
        known = set(SETTING_NAMES) | {'position', 'schedule'}
        if strict:
            unknown = set(params) - known - NODE_ONLY_PARAMETERS
            if unknown:
                raise ValueError(f'unknown brake_valve parameter(s): {", ".join(sorted(unknown))}')
        kwargs = {k: v for k, v in params.items() if k in known}
        schedule = kwargs.pop('schedule', None)
        if schedule is None:
            schedule = []
        return cls(schedule=schedule, **kwargs)

    def _as_entries(self, schedule: Iterable[Any]) -> list[ScheduleEntry]:
        if isinstance(schedule, (str, bytes)) or not isinstance(schedule, Iterable):
            return parse_schedule(schedule, self.settings)    # raises with the reason
        schedule = list(schedule)
        if schedule and all(isinstance(e, ScheduleEntry) for e in schedule):
            schedule = [f'{quote(e.time)}:{e.position}' for e in schedule]
        return parse_schedule(schedule, self.settings)

    # -- state -------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to t = 0: charged pipe, initial handle position, the whole schedule pending."""
        self.t = 0.0
        self.pressure = float(self.settings['pipe_nominal_pressure'])
        self.position = self._initial_position
        self._origin = 0.0
        self._next = 0
        self._apply_due_events()

    @property
    def schedule(self) -> list[ScheduleEntry]:
        """Return the schedule as set (times relative to when it was set)."""
        return list(self._entries)

    @property
    def pending(self) -> list[ScheduleEntry]:
        """Schedule entries not yet applied, with ABSOLUTE model times [s]."""
        return [ScheduleEntry(self._origin + e.time, e.position)
                for e in self._entries[self._next:]]

    @property
    def target(self) -> float:
        """Target gauge pressure [Pa] of the current handle position."""
        return target_pressure(self.position, self.settings)

    def positions(self) -> list[str]:
        """Return the valid handle positions with the current ``service_steps``."""
        return position_names(self.settings['service_steps'])

    def target_of(self, position: str) -> float:
        """Target gauge pressure [Pa] of ``position`` (``ValueError`` if unknown)."""
        return target_pressure(position, self.settings)

    # -- live changes -------------------------------------------------------------------
    def set_position(self, position: str) -> None:
        """Move the handle now; cancels the rest of the schedule (a driver's override)."""
        position = validate_position(position, self.settings)
        self.position = position
        self._initial_position = position    # what reset() returns to
        self._entries = []
        self._origin = 0.0
        self._next = 0

    def set_schedule(self, schedule: Iterable[Any]) -> None:
        """Replace the schedule; its times count from now (``self.t``). Due entries apply now."""
        entries = self._as_entries(schedule)
        self._entries = entries
        self._origin = self.t
        self._next = 0
        self._initial_position = self.position
        self._apply_due_events()

    def update_settings(self, **changes: Any) -> None:
        """Change numeric settings (validated together; handle and schedule must stay valid)."""
        merged = dict(self.settings)
        merged.update(changes)
        check_live_change(self, changes)
        self.settings = validate_settings(merged)

    # -- time ----------------------------------------------------------------------------
    def _apply_due_events(self) -> None:
        while self._next < len(self._entries) and \
                self._origin + self._entries[self._next].time <= self.t:
            self.position = self._entries[self._next].position
            self._next += 1

    def _ramp(self, dt: float) -> None:
        """Move the output toward the current target for ``dt`` seconds (constant handle)."""
        if dt <= 0.0:
            return
        target = self.target
        p = self.pressure
        if p > target:
            key = 'emergency_rate' if self.position == 'emergency' else 'service_rate'
            rate = self.settings[key]
            self.pressure = max(target, p - rate * dt)
        elif p < target:
            self.pressure = min(target, p + self.settings['release_rate'] * dt)

    def advance_to(self, t: float) -> float:
        """
        Run the valve to time ``t`` [s] (>= ``self.t``); return the gauge pressure [Pa].

        A ``t`` earlier than ``self.t`` changes nothing (time never runs backwards here; call
        :meth:`reset` to start over).
        """
        t = float(t)
        if not math.isfinite(t):
            raise ValueError(f'time must be finite, got {t}')
        while self._next < len(self._entries):
            t_event = self._origin + self._entries[self._next].time
            if t_event > t:
                break
            self._ramp(t_event - self.t)
            self.t = max(self.t, t_event)
            self.position = self._entries[self._next].position
            self._next += 1
        if t > self.t:
            self._ramp(t - self.t)
            self.t = t
        return self.pressure

    def advance(self, dt: float) -> float:
        """Run the valve for ``dt`` [s] (>= 0); return the gauge pressure [Pa]."""
        if not dt >= 0.0:
            raise ValueError(f'dt must be >= 0, got {dt}')
        return self.advance_to(self.t + dt)

    def pressure_at(self, t: float) -> float:
        """
        Gauge pressure [Pa] at time ``t`` following the schedule from t = 0.

        Stateless: replays a copy of the valve from :meth:`reset` (live changes made so far are
        part of its initial position/schedule); ``self`` is not modified.
        """
        clone = copy.deepcopy(self)
        clone.reset()
        return clone.advance_to(t)

    def pressures(self, times: Iterable[float]) -> list[float]:
        """Gauge pressures [Pa] at increasing ``times`` [s], replayed from t = 0 (stateless)."""
        clone = copy.deepcopy(self)
        clone.reset()
        return [clone.advance_to(t) for t in times]


def check_live_change(model: BrakeValveModel, changes: Mapping[str, Any], *,
                      check_pending: bool = True) -> None:
    """
    Raise ``ValueError`` if ``changes`` to the settings would make the valve inconsistent.

    The current handle position and every pending schedule entry must stay valid (e.g.
    lowering ``service_steps`` below a position in use is refused).
    """
    merged = dict(model.settings)
    merged.update(changes)
    settings = validate_settings(merged)
    try:
        target_pressure(model.position, settings)
    except ValueError as exc:
        raise ValueError(f'the handle is at {quote(model.position)}, which would become invalid: '
                         f'{exc}') from None
    for entry in (model.pending if check_pending else []):
        try:
            target_pressure(entry.position, settings)
        except ValueError as exc:
            raise ValueError(f'pending schedule entry {quote(entry.position)} would become '
                             f'invalid: {exc}') from None
