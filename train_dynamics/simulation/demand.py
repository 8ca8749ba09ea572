"""
The parameter file's schedule of the brake control unit's inputs (``blending: builtin``).

Demand, emergency, ED trip are rows ``demand``, ``emergency``, ``ed_trip`` of the input table
(:data:`train_dynamics.input_kinds.KINDS`: topics, rules, setters). Offline they come from
an input bag (:mod:`train_dynamics.recording.inputs`) or from the parameter file's
``demand_schedule_*``, ``emergency_schedule_time``, ``ed_trip_schedule_time`` read here.
"""
from __future__ import annotations

from typing import Any


def blending_schedule(cfg: Any) -> list[tuple[int, str, float]]:
    """Return the scheduled inputs of the parameter file: (t [ns], kind, value), in order."""
    out = [(int(round(t * 1e9)), 'demand', float(v))
           for t, v in zip(cfg.demand_schedule_times, cfg.demand_schedule_values)]
    if cfg.emergency_schedule_time >= 0.0:
        out.append((int(round(cfg.emergency_schedule_time * 1e9)), 'emergency', 1.0))
    if cfg.ed_trip_schedule_time >= 0.0:
        out.append((int(round(cfg.ed_trip_schedule_time * 1e9)), 'ed_trip', 1.0))
    return sorted(out, key=lambda e: e[0])
