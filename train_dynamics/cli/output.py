"""
Output directories of ``plot`` and ``compare``: checked before any work, cleaned up on failure.

:func:`output_dir` creates the directory (and missing parents) and proves it writable with a
probe file before the command simulates or reads anything, so that a read-only or impossible
location is one line and exit 2 at once (as root, permission bits do not tell: only a write
does); :func:`remove_created` takes back what it created when the command fails.
"""
from __future__ import annotations

import os
from pathlib import Path
import tempfile

from train_dynamics.cli.errors import CliError


def output_dir(path: str | os.PathLike) -> list[Path]:
    """Create ``path`` if needed and check that files can be written in it; return the new dirs."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise CliError(f'cannot write figures to {out}: it is not a directory')
    created = []
    p = out
    while not p.exists() and not p.is_symlink() and p != p.parent:
        created.append(p)
        p = p.parent
    try:
        for d in reversed(created):
            d.mkdir()
        with tempfile.TemporaryFile(dir=out):
            pass
    except OSError as exc:
        remove_created(created)
        raise CliError(f'cannot write figures to {out}: {exc.strerror or exc}') from None
    return created


def remove_created(created: list[Path]) -> None:
    """Remove the directories :func:`output_dir` created (innermost first) if still empty."""
    for d in created:
        try:
            d.rmdir()
        except OSError:
            pass
