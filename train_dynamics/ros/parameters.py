"""
ROS 2 parameters from :class:`~train_dynamics.physics.config.ParamSpec` tables.

One descriptor builder (:func:`descriptor`), one declaration (:func:`declare_parameters`) and
one set-callback scheme (:func:`watch_parameters`) for both nodes, following the ROS 2
parameter design: a pre-set callback converts what ``ros2 param set`` sends into the declared
type, the set callback VALIDATES ONLY (no side effects; every value through
:func:`~train_dynamics.physics.config.validate_value`, then the node's whole-batch check),
and the change is APPLIED by the post-set callback, after rclpy has stored the new values.
All three run on the executor thread (or the thread calling ``set_parameters``).
"""
from __future__ import annotations

from typing import Any, Callable, Mapping

from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter

from train_dynamics.physics.config import (ARRAY_KINDS, BOOL, DOUBLE, DOUBLE_ARRAY, INTEGER,
                                           ParamSpec, STRING, STRING_ARRAY, validate_value)
from train_dynamics.quoting import clip

Specs = Mapping[str, ParamSpec]

#: the most characters of a rejection's reason (the set's reply and the log line)
MAX_REASON = 500

_ROS_TYPE = {DOUBLE: ParameterType.PARAMETER_DOUBLE, INTEGER: ParameterType.PARAMETER_INTEGER,
             STRING: ParameterType.PARAMETER_STRING, BOOL: ParameterType.PARAMETER_BOOL,
             DOUBLE_ARRAY: ParameterType.PARAMETER_DOUBLE_ARRAY,
             STRING_ARRAY: ParameterType.PARAMETER_STRING_ARRAY}
_PARAMETER_TYPE = {DOUBLE_ARRAY: Parameter.Type.DOUBLE_ARRAY,
                   STRING_ARRAY: Parameter.Type.STRING_ARRAY}
_ANY_ARRAY = (Parameter.Type.INTEGER_ARRAY, Parameter.Type.BOOL_ARRAY,
              Parameter.Type.BYTE_ARRAY, Parameter.Type.STRING_ARRAY,
              Parameter.Type.DOUBLE_ARRAY)


def constraints(spec: ParamSpec) -> str:
    """Return the constraints of ``spec`` in words (choices, bounds), as the docs show them."""
    words = []
    if spec.choices:
        words.append('one of: ' + ', '.join(spec.choices))
    words += spec.bounds()
    if spec.kind == DOUBLE_ARRAY and words:
        words[0] = 'every element ' + words[0]
    return ', '.join(words)


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """Build the ParameterDescriptor (type, description, range, choices) of ``spec``."""
    when = ('changeable while running' if spec.dynamic
            else 'structural: pending until the reset service is called')
    d = ParameterDescriptor(name=spec.name, type=_ROS_TYPE[spec.kind],
                            description=f'{spec.description} ({when})',
                            additional_constraints=constraints(spec), read_only=False)
    if spec.low is None or spec.high is None:
        return d
    if spec.kind == DOUBLE:
        d.floating_point_range = [FloatingPointRange(from_value=float(spec.low),
                                                     to_value=float(spec.high), step=0.0)]
    elif spec.kind == INTEGER:
        d.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high),
                                        step=1)]
    return d


def as_declared_type(param: Parameter, spec: ParamSpec | None) -> Parameter:
    """
    Convert ``param`` to the type ``spec`` declares, where the meaning is unambiguous.

    An integer for a double; an integer array for a double array; an empty array of any type
    for an array (``ros2 param set`` sends ``[]`` as a bool array). Anything else unchanged
    (rclpy then rejects a wrong type).
    """
    if spec is None:
        return param
    t = param.type_
    if spec.kind == DOUBLE and t == Parameter.Type.INTEGER:
        return Parameter(param.name, Parameter.Type.DOUBLE, float(param.value))
    if spec.kind in ARRAY_KINDS and t in _ANY_ARRAY:
        values = list(param.value)
        if not values:
            return Parameter(param.name, _PARAMETER_TYPE[spec.kind], [])
        if spec.kind == DOUBLE_ARRAY and t == Parameter.Type.INTEGER_ARRAY:
            return Parameter(param.name, Parameter.Type.DOUBLE_ARRAY, [float(v) for v in values])
    return param


def declare_parameters(node: Node, specs: Specs) -> None:
    """
    Declare every parameter of ``specs`` with its default and descriptor.

    The value of an override (command line, parameter file) wins, as rclpy does; one of
    another type that :func:`as_declared_type` converts (an integer for a double, ``[]`` for
    an array) is accepted as the offline command accepts it.
    """
    for name, spec in specs.items():
        try:
            _declare(node, name, spec, ignore_override=False)
        except InvalidParameterTypeException:
            given = _override_of(node, name)
            converted = as_declared_type(given, spec)
            if converted.type_ == given.type_:
                raise
            _declare(node, name, spec, ignore_override=True, value=converted)


def _declare(node: Node, name: str, spec: ParamSpec, ignore_override: bool,
             value: Parameter | None = None) -> None:
    """Declare ``name``: ``value``, else the override, else the default."""
    if spec.kind in ARRAY_KINDS:
        # declared by type: an empty default would not tell rclpy the element type
        node.declare_parameter(name, _PARAMETER_TYPE[spec.kind], descriptor(spec),
                               ignore_override=ignore_override)
        if value is not None:
            node.set_parameters([value])
            return
        try:
            node.get_parameter(name)
        except ParameterUninitializedException:
            node.set_parameters([Parameter(name, _PARAMETER_TYPE[spec.kind],
                                           list(spec.default))])
    else:
        default = spec.default if value is None else value.value
        node.declare_parameter(name, default, descriptor(spec), ignore_override=ignore_override)


def _override_of(node: Node, name: str) -> Parameter:
    """Return the override of ``name`` whatever its type (declared untyped, then undeclared)."""
    node.declare_parameter(name, None, ParameterDescriptor(dynamic_typing=True))
    given = node.get_parameter(name)
    node.undeclare_parameter(name)
    return given


def parameter_values(node: Node, specs: Specs) -> dict[str, Any]:
    """Return the node's current values of ``specs`` (arrays as lists)."""
    out = {}
    for name, spec in specs.items():
        value = node.get_parameter(name).value
        out[name] = list(value) if spec.kind in ARRAY_KINDS else value
    return out


def validated(params: list[Parameter], specs: Specs) -> dict[str, Any]:
    """Return ``{name: value}`` of the parameters in ``specs``, each value validated."""
    return {p.name: validate_value(p.name, p.value, specs) for p in params if p.name in specs}


def rejection_reason(exc: Exception) -> str:
    """
    Return the one-line reason of a refused parameter change, at most :data:`MAX_REASON` chars.

    A ``ValueError`` (ConfigError) or ``OSError`` says why; anything else (a ``MemoryError``,
    a bug) is named by its type too, so that the set is refused instead of raising on the
    executor.
    """
    text = ' '.join(str(exc).split())
    if not isinstance(exc, (ValueError, OSError)) or not text:
        text = f'{type(exc).__name__}: {text}' if text else type(exc).__name__
    return clip(text, MAX_REASON)


def watch_parameters(node: Node, specs: Specs, check: Callable[[dict[str, Any]], None],
                     apply: Callable[[dict[str, Any]], None],
                     skip: Callable[[], bool] = lambda: False) -> None:
    """
    Register the set callbacks of ``node`` for ``specs``.

    ``check(changes)`` is the node's whole-batch validation (no side effects): it raises
    ``ValueError`` (or ``OSError``) with the reason to reject the batch, which then changes
    nothing; any other exception rejects the batch too (:func:`rejection_reason`), never
    reaching the executor. ``apply(changes)`` runs after rclpy has stored an accepted batch.
    ``changes`` holds the validated values of the batch's parameters of ``specs``; others (e.g.
    ``use_sim_time``) are left to rclpy. While ``skip()`` is true (the node setting a
    parameter itself) neither runs.
    """
    log = node.get_logger()

    def convert(params: list[Parameter]) -> list[Parameter]:
        return [as_declared_type(p, specs.get(p.name)) for p in params]

    def validate(params: list[Parameter]) -> SetParametersResult:
        if skip():
            return SetParametersResult(successful=True)
        try:
            check(validated(params, specs))
        except Exception as exc:  # noqa: BLE001 - every failure of a check is a rejection
            reason = rejection_reason(exc)
            log.warning(f'parameter change rejected: {reason}')
            return SetParametersResult(successful=False, reason=reason)
        return SetParametersResult(successful=True)

    def post_set(params: list[Parameter]) -> None:
        if not skip():
            apply(validated(params, specs))

    node.add_pre_set_parameters_callback(convert)
    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(post_set)
