"""
The parameter tables of the documentation, generated from the table (:data:`PARAMETERS`).

The parameters, then the per-vehicle fields of a consist (:data:`VEHICLE_PARAMETERS`);
:func:`parameter_table` formats any table of :class:`ParamSpec` (``sim_node``'s own:
:mod:`train_dynamics.ros.node_parameters`).
``python -m train_dynamics.physics.config.docs`` prints them; a test checks that
docs/parameters.md holds them as printed.
"""
from __future__ import annotations

from typing import Any, Mapping

from train_dynamics.physics.config.spec import ADDED, EQUAL_FORCE, ParamSpec, SERIES
from train_dynamics.physics.config.table import PARAMETERS, VEHICLE_PARAMETERS


#: the heading of the per-vehicle table (the text before it is docs/parameters.md's own)
VEHICLE_HEADING = """\
### Per-vehicle fields

A consist file (`consist_file`) may set these per vehicle; a vehicle that leaves one out takes
the parameter named. Range and unit are the parameter's. A field with a kernel row reaches the
kernel as is (`layout.VEHICLE`); mass, rotating mass factor, adhesion coefficient and length also
make the derived rows (inertia, braking mass, weight, track position, pipe delay).\
"""


def fmt_default(v: Any) -> str:
    """Return a default value as the table shows it (markdown)."""
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, str):
        return '`""`' if v == '' else f'`{v}`'
    if isinstance(v, list):
        return '`[]`' if not v else f'`{v!r}`'
    if isinstance(v, float):
        return f'{v:g}'
    return str(v)


def fmt_range(s: ParamSpec) -> str:
    """Return the choices or the bounds (:meth:`ParamSpec.bounds`) as the table shows them."""
    if s.choices:
        return ', '.join(f'`{c}`' for c in s.choices)
    return ', '.join(s.bounds())


#: how a connection field joins two vehicles, in words
_CONNECTION_WORDS = {SERIES: 'ends in series (compliances add)', ADDED: 'ends add',
                     EQUAL_FORCE: 'ends in series (equal force, strokes add: one table)'}


def vehicle_table() -> str:
    """Return the table of the per-vehicle fields: default, coupler rule, kernel row."""
    lines = ['| consist field | default: parameter | coupling of two vehicle ends | kernel row |',
             '| --- | --- | --- | --- |']
    for field, s in VEHICLE_PARAMETERS.items():
        row = f'`{s.row}`' if s.row else ''
        lines.append(f'| `{field}` | `{s.name}` | {_CONNECTION_WORDS.get(s.connection, "")} '
                     f'| {row} |')
    return '\n'.join(lines)


def parameter_table(specs: Mapping[str, ParamSpec]) -> str:
    """Return the markdown table of ``specs``: name, type, default, range, when, meaning."""
    lines = ['| name | type | default | range | when | meaning |',
             '| --- | --- | --- | --- | --- | --- |']
    for s in specs.values():
        when = 'live' if s.dynamic else 'reset'
        meaning = s.description.replace('|', '/')
        lines.append(f'| `{s.name}` | {s.kind} | {fmt_default(s.default)} | {fmt_range(s)} '
                     f'| {when} | {meaning} |')
    return '\n'.join(lines)


def markdown_table() -> str:
    """Return the docs' parameter tables: :data:`PARAMETERS`, then :func:`vehicle_table`."""
    return (parameter_table(PARAMETERS) + '\n\n' + VEHICLE_HEADING + '\n\n'
            + vehicle_table())


if __name__ == '__main__':   # python -m train_dynamics.physics.config.docs: the docs' tables
    print(markdown_table())
