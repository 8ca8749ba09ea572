"""
Bounded quotes of values for one-line messages: :func:`quote` (a value), :func:`clip` (a text).

Every error message that shows a value the user gave (a parameter, a field of a consist or
sweep file, a path) quotes it with :func:`quote`: never its full repr, since a value read from
a file may be a YAML alias bomb (a few hundred bytes that stand for gigabytes of nested lists)
or a list of a million numbers. Loads nothing but the standard library, so that every layer
may import it.
"""
from __future__ import annotations

import reprlib

#: the most characters of a value an error message quotes
QUOTE_CHARS = 60
_QUOTE = reprlib.Repr()           # (Python 3.11 has no keyword arguments for these)
_QUOTE.maxlevel = 2
for _name in ('maxtuple', 'maxlist', 'maxarray', 'maxdict', 'maxset', 'maxfrozenset',
              'maxdeque'):
    setattr(_QUOTE, _name, 4)
_QUOTE.maxstring = _QUOTE.maxlong = _QUOTE.maxother = QUOTE_CHARS


def quote(value: object) -> str:
    """
    Return a bounded repr of ``value`` for a message: at most :data:`QUOTE_CHARS` characters.

    Never the full repr: a value read from a file may be a YAML alias bomb (a few hundred
    bytes that stand for gigabytes of nested lists); :mod:`reprlib` looks at a bounded part.
    """
    try:
        text = _QUOTE.repr(value)
    except Exception:  # noqa: BLE001 - e.g. an int beyond str()'s digit limit: name the type
        text = f'<{type(value).__name__}>'
        if isinstance(value, int):
            text = f'<an integer of {value.bit_length()} bits>'
    return clip(text, QUOTE_CHARS)


def clip(text: str, limit: int = 300) -> str:
    """Return ``text`` cut to ``limit`` characters (an error message of another module)."""
    return text if len(text) <= limit else text[:limit - 3] + '...'
