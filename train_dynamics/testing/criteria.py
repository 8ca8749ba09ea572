"""
Acceptance criteria of a scenario file, checked against a run's metrics.

A criterion names a metric of ``train-dynamics report`` (a key of ``summary.json``'s
``train``: ``stopping_distance`` [m], ``max_compression`` and ``max_tension`` [N, positive],
``max_jerk`` [m/s^3], ``max_deceleration`` [m/s^2], ``stopped``, ``blocking_count``, ...) and
bounds it: ``{max: X}``, ``{min: X}``, both, or ``{equals: X}``. A metric the run did not
produce (None, or absent, e.g. ``stopping_distance`` of a train that did not stop) fails the
criterion and says so.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Any, Mapping

from train_dynamics.physics.config import ConfigError

BOUNDS = ('min', 'max', 'equals')


@dataclass(frozen=True)
class CriterionResult:
    """The verdict on one criterion: ``passed``, the value, and a line saying why."""

    criterion: Criterion
    value: Any
    passed: bool
    text: str


@dataclass(frozen=True)
class Criterion:
    """A bound on one run metric: ``low <= value <= high``, or ``value == equals``."""

    metric: str
    low: float | None = None
    high: float | None = None
    equals: Any = None

    @classmethod
    def parse(cls, metric: str, spec: Any) -> Criterion:
        """Return the criterion of a scenario file's ``metric: {max: X, ...}``."""
        if not isinstance(spec, Mapping) or not spec or set(spec) - set(BOUNDS):
            raise ConfigError(f'criterion {metric}: expected a mapping of {", ".join(BOUNDS)}, '
                              f'got {spec!r}')
        return cls(metric, low=_number(metric, spec.get('min')),
                   high=_number(metric, spec.get('max')), equals=spec.get('equals'))

    def describe(self) -> str:
        """Return e.g. ``stopping_distance <= 120``."""
        if self.equals is not None:
            return f'{self.metric} == {self.equals!r}'
        parts = ([f'{self.low:g} <='] if self.low is not None else []) + [self.metric] + \
            ([f'<= {self.high:g}'] if self.high is not None else [])
        return ' '.join(parts)

    def check(self, metrics: Mapping[str, Any]) -> CriterionResult:
        """Return the verdict on ``metrics`` (a run's ``summary.json`` ``train``)."""
        value = metrics.get(self.metric)
        if value is None:
            return CriterionResult(self, None, False,
                                   f'FAIL {self.describe()}: the run has no {self.metric}')
        if self.equals is not None:
            ok = value == self.equals
        else:
            ok = isinstance(value, (int, float)) and math.isfinite(value) and \
                (self.low is None or value >= self.low) and \
                (self.high is None or value <= self.high)
        shown = f'{value:.6g}' if isinstance(value, float) else repr(value)
        return CriterionResult(self, value, ok,
                               f'{"pass" if ok else "FAIL"} {self.describe()}: {shown}')


def _number(metric: str, value: Any) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'criterion {metric}: bound {value!r} is not a number')
    return float(value)


def parse_criteria(spec: Any) -> list[Criterion]:
    """Return the criteria of a scenario file's ``criteria:`` mapping (metric -> bounds)."""
    if spec is None:
        return []
    if not isinstance(spec, Mapping):
        raise ConfigError(f'criteria: expected a mapping metric -> bounds, got {spec!r}')
    return [Criterion.parse(str(metric), bounds) for metric, bounds in spec.items()]
