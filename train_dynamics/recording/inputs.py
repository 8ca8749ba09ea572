"""
Controller inputs read from a rosbag2: the events that drive an offline run.

Every kind of :data:`train_dynamics.input_kinds.INPUT_KINDS` is read by its row: topic,
message type, the field carrying the value, the node's rule refusing a value, the vehicles
that take it on the run's train. A leading '/' and a namespace prefix are accepted. A
message takes effect at its bag time relative to the bag's first message, at the first
integration step starting at or after that time
(:func:`train_dynamics.simulation.runner.step_of`), and holds until the next one.

:func:`read_input_bag`: the brake inputs of the run's ``brake_input`` mode
(``sensor_msgs/FluidPressure``, ABSOLUTE [Pa], gauge = absolute - ``atmospheric_pressure``;
refused: non-finite, negative or above 20 bar absolute, with a warning counting them per
reason). A ``pipe_head`` run whose bag has no brake-pipe input but commands the run can use
(:func:`read_command_bag`: the EP / ECP command, traction, WSP valves, the brake control
unit's inputs, ED forces) keeps the pipe charged at ``pipe_nominal_pressure``, as
``sim_node`` holds it without a brake input (with a warning); a bag with neither is refused.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
import logging
from pathlib import Path
from typing import Any

from train_dynamics import topics
from train_dynamics.input_kinds import BRAKE_KINDS, COMMAND_KINDS, InputKind, KINDS
from train_dynamics.recording.bags import bag_info, BagError, BagInfo, read_topics
from train_dynamics.simulation.runner import CommandEvent, InputSchedule, step_of

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
        if mode != topics.PIPE_HEAD or not _select_commands(info, cfg, ns, _quiet):
            raise
        # commands only (e.g. brake_ep/command of an EP train): the pipe stays charged
        warn(f'input bag: no {topics.HEAD_PIPE_TOPIC} input: the brake pipe stays at '
             f'pipe_nominal_pressure ({float(cfg.pipe_nominal_pressure):g} Pa gauge), as '
             'sim_node holds it without one')
        return InputSchedule(mode, [], None, f'bag {Path(path).name} (commands only)')
    kind = KINDS[mode]
    h = float(cfg.integration_step)
    events: list[CommandEvent] = []
    rejected = dict.fromkeys(kind.reasons, 0)
    try:
        for topic, t_ns, msg in read_topics(path, list(selected)):
            p = kind.value(msg)
            why = kind.rule(p, cfg)
            if why is not None:
                rejected[why[0]] += 1
                continue
            rel_ns = t_ns - info.start_ns
            rel_topic = topic[len(ns) + 1:] if ns else topic
            events.append(CommandEvent(mode, selected[topic], kind.sim_value(p, cfg), rel_ns,
                                       step_of(rel_ns, h), rel_topic, msg))
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


def read_command_bag(path: str, cfg: Any, *, namespace: str = '',
                     warn: Callable[[str], None] = _log.warning) -> list[CommandEvent]:
    """
    Return the commands (every kind but the brake inputs) in the bag, sorted by time.

    Only the vehicles that take a kind on this train (``InputKind.takes``: locomotives for
    traction, every vehicle with ``wsp: external`` ...) take its messages; the others are
    named through ``warn`` and ignored. A value the node's rule refuses is counted and
    reported through ``warn``. Empty when the bag has none.
    """
    ns = namespace.strip('/')
    try:
        info = bag_info(path)
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    selected = _select_commands(info, cfg, ns, warn)
    h = float(cfg.integration_step)
    events: list[CommandEvent] = []
    rejected: dict[str, int] = {}
    try:
        for topic, t_ns, msg in read_topics(path, list(selected)):
            kind, index = selected[topic]
            value = kind.value(msg)
            if kind.rule(value, cfg) is not None:
                rejected[kind.label] = rejected.get(kind.label, 0) + 1
                continue
            rel_ns = t_ns - info.start_ns
            events.append(CommandEvent.at(kind.name, index, kind.sim_value(value, cfg), rel_ns,
                                          h, msg))
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    if rejected:
        warn(f'input bag: {sum(rejected.values())} command(s) not finite or out of range '
             f'rejected ({", ".join(f"{k}: {n}" for k, n in rejected.items())}), as sim_node '
             'rejects them')
    events.sort(key=lambda e: e.t_ns)
    return events


def _relative(topic: str, ns: str) -> str | None:
    """Return a bag topic relative to the namespace ``ns`` ('' none), None outside it."""
    rel = topic.lstrip('/')
    if not ns:
        return rel
    return rel[len(ns) + 1:] if rel.startswith(ns + '/') else None


def _select_commands(info: BagInfo, cfg: Any, ns: str, warn: Callable[[str], None]
                     ) -> dict[str, tuple[InputKind, int | None]]:
    """
    Return the bag's usable command topics -> (kind, 0-based vehicle or None).

    A topic of a kind whose message type differs, or of a vehicle that does not take the
    kind on this train, is named through ``warn``.
    """
    takes = {k.name: set(k.takes(cfg)) for k in COMMAND_KINDS}
    selected: dict[str, tuple[InputKind, int | None]] = {}
    for topic, (msgtype, _) in info.topics.items():
        rel = _relative(topic, ns)
        if rel is None:
            continue
        for kind in COMMAND_KINDS:
            m = kind.pattern.fullmatch(rel)
            if m is None:
                continue
            index = int(m.group(1)) - 1 if kind.per_vehicle else None
            if msgtype != kind.msgtype:
                warn(f'input bag: {topic} has type {msgtype}, not {kind.msgtype}; ignored')
            elif (0 if index is None else index) not in takes[kind.name]:
                who = f'vehicle {index + 1} ' if index is not None else 'this train '
                warn(f'input bag: {topic}: {who}takes no {kind.label} ({kind.when}); ignored')
            else:
                selected[topic] = (kind, index)
            break
    return selected


def _select_topics(info: BagInfo, mode: str, ns: str, n_coaches: int,
                   warn: Callable[[str], None], path: str) -> dict[str, int | None]:
    """Return the bag's usable input topics of ``mode`` -> 0-based coach (None: the head)."""
    pattern = KINDS[mode].pattern
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
            if any(k.pattern.fullmatch(rel) for k in BRAKE_KINDS):
                other_modes.append(rel)
            continue
        if msgtype != KINDS[mode].msgtype:
            warn(f'input bag: {topic} has type {msgtype}, not {KINDS[mode].msgtype}; ignored')
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
            f'{KINDS[mode].display} ({KINDS[mode].msgtype}){hint}')
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
