"""
``train-dynamics plot``: PNG figures of a bag that holds ``couplers``.

The figures are those of :func:`train_dynamics.recording.plots.plot_history` (the paper's
figs. 5-7 / 9-11, and the coaches when recorded).
"""
from __future__ import annotations

import argparse
from pathlib import Path

from train_dynamics.cli.errors import CliError, EXIT_OK
from train_dynamics.cli.output import output_dir, remove_created
from train_dynamics.recording.bags import BagError
from train_dynamics.recording.plots import plot_bag, PlotError


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``plot`` command and its options."""
    pl = sub.add_parser('plot', help='PNG figures of a bag holding couplers',
                        description='PNG figures of relative displacement, relative velocity '
                        'and coupler force against time (one curve per coupler), and of the '
                        'coaches when recorded.')
    pl.add_argument('bag', metavar='BAG', help='rosbag2 holding couplers (JointState)')
    pl.add_argument('--output', required=True, metavar='DIR', help='directory for the PNGs')
    pl.add_argument('--namespace', default='', metavar='NS', help='topics under this namespace')
    pl.add_argument('--title', default=None, help='subtitle (default: bag name and model)')
    pl.add_argument('-q', '--quiet', action='store_true', help='do not list the files written')
    pl.set_defaults(func=cmd_plot)


def cmd_plot(args: argparse.Namespace) -> int:
    """Run ``plot``; return the exit status."""
    if not Path(args.bag).exists():
        raise CliError(f'bag not found: {args.bag}')
    created = output_dir(args.output)
    try:
        paths = plot_bag(args.bag, args.output, namespace=args.namespace, title=args.title)
    except (BagError, PlotError) as exc:
        remove_created(created)
        raise CliError(str(exc)) from None
    except OSError as exc:
        remove_created(created)
        raise CliError(f'cannot write figures to {args.output}: {exc.strerror or exc}'
                       ) from None
    except BaseException:
        remove_created(created)
        raise
    if not args.quiet:
        for p in paths:
            print(p)
    return EXIT_OK
