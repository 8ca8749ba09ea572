"""
The progress bar of the offline runs (``tqdm``), on stderr.

Shown only when stderr is a terminal and the command was not given ``-q``:
``simulate [#######.......]  52.3 % t =   31.38/60 s  6.71s/s`` (simulated seconds per wall
second: the speed-up over real time).
"""
from __future__ import annotations

from collections.abc import Callable
import sys

_FORMAT = '{desc} [{bar:30}] {percentage:5.1f} % t = {n:7.2f}/{total:g} s  {rate_noinv_fmt}'


def progress_bar(label: str, duration: float, quiet: bool = False) -> Callable[[float], None]:
    """
    Return the ``progress`` callback of a run of ``duration`` [s] of simulation time.

    It takes the fraction done; 1.0 ends the bar (a newline). No output with ``quiet`` or
    when stderr is not a terminal; tqdm is imported only for a bar that is shown (~30 ms
    of every run's start-up otherwise).
    """
    isatty = getattr(sys.stderr, 'isatty', None)
    if quiet or (isatty is not None and not isatty()):
        return _no_progress
    from tqdm import tqdm

    bar = tqdm(total=duration, desc=label, unit='s', file=sys.stderr, ascii='.#',
               bar_format=_FORMAT, disable=False, mininterval=0.1,
               smoothing=0.0, dynamic_ncols=False)

    def show(fraction: float) -> None:
        bar.update(min(fraction, 1.0) * duration - bar.n)
        if fraction >= 1.0:
            bar.close()

    return show


def _no_progress(fraction: float) -> None:
    """Show nothing (the callback of a run without a progress bar)."""
