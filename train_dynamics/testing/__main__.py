"""
``python -m train_dynamics.testing SCENARIO --output DIR [options] -- CONTROLLER...``.

Runs the controller's command against the scenario (:func:`train_dynamics.testing.run_scenario`)
and prints the pass/fail report. Exit status: 0 passed, 1 failed (a criterion, or the run:
controller gone, node error, timeout), 2 a configuration error (scenario, options, output
folder, controller command not found: one line, nothing run), 130 Ctrl-C, 143 SIGTERM (both
after the processes are ended).
"""
from __future__ import annotations

import argparse
import signal
import sys
from typing import Sequence

PROG = 'python -m train_dynamics.testing'


class _Terminated(BaseException):
    """SIGTERM, raised like KeyboardInterrupt so that the harness ends its processes."""


def _terminate(signum, frame):
    raise _Terminated()


def parser() -> argparse.ArgumentParser:
    """Return the command's argument parser."""
    p = argparse.ArgumentParser(
        prog=PROG, usage=f'{PROG} SCENARIO --output DIR [options] [-- CONTROLLER...]',
        description='Run a brake controller against a scenario in lock-step and check its '
        'criteria.', epilog='Everything after -- is the controller command (none: a '
        'controller started elsewhere).')
    p.add_argument('scenario', metavar='SCENARIO', help='scenario file (YAML)')
    p.add_argument('--output', required=True, metavar='DIR',
                   help='run folder (new or empty): bag, logs, report/')
    p.add_argument('--namespace', default='', metavar='NS', help='run both nodes under NS')
    p.add_argument('--figures', action='store_true', default=None,
                   help="draw the report's figures (default: the scenario's figures, off)")
    p.add_argument('--timeout', type=float, default=300.0, metavar='S',
                   help='wall seconds for the whole run (default 300)')
    p.add_argument('--lockstep-timeout', type=float, default=10.0, metavar='S',
                   help='wall seconds the node waits for an answer (default 10)')
    p.add_argument('--real-time-factor', type=float, default=0.0, metavar='F',
                   help='0 = as fast as possible (default)')
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command; return the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    split = argv.index('--') if '--' in argv else len(argv)
    args = parser().parse_args(argv[:split])
    controller = argv[split + 1:]          # none: a controller started elsewhere
    from train_dynamics.physics.config import ConfigError
    from train_dynamics.testing import run_scenario

    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        result = run_scenario(args.scenario, controller or None, args.output,
                              namespace=args.namespace, figures=args.figures,
                              timeout=args.timeout, lockstep_timeout=args.lockstep_timeout,
                              real_time_factor=args.real_time_factor)
    except ConfigError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted; processes ended', file=sys.stderr)
        return 130
    except _Terminated:
        print(f'{PROG}: terminated; processes ended', file=sys.stderr)
        return 143
    finally:
        signal.signal(signal.SIGTERM, previous)
    print(result.report())
    return 0 if result.passed else 1


if __name__ == '__main__':
    sys.exit(main())
