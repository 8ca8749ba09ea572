"""
Brake inputs read from a rosbag2: the events that drive an offline run.

:func:`read_input_bag` takes the contract's input topics of the run's ``brake_input`` mode
(:data:`train_dynamics.topics.INPUT_TOPIC_PATTERNS`; ``sensor_msgs/FluidPressure``, ABSOLUTE
[Pa]; a leading '/' and a namespace prefix are accepted) from an MCAP or sqlite3 bag. A
message takes effect at its bag time relative to the bag's first message, at the first
integration step starting at or after that time
(:func:`train_dynamics.simulation.runner.step_of`), and holds until the next one. Messages are
rejected by the node's rule (:func:`train_dynamics.physics.config.input_rejection`:
non-finite, negative or above 20 bar absolute), with a warning counting them per reason.
A ``pipe_head`` run whose bag has no brake-pipe input but commands the run can use (the EP /
ECP command of an EP train, traction, WSP valves, ED forces: :func:`read_traction_bag`) keeps
the pipe charged at ``pipe_nominal_pressure``, as ``sim_node`` holds it without a brake input
(with a warning); a bag with neither is refused.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
import logging
from pathlib import Path
from typing import Any

from train_dynamics import topics
from train_dynamics.physics.config import (ep_rejection, input_rejection, INPUT_VALUE_REASONS,
                                           traction_rejection, wsp_rejection)
from train_dynamics.physics.ed_force import ed_force_rejection, ed_motor_cars
from train_dynamics.recording.bags import bag_info, BagError, BagInfo, read_topics
from train_dynamics.simulation.runner import (EP_INDEX, InputEvent, InputSchedule, step_of,
                                              TractionEvent)

_log = logging.getLogger(__name__)


class InputBagError(ValueError):
    """An input bag with nothing usable for the run; the message is one line."""


def _quiet(text: str) -> None:
    """Drop a warning (the topics are named when they are read)."""


def read_input_bag(path: str, cfg: Any, *, namespace: str = '',
                   warn: Callable[[str], None] = _log.warning) -> InputSchedule:
    """
    Return the input events of ``cfg.brake_input`` in the bag at ``path``.

    Gauge pressure = absolute - ``cfg.atmospheric_pressure`` [Pa]; events sorted by time (bag
    order for equal times). Ignored topics and rejected messages are reported through
    ``warn``; :class:`InputBagError` if the bag is unreadable or holds no usable input.
    """
    mode = cfg.brake_input
    ns = namespace.strip('/')
    try:
        info = bag_info(path)
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    try:
        selected = _select_topics(info, mode, ns, int(cfg.n_coaches), warn, path)
    except InputBagError:
        if mode != topics.PIPE_HEAD or not any(_select_commands(info, cfg, ns, _quiet)):
            raise
        # commands only (e.g. brake_ep/command of an EP train): the pipe stays charged
        warn(f'input bag: no {topics.HEAD_PIPE_TOPIC} input: the brake pipe stays at '
             f'pipe_nominal_pressure ({float(cfg.pipe_nominal_pressure):g} Pa gauge), as '
             'sim_node holds it without one')
        return InputSchedule(mode, [], None, f'bag {Path(path).name} (commands only)')
    atm = float(cfg.atmospheric_pressure)
    h = float(cfg.integration_step)
    events: list[InputEvent] = []
    rejected = dict.fromkeys(INPUT_VALUE_REASONS, 0)
    try:
        for topic, t_ns, msg in read_topics(path, list(selected)):
            p = float(msg.fluid_pressure)
            why = input_rejection(p)
            if why is not None:
                rejected[why[0]] += 1
                continue
            rel_ns = t_ns - info.start_ns
            rel_topic = topic[len(ns) + 1:] if ns else topic
            events.append(InputEvent(step_of(rel_ns, h), rel_ns, selected[topic], p - atm,
                                     rel_topic, msg))
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    bad = rejected['non_finite'] + rejected['negative']
    if bad:
        warn(f'input bag: {bad} message(s) with a non-finite or negative absolute pressure '
             'rejected (as sim_node rejects them)')
    if rejected['too_high']:
        warn(f'input bag: {rejected["too_high"]} message(s) with an absolute pressure above '
             f'{topics.MAX_ABSOLUTE_PRESSURE:g} Pa rejected (too_high, as sim_node rejects '
             'them)')
    if not events:
        raise InputBagError(f'input bag {path}: no usable input message for brake_input {mode}')
    events.sort(key=lambda e: e.t_ns)           # stable: bag order for equal times
    return InputSchedule(mode, events, None, f'bag {Path(path).name}')


def read_traction_bag(path: str, cfg: Any, *, namespace: str = '',
                      warn: Callable[[str], None] = _log.warning) -> list[TractionEvent]:
    """
    Return the traction commands (``coach_<i>/traction/command``, Float64) in the bag.

    Only locomotives (vehicles with traction or dynamic brake) take a command; a value that is
    not finite or outside [-1, 1] is rejected by the node's rule
    (:func:`train_dynamics.physics.config.traction_rejection`; counted, reported through
    ``warn``). With an EP or ECP brake system, ``brake_ep/command`` too (index
    :data:`~train_dynamics.simulation.runner.EP_INDEX`, rule
    :func:`~train_dynamics.physics.config.ep_rejection`); with ``wsp: external`` every
    vehicle's ``coach_<i>/wsp/valve`` (Int8, kind ``wsp``, rule
    :func:`~train_dynamics.physics.config.wsp_rejection`). Empty when the bag has none.
    """
    ns = namespace.strip('/')
    try:
        info = bag_info(path)
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    selected, wsp, ed = _select_commands(info, cfg, ns, warn)
    h = float(cfg.integration_step)
    events: list[TractionEvent] = []
    rejected = 0
    try:
        for topic, t_ns, msg in read_topics(path, list(selected) + list(wsp) + list(ed)):
            if topic in wsp:
                if wsp_rejection(int(msg.data)) is not None:
                    rejected += 1
                    continue
                rel_ns = t_ns - info.start_ns
                i, j = wsp[topic]
                name = (topics.bogie_wsp_valve_topic(i + 1, j) if j
                        else topics.wsp_valve_topic(i + 1))
                events.append(TractionEvent(step_of(rel_ns, h), rel_ns, i, int(msg.data),
                                            name, msg, kind='wsp', bogie=j))
                continue
            c = float(msg.data)
            if topic in ed:
                if ed_force_rejection(c) is not None:
                    rejected += 1
                    continue
                rel_ns = t_ns - info.start_ns
                events.append(TractionEvent(step_of(rel_ns, h), rel_ns, ed[topic], c,
                                            topics.ed_force_topic(ed[topic] + 1), msg,
                                            kind='ed_force'))
                continue
            i = selected[topic]
            if (ep_rejection(c) if i == EP_INDEX else traction_rejection(c)) is not None:
                rejected += 1
                continue
            rel_ns = t_ns - info.start_ns
            name = topics.EP_COMMAND_TOPIC if i == EP_INDEX else topics.traction_topic(i + 1)
            events.append(TractionEvent(step_of(rel_ns, h), rel_ns, i, c, name, msg))
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    if rejected:
        warn(f'input bag: {rejected} traction, EP, WSP or ED force command(s) not finite or '
             'out of range rejected')
    events.sort(key=lambda e: e.t_ns)
    return events


def _select_commands(info: BagInfo, cfg: Any, ns: str, warn: Callable[[str], None]
                     ) -> tuple[dict[str, int], dict[str, tuple[int, int]], dict[str, int]]:
    """
    Return the bag's usable command topics: Float64 -> vehicle (EP_INDEX), Int8 WSP -> vehicle.

    Traction commands of locomotives, ``brake_ep/command`` with an EP / ECP brake system,
    ``coach_<i>/wsp/valve`` with ``wsp: external`` (-> (vehicle, 0)), and
    ``coach_<i>/bogie_<j>/wsp/valve`` with ``bogie_wheelsets`` too (-> (vehicle, j)), and
    the motor cars' ``coach_<i>/ed_brake/force`` with ``blending: external`` (the third
    mapping, -> motor car); the others are named through ``warn``.
    """
    locos = set(cfg.consist.commanded) if cfg.external_forces else set()
    selected: dict[str, int] = {}
    wsp: dict[str, tuple[int, int]] = {}
    ed: dict[str, int] = {}
    motors = set(ed_motor_cars(cfg))
    for topic, (msgtype, _) in info.topics.items():
        rel = topic[len(ns) + 1:] if ns and topic.startswith(ns + '/') else topic
        if rel == topics.EP_COMMAND_TOPIC and (rel != topic or not ns):
            if msgtype != topics.FLOAT64:
                warn(f'input bag: {topic} has type {msgtype}, not {topics.FLOAT64}; ignored')
            elif not cfg.ep_commanded:
                warn(f'input bag: {topic}: needs brake_system ep or ecp; ignored')
            else:
                selected[topic] = EP_INDEX
            continue
        w = (topics.WSP_VALVE_TOPIC_PATTERN.fullmatch(rel)
             or topics.BOGIE_WSP_VALVE_TOPIC_PATTERN.fullmatch(rel))
        if w is not None and not (ns and rel == topic):
            i = int(w.group(1)) - 1
            j = int(w.group(2)) if w.re.groups > 1 else 0
            if msgtype != topics.INT8:
                warn(f'input bag: {topic} has type {msgtype}, not {topics.INT8}; ignored')
            elif cfg.wsp != 'external' or not 0 <= i < cfg.n_coaches or (
                    j and not cfg.bogie_wheelsets):
                warn(f"input bag: {topic}: needs wsp external (a bogie's valve also "
                     f'bogie_wheelsets) and vehicle {i + 1} in the train; ignored')
            else:
                wsp[topic] = (i, j)
            continue
        e = topics.ED_FORCE_TOPIC_PATTERN.fullmatch(rel)
        if e is not None and not (ns and rel == topic):
            i = int(e.group(1)) - 1
            if msgtype != topics.FLOAT64:
                warn(f'input bag: {topic} has type {msgtype}, not {topics.FLOAT64}; ignored')
            elif i not in motors:
                warn(f'input bag: {topic}: needs blending external and vehicle {i + 1} a '
                     'motor car (an ED brake); ignored')
            else:
                ed[topic] = i
            continue
        m = topics.TRACTION_TOPIC_PATTERN.fullmatch(rel)
        if m is None or (ns and rel == topic):
            continue
        i = int(m.group(1)) - 1
        if msgtype != topics.FLOAT64:
            warn(f'input bag: {topic} has type {msgtype}, not {topics.FLOAT64}; ignored')
        elif i not in locos:
            warn(f'input bag: {topic}: vehicle {i + 1} is not a locomotive; ignored')
        else:
            selected[topic] = i
    return selected, wsp, ed


def _select_topics(info: BagInfo, mode: str, ns: str, n_coaches: int,
                   warn: Callable[[str], None], path: str) -> dict[str, int | None]:
    """Return the bag's usable input topics of ``mode`` -> 0-based coach (None: the head)."""
    pattern = topics.INPUT_TOPIC_PATTERNS[mode]
    selected: dict[str, int | None] = {}
    other_modes = []
    for topic, (msgtype, count) in info.topics.items():
        rel = topic
        if ns:
            if not topic.startswith(ns + '/'):
                continue
            rel = topic[len(ns) + 1:]
        m = pattern.fullmatch(rel)
        if m is None:
            if any(p.fullmatch(rel) for p in topics.INPUT_TOPIC_PATTERNS.values()):
                other_modes.append(rel)
            continue
        if msgtype != topics.FLUID_PRESSURE:
            warn(f'input bag: {topic} has type {msgtype}, not {topics.FLUID_PRESSURE}; ignored')
            continue
        if count == 0:
            continue
        index = None
        if m.groups():
            i = int(m.group(1))
            if not 1 <= i <= n_coaches:
                warn(f'input bag: {topic} names coach {i}, the train has coaches '
                     f'1..{n_coaches}; ignored')
                continue
            index = i - 1
        selected[topic] = index
    if not selected:
        hint = f' (it has {", ".join(sorted(other_modes))}: set brake_input to match)' \
            if other_modes else ''
        raise InputBagError(
            f'input bag {path}: no usable input topic for brake_input {mode}: needs '
            f'{topics.INPUT_TOPIC_DISPLAY[mode]} ({topics.FLUID_PRESSURE}){hint}')
    if mode != topics.PIPE_HEAD:
        have = set(selected.values())
        missing = [i + 1 for i in range(n_coaches) if i not in have]
        if missing:
            held = 'pipe_nominal_pressure' if mode == topics.PIPE_PER_COACH else '0 Pa'
            warn(f'input bag: no input for coach(es) {_ranges(missing)}; held at {held}')
    return selected


def _ranges(numbers: Sequence[int]) -> str:
    """Return sorted coach numbers as ranges: [1, 2, 3, 5] -> '1-3,5'."""
    out, start, prev = [], None, None
    for n in list(numbers) + [None]:
        if start is None:
            start = prev = n
        elif n is not None and n == prev + 1:
            prev = n
        else:
            out.append(str(start) if start == prev else f'{start}-{prev}')
            start = prev = n
    return ','.join(out)
