"""
The offline command's errors and exit statuses, and its one-line messages on stderr.

Exit statuses: 0 done, 2 bad input (parameter file, bag, duration, existing output; also
argparse's usage errors; a configuration the simulator refuses: :func:`check_runnable`, any
``ConfigError``), 1 anything else, 3 simulation fault (the bag up to the fault is kept), 130
Ctrl-C, 143 SIGTERM.
"""
from __future__ import annotations

from collections.abc import Iterator
import contextlib
import signal
import sys
import threading
from typing import Any

PROG = 'train-dynamics'
EXIT_OK = 0
EXIT_ERROR = 1
EXIT_USAGE = 2
EXIT_FAULT = 3
EXIT_INTERRUPT = 130
EXIT_TERMINATED = 143
#: how a configuration error begins (after its source): every command, every sweep case
INVALID_PARAMETERS = 'invalid parameters'


class CliError(Exception):
    """A one-line error for the user; ``code`` is the exit status."""

    def __init__(self, message: str, code: int = EXIT_USAGE) -> None:
        super().__init__(' '.join(str(message).split()))
        self.code = code


def invalid_parameters(exc: BaseException, source: str = '') -> CliError:
    """Return the exit-2 error of a configuration refused with ``exc`` (one line)."""
    where = f'{source}: ' if source else ''
    why = ' '.join(str(exc).split()) or type(exc).__name__
    return CliError(f'{where}{INVALID_PARAMETERS}: {why}')


def check_runnable(cfg: Any, source: str = '') -> None:
    """
    Refuse (exit 2) a configuration the simulator cannot run, before anything is written.

    Builds the simulator of ``cfg`` and takes one step, as ``sim_node`` does at start: a
    ``ValueError`` (``ConfigError`` included: e.g. a friction material without a force level,
    a braked mass the brake cannot deliver) is an invalid configuration, as the node's exit 2.
    """
    from train_dynamics.physics.train import TrainSimulator     # here: errors stays light

    try:
        TrainSimulator(cfg).advance(1)
    except ValueError as exc:
        raise invalid_parameters(exc, source) from None


class Terminated(BaseException):
    """SIGTERM, raised like KeyboardInterrupt so that partial output is cleaned up."""


class Interrupted(Exception):
    """SIGINT or SIGTERM, taken at a safe point of a run (:func:`deferred_signals`)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.code = EXIT_INTERRUPT if signum == signal.SIGINT else EXIT_TERMINATED


class SignalFlag:
    """The first SIGINT / SIGTERM of a :func:`deferred_signals` block (None: none yet)."""

    def __init__(self) -> None:
        self.signum: int | None = None

    def check(self) -> None:
        """Raise :class:`Interrupted` if a signal came: call it where stopping is safe."""
        if self.signum is not None:
            raise Interrupted(self.signum)


@contextlib.contextmanager
def deferred_signals() -> Iterator[SignalFlag]:
    """
    Take SIGINT and SIGTERM at safe points: in the block a signal only sets the flag.

    The run calls :meth:`SignalFlag.check` between two samples, so that what it recorded
    ends on a whole sample. A second signal raises at once (KeyboardInterrupt or
    :class:`Terminated`), for a run that does not reach a safe point. Outside the main thread
    (no signal handlers there) the flag stays None.
    """
    flag = SignalFlag()
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return

    def handler(signum, frame):
        if flag.signum is not None:
            raise KeyboardInterrupt() if signum == signal.SIGINT else Terminated()
        flag.signum = signum

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def warn(text: str) -> None:
    """Print ``train-dynamics: warning: <text>`` on stderr."""
    print(f'{PROG}: warning: {text}', file=sys.stderr)


def error(text: str) -> None:
    """Print ``train-dynamics: error: <text>`` on stderr."""
    print(f'{PROG}: error: {text}', file=sys.stderr)
