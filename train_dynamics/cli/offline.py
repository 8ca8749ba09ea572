"""
``train-dynamics``: the offline command (simulate, plot, compare) on the node's model code.

    train-dynamics simulate --params FILE [--input BAG] --duration T --output BAG
    train-dynamics plot BAG --output DIR
    train-dynamics compare --params FILE --duration T --output DIR
                           [--scale-factors 100,1000,10000] [--steps 0.001,0.0001]
    train-dynamics report BAG --output DIR [--params FILE]
    train-dynamics sweep --params BASE --sweep SWEEP.yaml --output DIR
                         [--scheduler ADDRESS] [--workers N] [--keep-bags]

This module is the entry point (``main``; also ``python -m train_dynamics.cli.offline``): the
parser, the exit statuses and the signals. The commands are :mod:`.simulate` (runs
:class:`train_dynamics.physics.train.TrainSimulator`, the class ``sim_node`` runs, as fast as
the machine allows, through :func:`train_dynamics.simulation.runner.run_simulation`),
:mod:`.plot`, :mod:`.compare`, :mod:`.report` (run metrics of a bag) and :mod:`.sweep`
(parameter studies on Dask); the parameter file and brake inputs of a run are read by
:mod:`.scenario`. Brake input:

* ``--input BAG`` (MCAP or sqlite3 rosbag2): the contract's input topics
  (``brake_pipe/pressure``, ``coach_<i>/brake_pipe/pressure``,
  ``coach_<i>/brake_cylinder/pressure``; ``sensor_msgs/FluidPressure``, ABSOLUTE Pa; a leading
  '/' and a ``--namespace`` prefix are accepted); only those of the file's ``brake_input`` are
  used. A message takes effect at its bag time relative to the bag's first message, at the
  first integration step starting at or after that time, and holds until the next one
  (zero-order hold), exactly as the node applies a message at its next step.
* no input bag (``pipe_head`` only): the head-pipe pressure follows the ``brake_valve``
  section of the same parameter file, sampled at every integration step; without that
  section: emergency braking at t = 1 s.

Errors print one line ``train-dynamics: error: ...`` and exit with 2 (bad input: parameter
file, a configuration the simulator refuses, bag, duration, existing output) or 1 (anything
else); a simulation fault (diverged
state) keeps the bag up to the fault and exits 3; Ctrl-C exits 130, SIGTERM 143
(:mod:`.errors`; ``simulate`` keeps the bag of the samples so far, ``sweep`` its finished
cases). Nothing else is left under the output path unless the command wrote a complete
bag.
"""
from __future__ import annotations

import argparse
from collections.abc import Sequence
import importlib
import os
import signal
import sys
import threading

from train_dynamics import __version__
from train_dynamics.cli.errors import (CliError, error, EXIT_ERROR, EXIT_INTERRUPT,
                                       EXIT_TERMINATED, EXIT_USAGE, invalid_parameters, PROG,
                                       Terminated)


class _Parser(argparse.ArgumentParser):

    def error(self, message: str):
        """Print the usage and raise a one-line :class:`CliError` (exit 2, as argparse)."""
        self.print_usage(sys.stderr)
        raise CliError(message)


#: the commands, in the order of ``--help``: each one a module of this package with
#: ``add_parser(sub)`` (its options, its ``func``), imported only when the command is chosen
COMMANDS = ('simulate', 'plot', 'compare', 'report', 'sweep')


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """
    Return the parser of ``train-dynamics`` and its commands.

    With ``command`` (one of :data:`COMMANDS`) only that command's module is imported and
    only its options are known: a run does not pay for the imports of the other commands
    (matplotlib, dask, pandas, bag reading). Without it, all of them (``--help``).
    """
    p = _Parser(prog=PROG, description='Longitudinal train dynamics, offline: simulate, plot '
                'and compare coupler models (the sim_node model, as fast as possible).')
    p.add_argument('--version', action='version', version=f'%(prog)s {__version__}')
    sub = p.add_subparsers(dest='command', required=True, metavar='COMMAND', parser_class=_Parser)
    for name in COMMANDS:
        if command is None or name == command:
            importlib.import_module(f'{__package__}.{name}').add_parser(sub)
        else:
            sub.add_parser(name)        # a name only: this run is another command
    return p


def command_of(argv: Sequence[str]) -> str | None:
    """Return the command ``argv`` names (its first word that is not an option), or None."""
    word = next((a for a in argv if not a.startswith('-')), None)
    return word if word in COMMANDS else None


def main(argv: Sequence[str] | None = None) -> int:
    """
    Run the command line; return the exit status.

    Run as the command (``argv`` None), a run stopped by SIGINT or SIGTERM exits at once
    once its outputs are closed, without the interpreter's teardown (the finalisers of
    numba, scipy, dask... take 0.5-1 s): a stopped command is gone within a second.
    """
    status = _main(argv)
    if argv is None and status in (EXIT_INTERRUPT, EXIT_TERMINATED):
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


def _main(argv: Sequence[str] | None) -> int:
    if argv is None:
        argv = sys.argv[1:]
    parser = build_parser(command_of(argv))
    previous = _install_sigterm()
    try:
        args = parser.parse_args(argv)
        return args.func(args)
    except CliError as exc:
        error(str(exc))
        return exc.code
    except SystemExit as exc:          # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return EXIT_INTERRUPT
    except BrokenPipeError:
        return EXIT_ERROR
    except Terminated:
        print(f'{PROG}: terminated', file=sys.stderr)
        return EXIT_TERMINATED
    except Exception as exc:  # noqa: B902 - last resort: still one line
        from train_dynamics.physics.config import ConfigError   # imported by every command
        if isinstance(exc, ConfigError):           # a configuration error: exit 2, everywhere
            error(str(invalid_parameters(exc)))
            return EXIT_USAGE
        text = ' '.join(str(exc).split()) or type(exc).__name__
        error(f'{type(exc).__name__}: {text}')
        if os.environ.get('TRAIN_DYNAMICS_DEBUG'):
            raise
        return EXIT_ERROR
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


def _install_sigterm():
    """Make SIGTERM raise :class:`Terminated` in the main thread; return the old handler."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum, frame):
        raise Terminated()

    try:
        return signal.signal(signal.SIGTERM, handler)
    except (ValueError, OSError):
        return None


if __name__ == '__main__':
    sys.exit(main())
