"""
The sections of ``bench/RESULTS.md`` that a benchmark script owns, between its two markers.

One splice and one reader for every such section (soak, sweep, memory): a script writes its
section into RESULTS.md in place (or appends it), and ``run_all.py`` reads each script's last
saved section back when it renders the whole file.
"""
from __future__ import annotations

import os


def splice_section(results: str, begin: str, end: str, section: str) -> None:
    """Write ``section`` between the markers ``begin``/``end`` of the file ``results``."""
    block = f'{begin}\n{section}\n{end}'
    try:
        with open(results) as fh:
            text = fh.read()
    except OSError:
        text = '# Benchmark results\n\n'
    if begin in text and end in text:
        a = text.index(begin)
        b = text.index(end) + len(end)
        text = text[:a] + block + text[b:]
    else:
        text = text.rstrip('\n') + '\n\n' + block + '\n'
    with open(results, 'w') as fh:
        fh.write(text)


def saved_section(path: str | os.PathLike, begin: str, end: str, title: str) -> str:
    """Return the section saved in ``path`` within its markers ('Not run yet' without it)."""
    try:
        with open(path) as fh:
            body = fh.read().strip()
    except OSError:
        body = f'{title}\n\nNot run yet on this machine.'
    if body.startswith(begin):        # a file saved with its markers
        return body
    return f'{begin}\n{body}\n{end}'
