"""
``sim_node --help`` and ``brake_valve --help``: the usage of a node, printed before rclpy starts.

A ROS 2 node takes its configuration after ``--ros-args`` (``--params-file``, ``-p``, ``-r``;
the ROS 2 design article "ROS command line arguments"); ``-h`` or ``--help`` before it (or
with no ``--ros-args`` at all) asks for this text instead of a run. The parameter list is
generated from the node's parameter declarations (the one table), one line each: name,
default, the first sentence of the description.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
import re
import textwrap
from typing import Any

HELP_FLAGS = ('-h', '--help')
#: width of the parameter lines (the description is cut to fit)
WIDTH = 100


def wants_help(args: Sequence[str]) -> bool:
    """Return True if ``args`` (``sys.argv``: program first) ask for the usage."""
    for arg in list(args)[1:]:
        if arg == '--ros-args':
            return False
        if arg in HELP_FLAGS:
            return True
    return False


def _first_sentence(text: str) -> str:
    """Return the first sentence of ``text``: up to a '.' followed by a capital, or the end."""
    return re.split(r'(?<=\.)\s+(?=[A-Z])', ' '.join(text.split()), maxsplit=1)[0]


def _default(value: Any) -> str:
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, float):
        return f'{value:g}'
    return str(value)


def usage_text(prog: str, node_name: str, summary: str,
               specs: Mapping[str, Any]) -> str:
    """
    Return the usage of node executable ``prog`` (node name ``node_name``).

    ``summary``: what the node is, one line; ``specs``: name -> ``ParamSpec`` (its
    ``default`` and ``description``), in the order they are listed.
    """
    lines = [
        f'usage: {prog} [-h] [--ros-args [--params-file FILE] [-p NAME:=VALUE] '
        f'[-r FROM:=TO] ...]',
        '',
        *textwrap.wrap(summary, WIDTH),
        '',
        *textwrap.wrap(
            f'The node is named {node_name}. A parameter file configures it through its '
            f'section {node_name}: (root namespace) or /**/{node_name}: (any namespace); a '
            'file with no section for the node is an error (exit status 2).', WIDTH),
        '',
        f'parameters ({len(specs)}; ranges and units: ros2 param describe /{node_name} NAME, '
        'or docs/parameters.md):',
    ]
    for name, spec in specs.items():
        head = f'  {name} ({_default(spec.default)})'
        text = _first_sentence(spec.description)
        room = WIDTH - len(head) - 2
        lines.append(head + ('  ' + textwrap.shorten(text, room, placeholder=' ...')
                             if room > 20 else ''))
    lines += ['', *textwrap.wrap(
        'exit status: 0 ok (and after SIGINT/SIGTERM), 2 invalid parameters or arguments, 1 '
        'other errors (sim_node also: 3 numerical fault, 4 lock-step timeout).', WIDTH)]
    return '\n'.join(lines)
