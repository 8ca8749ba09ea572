"""
The parameter table of the documentation, generated from the table (:data:`PARAMETERS`).

``python -m train_dynamics.physics.config.docs`` prints it; a test checks that the README holds
it as printed.
"""
from __future__ import annotations

from typing import Any

from train_dynamics.physics.config.spec import ParamSpec
from train_dynamics.physics.config.table import PARAMETERS


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


def markdown_table() -> str:
    """Return the README's parameter table, generated from :data:`PARAMETERS`."""
    lines = ['| name | type | default | range | when | meaning |',
             '| --- | --- | --- | --- | --- | --- |']
    for s in PARAMETERS.values():
        when = 'live' if s.dynamic else 'reset'
        meaning = s.description.replace('|', '/')
        lines.append(f'| `{s.name}` | {s.kind} | {fmt_default(s.default)} | {fmt_range(s)} '
                     f'| {when} | {meaning} |')
    return '\n'.join(lines)


if __name__ == '__main__':   # python -m train_dynamics.physics.config.docs: the README table
    print(markdown_table())
