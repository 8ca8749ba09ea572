"""
The controller inputs, written once: one :class:`InputKind` row per kind of input.

A row says everything the node (``ros/controller_inputs.py``), the offline input-bag reader
(``recording/inputs.py``) and the offline run loop (``simulation/runner.py``) need to know of
one kind: its topic (relative name; ``{i}`` = the 1-based vehicle of a per-vehicle kind),
message type and the field that carries the value, the rule that refuses a value (one rule
for the node and the offline replay, counted per reason), the simulator setter it calls, the
vehicles that take it on a given train, the fail-safe when it goes stale, the lock-step
family that waits for it, whether its message is stamped (a lock-step answer matched by its
header stamp) and the text of the generated inputs table of ``docs/ros_interface.md``
(``python -m train_dynamics.input_kinds``).

Adding a controller input: a row here (and the simulator setter it calls, if new). The
node subscribes to it, validates, records, supervises and dispatches it; the offline command
reads it from an input bag and applies it at its bag time; the docs table lists it.

Layering: topic names and message types (not in ``physics/``); no rclpy, no rosbags (the
node decodes with rclpy, the bag reader with rosbags, both by the row's ``field``). The
simulator is reached only through its setters (duck typing), so the physics layer does not
know this table.
"""
from __future__ import annotations

from dataclasses import dataclass, field as dc_field
import math
import re
from typing import Any, Callable

from train_dynamics import topics
from train_dynamics.physics.ed_force import ed_force_rejection

Why = tuple[str, str] | None


# -- value rules: (value as the message carries it, run config) -> (reason, detail) | None ---
def pressure_rejection(absolute: float, cfg: Any = None) -> Why:
    """
    Return (reason, detail) if a brake-input ABSOLUTE pressure [Pa] is refused, else None.

    ``non_finite`` (NaN, +-inf), ``negative`` (< 0), ``too_high`` (>
    :data:`train_dynamics.topics.MAX_ABSOLUTE_PRESSURE`, 20 bar: implausible for a brake pipe
    or cylinder).
    """
    p = float(absolute)
    if not math.isfinite(p):
        return 'non_finite', f'pressure {p}'
    if p < 0.0:
        return 'negative', f'absolute pressure {p:g} Pa < 0'
    if p > topics.MAX_ABSOLUTE_PRESSURE:
        return 'too_high', (f'absolute pressure {p:g} Pa > '
                            f'{topics.MAX_ABSOLUTE_PRESSURE:g} Pa')
    return None


def _fraction_rule(low: float, high: float, what: str) -> Callable[[float, Any], Why]:
    """Return the rule of a command that is a fraction in [``low``, ``high``]."""
    def rule(value: float, cfg: Any = None) -> Why:
        c = float(value)
        if not math.isfinite(c):
            return 'non_finite', f'command {c}'
        if not low <= c <= high:
            return 'out_of_range', f'{what}{c:g} outside [{low:g}, {high:g}]'
        return None
    return rule


#: ``coach_<i>/traction/command``: > 0 traction, < 0 dynamic brake, a fraction in [-1, 1]
traction_rejection = _fraction_rule(-1.0, 1.0, 'command ')
#: ``brake_ep/command``: a fraction of full service in [0, 1]
ep_rejection = _fraction_rule(0.0, 1.0, 'EP command ')


def wsp_rejection(state: int, cfg: Any = None) -> Why:
    """Return (reason, detail) if a valve state (0 normal, 1 hold, 2 vent) is refused."""
    if int(state) not in (0, 1, 2):
        return 'out_of_range', f'valve state {int(state)} not 0 (normal), 1 (hold) or 2 (vent)'
    return None


def ed_force_rule(value: float, cfg: Any = None) -> Why:
    """Return (reason, detail) if an ED force command [N] is refused (finite, >= 0)."""
    why = ed_force_rejection(float(value))
    return None if why is None else (why, f'ED force {float(value):g} N (finite, >= 0)')


def _demand_rule(value: float, cfg: Any) -> Why:
    """``brake_demand``: finite, >= 0, and <= 1 when ``brake_demand_mode`` is fraction."""
    v = float(value)
    if not math.isfinite(v):
        return 'non_finite', f'{topics.BRAKE_DEMAND_TOPIC} {v}'
    if v < 0.0 or (cfg.brake_demand_mode == 'fraction' and v > 1.0):
        return 'out_of_range', f'{topics.BRAKE_DEMAND_TOPIC} {v:g}'
    return None


def _finite_rule(topic: str) -> Callable[[float, Any], Why]:
    def rule(value: float, cfg: Any = None) -> Why:
        v = float(value)
        return None if math.isfinite(v) else ('non_finite', f'{topic} {v}')
    return rule


# -- who takes a kind on a train: (run config) -> 0-based vehicles ([0] for a train-wide) ----
def _brake_mode(mode: str) -> Callable[[Any], list[int]]:
    def takes(cfg: Any) -> list[int]:
        if cfg.brake_input != mode:
            return []
        return [0] if mode == topics.PIPE_HEAD else list(range(int(cfg.n_coaches)))
    return takes


def locomotives(cfg: Any) -> list[int]:
    """Return the vehicles that take a traction command (locomotives, remotes excepted)."""
    return list(cfg.consist.commanded) if cfg.external_forces else []


def motor_cars(cfg: Any) -> list[int]:
    """Return the motor cars (0-based) that take ED force commands (``blending: external``)."""
    if cfg.blending != 'external':
        return []
    consist = cfg.consist
    force = consist.fields['max_dynamic_brake_force']
    return [i for i in consist.commanded if force[i] > 0.0]


def _blending_builtin(cfg: Any) -> list[int]:
    return [0] if cfg.blending == 'builtin' else []


def _nominal_pipe(cfg: Any) -> float:
    return float(cfg.pipe_nominal_pressure)


# -- the simulator setters: (simulator, value in the simulator's units, 0-based vehicle) -----
def _set_head(sim: Any, value: Any, index: Any) -> None:
    sim.set_head_pipe_pressure(value)


def _set_ed_force(sim: Any, value: Any, index: int) -> None:
    sim.ed_force.set_force(float(value), index)


def _bcu(sim: Any, topic: str) -> Any:
    if sim.bcu is None:
        raise ValueError(f'{topic} needs blending builtin')
    return sim.bcu


@dataclass(frozen=True)
class InputKind:
    """
    One kind of controller input (see the module).

    ``apply(sim, value, index)`` hands a value (after ``to_sim``) to the simulator;
    ``index`` is the 0-based vehicle of a per-vehicle kind (None: all vehicles at once, the
    value an array, where the setter allows it), 0 for a train-wide kind. ``takes(cfg)``:
    the vehicles that take the kind on ``cfg``'s train (train-wide: ``[0]`` or ``[]``).
    ``on_stale`` (``input_timeout`` > 0 s wall after a first value): ``policy`` (the
    fail-safe with ``on_input_timeout`` emergency, else hold), ``failsafe`` (always),
    ``line`` (the EP / ECP train line is lost until the next value), ``''`` (not supervised).
    ``family`` ``''``: no lock-step period waits for the kind (its values act when they
    arrive). ``stamped``: the message has a ``header`` and answers the lock-step output of
    its stamp (an unstamped one answers the latest output published before it arrived).
    """

    name: str
    topic: str                       # relative; '{i}': the 1-based vehicle
    msgtype: str
    field: str                       # the message's field that carries the value
    rule: Callable[[Any, Any], Why]  # (value as carried, cfg) -> (reason, detail) | None
    reasons: tuple[str, ...]         # what ``rule`` may answer
    apply: Callable[[Any, Any, Any], None]
    takes: Callable[[Any], list[int]]
    family: str                      # lock-step family (``lockstep_inputs``); '': none
    label: str                       # how the log names one
    meaning: str                     # docs: what the value is
    when: str                        # docs: when the node subscribes to it
    failsafe: Any = None             # value applied when stale (``on_stale`` policy/failsafe)
    on_stale: str = ''
    stamped: bool = False
    integer: bool = False            # the value is an integer (Int8 ...)
    to_sim: Callable[[float, Any], float] | None = None   # message value -> simulator value
    initial: Callable[[Any], float] | float = 0.0         # the value before any message
    #: a vehicle in the train that does not take it: the reason its messages are refused
    #: (the node's graph scan subscribes to such topics to count them); '' = not scanned
    idle_reason: str = ''
    pattern: re.Pattern = dc_field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        """Compile the topic pattern: group 1 = the vehicle number of a per-vehicle kind."""
        rx = re.escape(self.topic).replace(re.escape('{i}'), r'(\d+)')
        object.__setattr__(self, 'pattern', re.compile(rx))

    @property
    def per_vehicle(self) -> bool:
        """Return True for a kind with one topic per vehicle (``coach_<i>/...``)."""
        return '{i}' in self.topic

    @property
    def display(self) -> str:
        """Return the topic as the docs and messages name it (``coach_<i>/...``)."""
        return self.topic.format(i='<i>')

    def topic_of(self, index: int) -> str:
        """Return the topic of vehicle ``index`` (0-based; any index of a train-wide kind)."""
        return self.topic.format(i=index + 1) if self.per_vehicle else self.topic

    def value(self, msg: Any) -> Any:
        """Return the value a decoded message carries (rclpy's or rosbags' message)."""
        v = getattr(msg, self.field)
        return int(v) if self.integer else float(v)

    def sim_value(self, value: Any, cfg: Any) -> Any:
        """Return a message value in the simulator's units (e.g. absolute -> gauge Pa)."""
        return value if self.to_sim is None else self.to_sim(value, cfg)

    def initial_value(self, cfg: Any) -> float:
        """Return the value the simulator holds before any message."""
        return self.initial(cfg) if callable(self.initial) else self.initial


def _gauge(absolute: float, cfg: Any) -> float:
    return absolute - float(cfg.atmospheric_pressure)


_PRESSURE: dict[str, Any] = {
    'msgtype': topics.FLUID_PRESSURE, 'field': 'fluid_pressure', 'rule': pressure_rejection,
    'reasons': ('non_finite', 'negative', 'too_high'), 'family': 'brake', 'stamped': True,
    'to_sim': _gauge, 'on_stale': 'policy'}
_FLOAT: dict[str, Any] = {'msgtype': topics.FLOAT64, 'field': 'data'}
_FRACTION = ('non_finite', 'out_of_range')

#: every kind of controller input, in the order the node applies the commands of an instant
#: (the brake pressures after them; offline, the brake events before them)
INPUT_KINDS: tuple[InputKind, ...] = (
    InputKind(topics.PIPE_HEAD, topics.HEAD_PIPE_TOPIC, apply=_set_head,
              takes=_brake_mode(topics.PIPE_HEAD), label='brake input', failsafe=0.0,
              initial=_nominal_pipe,
              meaning='brake-pipe pressure at the head of the train, ABSOLUTE [Pa] (the '
                      "driver's brake valve or a brake controller); the node propagates it "
                      'along the pipe', when='`brake_input: pipe_head` (default)', **_PRESSURE),
    InputKind(topics.PIPE_PER_COACH, topics.COACH_INPUT_TOPIC[topics.PIPE_PER_COACH],
              apply=lambda sim, v, i: sim.set_pipe_pressure(v, i),
              takes=_brake_mode(topics.PIPE_PER_COACH), label='brake input', failsafe=0.0,
              initial=_nominal_pipe,
              meaning='local brake-pipe pressure at vehicle i, ABSOLUTE [Pa]',
              when='`brake_input: pipe_per_coach`', **_PRESSURE),
    InputKind(topics.CYLINDER_PER_COACH, topics.COACH_INPUT_TOPIC[topics.CYLINDER_PER_COACH],
              apply=lambda sim, v, i: sim.set_cylinder_pressure(v, i),
              takes=_brake_mode(topics.CYLINDER_PER_COACH), label='brake input',
              failsafe=lambda cfg: float(cfg.max_cylinder_pressure),
              meaning='brake-cylinder pressure of vehicle i, ABSOLUTE [Pa], used directly in '
                      'eq. 13', when='`brake_input: cylinder_per_coach`', **_PRESSURE),
    InputKind('traction', topics.TRACTION_TOPIC, **_FLOAT, rule=traction_rejection,
              reasons=_FRACTION, apply=lambda sim, v, i: sim.set_traction_command(v, i),
              takes=locomotives, family='traction', label='traction command',
              failsafe=0.0, on_stale='policy', idle_reason='not_locomotive',
              meaning='fraction of the force available at the present speed in [-1, 1]: > 0 '
                      'traction, < 0 dynamic brake', when='each locomotive (not the remotes)'),
    InputKind('ep', topics.EP_COMMAND_TOPIC, **_FLOAT, rule=ep_rejection, reasons=_FRACTION,
              apply=lambda sim, v, i: sim.set_ep_command(v), takes=lambda cfg: (
                  [0] if cfg.ep_commanded else []), family='ep', label='EP command',
              on_stale='line',
              meaning='fraction of full service in [0, 1] that every EP valve / car control '
                      'device follows; stale: the train line is lost',
              when='`brake_system` ep or ecp'),
    InputKind('wsp', topics.WSP_VALVE_TOPIC, msgtype=topics.INT8, field='data',
              rule=wsp_rejection, reasons=('out_of_range',), integer=True,
              apply=lambda sim, v, i: sim.set_wsp_valve(int(v), i),
              takes=lambda cfg: list(range(int(cfg.n_coaches))) if cfg.wsp == 'external'
              else [], family='wsp', label='wsp valve', failsafe=0, on_stale='failsafe',
              meaning="0 normal, 1 hold, 2 vent: the valves on vehicle i's brake cylinder; "
                      'stale: 0', when='`wsp: external`, every vehicle'),
    InputKind('ed_force', topics.ED_FORCE_TOPIC, **_FLOAT, rule=ed_force_rule,
              reasons=_FRACTION, apply=_set_ed_force, takes=motor_cars, family='blending',
              label='ED force command',
              meaning='ED brake force [N, >= 0] commanded of motor car i',
              when='`blending: external`, each motor car'),
    InputKind('demand', topics.BRAKE_DEMAND_TOPIC, **_FLOAT, rule=_demand_rule,
              reasons=_FRACTION, takes=_blending_builtin, family='blending',
              apply=lambda sim, v, i: _bcu(sim, topics.BRAKE_DEMAND_TOPIC).set_demand(v),
              label='brake demand',
              meaning='train-wide brake demand: a fraction of full service in [0, 1] or a '
                      'deceleration [m/s^2] (`brake_demand_mode`)',
              when='`blending: builtin`'),
    InputKind('emergency', topics.BRAKE_EMERGENCY_TOPIC, **_FLOAT,
              rule=_finite_rule(topics.BRAKE_EMERGENCY_TOPIC), reasons=('non_finite',),
              takes=_blending_builtin, family='blending', label='emergency brake',
              apply=lambda sim, v, i: _bcu(sim, topics.BRAKE_EMERGENCY_TOPIC).set_emergency(
                  v >= 0.5),
              meaning='emergency brake, bypassing the blending: >= 0.5 applied, < 0.5 released',
              when='`blending: builtin`'),
    InputKind('ed_trip', topics.ED_TRIP_TOPIC, **_FLOAT, rule=_finite_rule(topics.ED_TRIP_TOPIC),
              reasons=('non_finite',), takes=_blending_builtin, family='blending',
              label='ED trip',
              apply=lambda sim, v, i: _bcu(sim, topics.ED_TRIP_TOPIC).set_ed_trip(v >= 0.5),
              meaning='the ED brake of every motor car lost (line breaker trip): >= 0.5 '
                      'tripped, < 0.5 restored', when='`blending: builtin`'),
    InputKind('track_brake', 'track_brake/command', **_FLOAT,
              rule=_finite_rule('track_brake/command'), reasons=('non_finite',),
              takes=_blending_builtin, family='', label='track brake command',
              apply=lambda sim, v, i: sim.bcu.track.set_applied(v >= 0.5 or sim.bcu.emergency),
              meaning='the magnetic track and eddy-current brakes of every car that has them '
                      '(`track_brake_force`, `eddy_brake_force`) applied without the '
                      'emergency brake: >= 0.5 applied (acting after `track_brake_delay`), '
                      '< 0.5 released (not while the emergency brake is applied)',
              when='`blending: builtin`'),
)

#: name -> row
KINDS: dict[str, InputKind] = {k.name: k for k in INPUT_KINDS}
#: the brake-input kinds (``brake_input`` modes: one is active per run)
BRAKE_KINDS = tuple(k for k in INPUT_KINDS if k.family == 'brake')
#: the command kinds (every one whose ``takes`` is not empty is active)
COMMAND_KINDS = tuple(k for k in INPUT_KINDS if k.family != 'brake')
#: lock-step family -> why a train has no input of it (``lockstep_inputs`` refused)
FAMILY_NEEDS = {'traction': 'no locomotive takes traction commands',
                'ep': 'brake_system is neither ep nor ecp',
                'wsp': 'wsp is not external',
                'blending': 'blending is neither builtin nor external with motor cars'}


def family_active(family: str, cfg: Any) -> bool:
    """Return True if ``cfg``'s train has an input of lock-step ``family``."""
    return family == 'brake' or any(k.takes(cfg) for k in INPUT_KINDS if k.family == family)


def failsafe_value(kind: InputKind, cfg: Any) -> Any:
    """Return the fail-safe value of ``kind`` on ``cfg``'s train."""
    return kind.failsafe(cfg) if callable(kind.failsafe) else kind.failsafe


def match(rel: str) -> tuple[InputKind, int | None] | None:
    """Return (kind, 0-based vehicle or None) of a relative topic name, None if no input."""
    for kind in INPUT_KINDS:
        m = kind.pattern.fullmatch(rel)
        if m is not None:
            return kind, (int(m.group(1)) - 1 if m.groups() else None)
    return None


def markdown_table() -> str:
    """Return the inputs table of docs/ros_interface.md (``python -m`` this module)."""
    lines = ['| topic | type | when | meaning | refused | lock-step | stale |',
             '| --- | --- | --- | --- | --- | --- | --- |']
    stale = {'policy': 'fail-safe {f} with `on_input_timeout: emergency`, else hold',
             'failsafe': 'fail-safe {f}', 'line': 'train line lost', '': 'held'}
    for k in INPUT_KINDS:
        f = ('`max_cylinder_pressure`' if callable(k.failsafe)
             else f'{k.failsafe:g}' if k.failsafe is not None else '')
        lines.append(f'| `{k.display}` | `{k.msgtype}` | {k.when} | {k.meaning} | '
                     f'{", ".join(k.reasons)} | '
                     f'{f"`{k.family}`" if k.family else "not waited for"}'
                     f'{" (header stamp)" if k.stamped else ""} | '
                     f'{stale[k.on_stale].format(f=f)} |')
    return '\n'.join(lines)


if __name__ == '__main__':   # python -m train_dynamics.input_kinds: the docs' table
    print(markdown_table())
