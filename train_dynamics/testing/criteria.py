"""
Acceptance criteria of a scenario file, checked against a run's metrics.

A criterion names a metric of ``train-dynamics report`` (a key of ``summary.json``'s
``train``, :data:`METRICS`: ``stopping_distance`` [m], ``max_compression`` and ``max_tension``
[N, positive], ``max_jerk`` [m/s^3], ``max_deceleration`` [m/s^2], ``stopped``,
``blocking_count``, ...) or of its brake blending (``blending.<key>``, a key of
``summary.json``'s ``blending``, :data:`BLENDING_METRICS`: ``blending.friction_share``,
``blending.max_jerk``, ``blending.max_tracking_error``, ``blending.energy_regenerated``, ...;
the run's flat view is :func:`criteria_metrics`) and bounds it: ``{max: X}``, ``{min: X}``,
both (``min <= max``), or
``{equals: X}`` alone. Bounds are finite numbers; ``equals`` is ``true``/``false`` for the
yes/no metrics (:data:`BOOLEAN_METRICS`) and a finite number for the others. Anything else
is refused when the scenario is read (:class:`ConfigError` naming the criterion): a criterion
that could never fail, or never pass, tests nothing. A metric the run did not produce (None,
e.g. ``stopping_distance`` of a train that did not stop, or any ``blending.`` metric of a run
without blending) fails the criterion and says so.
"""
from __future__ import annotations

from dataclasses import dataclass
import difflib
import math
from typing import Any, Mapping

from train_dynamics.physics.config import ConfigError
from train_dynamics.physics.metrics import FLAT_KEYS, SLIDING_KEYS
from train_dynamics.quoting import quote
from train_dynamics.recording.blending_metrics import BLENDING_KEYS

BOUNDS = ('min', 'max', 'equals')
#: the section prefix of the blending metrics in a criterion's name
BLENDING = 'blending.'
#: the blending metrics a criterion may name: ``summary.json``'s ``blending`` keys
BLENDING_METRICS = tuple(BLENDING + key for key in BLENDING_KEYS)
#: the run metrics a criterion may name: ``summary.json``'s ``train`` keys, then blending's
METRICS = FLAT_KEYS + SLIDING_KEYS + BLENDING_METRICS
#: the metrics that are true or false (``equals`` only)
BOOLEAN_METRICS = ('stopped',)


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

    def __post_init__(self) -> None:
        """Refuse a criterion that cannot be meant (raises :class:`ConfigError`)."""
        name = f'criterion {self.metric}'
        if self.metric not in METRICS:
            close = difflib.get_close_matches(str(self.metric), METRICS, n=1)
            raise ConfigError(f'{name}: no such run metric'
                              + (f' (did you mean {close[0]}?)' if close else
                                 f' (known: {", ".join(METRICS)})'))
        for which, bound in (('min', self.low), ('max', self.high)):
            if bound is not None:
                _finite(name, which, bound)
        if self.equals is not None:
            if self.low is not None or self.high is not None:
                raise ConfigError(f'{name}: equals cannot be combined with min or max '
                                  '(give either equals or bounds)')
            if self.metric in BOOLEAN_METRICS:
                if not isinstance(self.equals, bool):
                    raise ConfigError(f'{name}: equals must be true or false, got '
                                      f'{quote(self.equals)}')
            else:
                _finite(name, 'equals', self.equals)
        elif self.low is None and self.high is None:
            raise ConfigError(f'{name}: no bound (give min, max or equals)')
        elif self.metric in BOOLEAN_METRICS:
            raise ConfigError(f'{name}: a true/false metric takes equals, not min or max')
        if self.low is not None and self.high is not None and self.low > self.high:
            raise ConfigError(f'{name}: min {self.low:g} > max {self.high:g}: no value passes')

    @classmethod
    def parse(cls, metric: str, spec: Any) -> Criterion:
        """Return the criterion of a scenario file's ``metric: {max: X, ...}``."""
        if not isinstance(spec, Mapping) or not spec or set(spec) - set(BOUNDS):
            raise ConfigError(f'criterion {metric}: expected a mapping of {", ".join(BOUNDS)}, '
                              f'got {quote(spec)}')
        for key in BOUNDS:
            if key in spec and spec[key] is None:
                raise ConfigError(f'criterion {metric}: {key}: null is no value')
        return cls(metric, low=spec.get('min'), high=spec.get('max'), equals=spec.get('equals'))

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
            ok = type(value) is type(self.equals) or (
                not isinstance(value, bool) and not isinstance(self.equals, bool))
            ok = ok and value == self.equals
        else:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and \
                math.isfinite(value) and \
                (self.low is None or value >= self.low) and \
                (self.high is None or value <= self.high)
        shown = f'{value:.6g}' if isinstance(value, float) else repr(value)
        return CriterionResult(self, value, ok,
                               f'{"pass" if ok else "FAIL"} {self.describe()}: {shown}')


def _finite(name: str, which: str, value: Any) -> None:
    """Refuse a bound that is not a finite number (true/false, text, NaN, infinity)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'{name}: {which} {quote(value)} is not a number')
    try:
        finite = math.isfinite(value)
    except OverflowError:
        finite = False
    if not finite:
        raise ConfigError(f'{name}: {which} {quote(value)} is not a finite number')


def criteria_metrics(summary: Mapping[str, Any]) -> dict[str, Any]:
    """
    Return the metrics criteria are checked against, from a ``summary.json`` document.

    ``summary``'s ``train`` as it is, and its ``blending`` section (when the run blends) as
    ``blending.<key>``.
    """
    out = dict(summary.get('train') or {})
    out.update({BLENDING + key: value
                for key, value in (summary.get('blending') or {}).items()})
    return out


def parse_criteria(spec: Any) -> list[Criterion]:
    """Return the criteria of a scenario file's ``criteria:`` mapping (metric -> bounds)."""
    if spec is None:
        return []
    if not isinstance(spec, Mapping):
        raise ConfigError(f'criteria: expected a mapping metric -> bounds, got {quote(spec)}')
    return [Criterion.parse(str(metric), bounds) for metric, bounds in spec.items()]
