"""
The brake control unit's inputs read from a rosbag2 (``blending: builtin``).

``brake_demand``, ``brake_emergency``, ``ed_brake/trip`` (std_msgs/Float64; a leading '/'
and a namespace prefix accepted): a message takes effect at its bag time relative to the
bag's first message, as the other inputs of :mod:`train_dynamics.recording.inputs`. Values
are refused by the node's rule (:func:`~train_dynamics.simulation.demand.blending_rejection`),
counted and reported through ``warn``.
"""
from __future__ import annotations

from collections.abc import Callable
import logging
from typing import Any

from train_dynamics import topics
from train_dynamics.recording.bags import bag_info, BagError, read_topics
from train_dynamics.recording.inputs import InputBagError
from train_dynamics.simulation.demand import BLENDING_INDEX, blending_rejection, BLENDING_TOPICS
from train_dynamics.simulation.runner import step_of, TractionEvent

_log = logging.getLogger(__name__)


def read_blending_bag(path: str, cfg: Any, *, namespace: str = '',
                      warn: Callable[[str], None] = _log.warning) -> list[TractionEvent]:
    """Return the brake control unit's inputs in the bag at ``path`` (empty: none)."""
    ns = namespace.strip('/')
    try:
        info = bag_info(path)
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    kinds = {t: k for k, t in BLENDING_TOPICS.items()}
    selected: dict[str, str] = {}
    for topic, (msgtype, _) in info.topics.items():
        rel = topic.lstrip('/')
        if ns:
            if not rel.startswith(ns + '/'):
                continue
            rel = rel[len(ns) + 1:]
        if rel not in kinds:
            continue
        if msgtype != topics.FLOAT64:
            warn(f'input bag: {topic} has type {msgtype}, not {topics.FLOAT64}; ignored')
        elif cfg.blending != 'builtin':
            warn(f'input bag: {topic}: needs blending builtin; ignored')
        else:
            selected[topic] = kinds[rel]
    h = float(cfg.integration_step)
    events: list[TractionEvent] = []
    rejected = 0
    try:
        for topic, t_ns, msg in read_topics(path, list(selected)):
            kind, value = selected[topic], float(msg.data)
            if blending_rejection(kind, value, cfg) is not None:
                rejected += 1
                continue
            rel_ns = t_ns - info.start_ns
            events.append(TractionEvent(step_of(rel_ns, h), rel_ns, BLENDING_INDEX, value,
                                        BLENDING_TOPICS[kind], msg, kind=kind))
    except BagError as exc:
        raise InputBagError(f'input bag: {exc}') from None
    if rejected:
        warn(f'input bag: {rejected} brake demand / emergency / ED trip value(s) not finite or '
             'out of range rejected')
    return sorted(events, key=lambda e: e.t_ns)
