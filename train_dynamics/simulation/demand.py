"""
The inputs of the brake control unit (``blending: builtin``): demand, emergency, ED trip.

Offline they are :class:`~train_dynamics.simulation.runner.TractionEvent` of index
:data:`BLENDING_INDEX` and kind ``demand``, ``emergency`` or ``ed_trip`` (std_msgs/Float64
on :data:`~train_dynamics.topics.BRAKE_DEMAND_TOPIC`, ``BRAKE_EMERGENCY_TOPIC``,
``ED_TRIP_TOPIC``): from an input bag (:mod:`train_dynamics.recording.demand_inputs`) or the
parameter file's ``demand_schedule_*``, ``emergency_schedule_time``, ``ed_trip_schedule_time``.
"""
from __future__ import annotations

from typing import Any

from train_dynamics import topics

#: TractionEvent.index of the brake control unit's inputs
BLENDING_INDEX = -2
#: kind -> topic of the brake control unit's inputs
BLENDING_TOPICS = {'demand': topics.BRAKE_DEMAND_TOPIC,
                   'emergency': topics.BRAKE_EMERGENCY_TOPIC,
                   'ed_trip': topics.ED_TRIP_TOPIC}


def apply_blending_input(sim: Any, kind: str, value: float) -> None:
    """Hand one input of ``kind`` to the brake control unit of ``sim`` (ValueError: none)."""
    bcu = sim.bcu
    if bcu is None:
        raise ValueError(f'{BLENDING_TOPICS[kind]} needs blending builtin')
    if kind == 'demand':
        bcu.set_demand(value)
    elif kind == 'emergency':
        bcu.set_emergency(value >= 0.5)
    else:
        bcu.set_ed_trip(value >= 0.5)


def blending_rejection(kind: str, value: float, cfg: Any) -> str | None:
    """Return why ``value`` of ``kind`` is refused ('non_finite', 'out_of_range'), else None."""
    if value != value or value in (float('inf'), float('-inf')):
        return 'non_finite'
    if kind == 'demand' and (value < 0.0 or (cfg.brake_demand_mode == 'fraction'
                                             and value > 1.0)):
        return 'out_of_range'
    return None


def blending_schedule(cfg: Any) -> list[tuple[int, str, float]]:
    """Return the scheduled inputs of the parameter file: (t [ns], kind, value), in order."""
    out = [(int(round(t * 1e9)), 'demand', float(v))
           for t, v in zip(cfg.demand_schedule_times, cfg.demand_schedule_values)]
    if cfg.emergency_schedule_time >= 0.0:
        out.append((int(round(cfg.emergency_schedule_time * 1e9)), 'emergency', 1.0))
    if cfg.ed_trip_schedule_time >= 0.0:
        out.append((int(round(cfg.ed_trip_schedule_time * 1e9)), 'ed_trip', 1.0))
    return sorted(out, key=lambda e: e[0])
