"""
The parameter description format (:class:`ParamSpec`) and its one validator (:func:`check_value`).

Every parameter of the simulator and of ``sim_node`` (:mod:`~train_dynamics.physics.config.table`)
and of the brake valve is declared as a :class:`ParamSpec`; the nodes build their ROS 2
parameter descriptors from it and every value, from whichever source (parameter file, ``ros2
param set``, consist file, sweep file), goes through :func:`check_value`. Never imports rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass
import itertools
import math
from typing import Any

from train_dynamics.quoting import quote

# Kinds of value, named after the ROS 2 parameter types they map to.
DOUBLE = 'double'
INTEGER = 'integer'
STRING = 'string'
BOOL = 'bool'
DOUBLE_ARRAY = 'double_array'
STRING_ARRAY = 'string_array'
ARRAY_KINDS = (DOUBLE_ARRAY, STRING_ARRAY)

#: how a per-vehicle field joins two vehicles into one coupler (see config.consist)
SERIES = 'series'   # the two ends' springs in series: compliances add, k_a k_b / (k_a + k_b)
ADDED = 'added'     # the two ends' travels add: a + b

#: the most values an array parameter may hold (checked before any value is looked at)
MAX_ITEMS = 100_000


class ConfigError(ValueError):
    """A parameter value or a parameter file that cannot be used; the message says why."""


@dataclass(frozen=True)
class ParamSpec:
    """
    Declaration of one parameter: what ``ros2 param describe`` shows.

    ``dynamic``: the value may change while the node runs and acts at once; otherwise it is
    structural (``sim_node`` keeps it pending until the ``reset`` service).
    ``file_input``: the value names a file to read (relative: the path rule of
    :mod:`~train_dynamics.physics.config.files`).
    ``vehicle``: the field of a consist's vehicle this parameter is the default of (its name
    in a consist file), '' when not per vehicle; ``connection``: how the field of two
    vehicle ends makes the value of the coupling between them (:data:`SERIES`,
    :data:`ADDED`), '' when it is no coupling constant; ``row``: the name of the
    per-vehicle constant row of the kernel (``layout.VEHICLE``) that holds the field's value
    of each vehicle as is, '' when the kernel has no such row. A per-vehicle field is this one
    declaration: the consist field list, the docs' tables, the kernel row and the copy into
    it are derived from it.
    """

    name: str
    default: Any
    kind: str
    description: str
    low: float | None = None          # lower bound, inclusive unless low_exclusive
    high: float | None = None         # upper bound, inclusive
    low_exclusive: bool = False
    choices: tuple[str, ...] = ()
    dynamic: bool = False
    file_input: bool = False
    vehicle: str = ''
    connection: str = ''
    row: str = ''
    max_items: int = MAX_ITEMS
    min_items: int = 0

    def bounds(self) -> list[str]:
        """Return the numeric range in words, e.g. ``['> 0', '<= 1e+07']`` (docs, descriptors)."""
        words = []
        if self.low is not None:
            words.append(('> ' if self.low_exclusive else '>= ') + f'{self.low:g}')
        if self.high is not None:
            words.append(f'<= {self.high:g}')
        return words


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def check_value(spec: ParamSpec, value: Any) -> Any:
    """
    Check one value of the parameter ``spec`` declares; return it normalised.

    Integers become floats for doubles, arrays become lists. Raises :class:`ConfigError`
    with a one-line reason.
    """
    name, kind = spec.name, spec.kind
    if kind in (DOUBLE, INTEGER):
        return _check_number(spec, value, name)
    if kind == BOOL:
        if not isinstance(value, bool):
            raise ConfigError(f'{name}: expected true or false, got {quote(value)}')
        return value
    if kind == STRING:
        if not isinstance(value, str):
            raise ConfigError(f'{name}: expected a string, got {type(value).__name__} '
                              f'{quote(value)}')
        if spec.choices and value not in spec.choices:
            raise ConfigError(f'{name}: {quote(value)} is not one of {", ".join(spec.choices)}')
        return value
    if kind in ARRAY_KINDS:
        if isinstance(value, (str, bytes)) or not hasattr(value, '__iter__'):
            what = 'numbers' if kind == DOUBLE_ARRAY else 'strings'
            raise ConfigError(f'{name}: expected a list of {what}, got {quote(value)}')
        count = len(value) if hasattr(value, '__len__') else None
        if count is None:       # an iterator: look at one value more than the limit at most
            value = list(itertools.islice(value, spec.max_items + 1))
            count = len(value)
        if count > spec.max_items:
            raise ConfigError(f'{name}: {count} values, more than the limit of '
                              f'{spec.max_items}')
        if count < spec.min_items:
            raise ConfigError(f'{name}: {count} values, at least {spec.min_items} needed')
        if kind == STRING_ARRAY:
            items = [_check_string(item, f'{name}[{k}]') for k, item in enumerate(value)]
            if spec.choices:        # a set of choices: each one at most once
                for k, item in enumerate(items):
                    if item not in spec.choices:
                        raise ConfigError(f'{name}[{k}]: {quote(item)} is not one of '
                                          f'{", ".join(spec.choices)}')
                    if item in items[:k]:
                        raise ConfigError(f'{name}[{k}]: {quote(item)} given twice')
            return items
        return [_check_number(spec, item, f'{name}[{k}]') for k, item in enumerate(value)]
    raise AssertionError(kind)


def _check_string(value: Any, label: str) -> str:
    if not isinstance(value, str):
        raise ConfigError(f'{label}: expected a string, got {quote(value)}')
    return value


def _check_number(spec: ParamSpec, value: Any, label: str) -> float | int:
    """Check a number of ``spec`` (an element for a double array), range included."""
    if spec.kind == INTEGER:
        if not isinstance(value, int) or isinstance(value, bool):
            raise ConfigError(f'{label}: expected an integer, got {type(value).__name__} '
                              f'{quote(value)}')
        value = int(value)
        if value.bit_length() > 63:      # (also: %g of it would overflow)
            raise ConfigError(f'{label}: out of range, got {quote(value)}')
    elif not _is_number(value):
        if spec.kind == DOUBLE_ARRAY:
            raise ConfigError(f'{label}: expected a number, got {quote(value)}')
        raise ConfigError(f'{label}: expected a number, got {type(value).__name__} {quote(value)}')
    else:
        try:
            value = float(value)
        except OverflowError:           # an integer beyond the floats
            raise ConfigError(f'{label}: must be finite, got {quote(value)}') from None
    _check_range(spec, value, label)
    return value


def _check_range(spec: ParamSpec, value: float, label: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f'{label}: must be finite, got {value}')
    if spec.low is not None:
        if spec.low_exclusive and not value > spec.low:
            raise ConfigError(f'{label}: must be > {spec.low:g}, got {value:g}')
        if not spec.low_exclusive and not value >= spec.low:
            raise ConfigError(f'{label}: must be >= {spec.low:g}, got {value:g}')
    if spec.high is not None and not value <= spec.high:
        raise ConfigError(f'{label}: must be <= {spec.high:g}, got {value:g}')
