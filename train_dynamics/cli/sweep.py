"""
``train-dynamics sweep``: a parameter study, each case an offline run on a Dask worker.

    train-dynamics sweep --params BASE --sweep SWEEP.yaml --output DIR
                         [--scheduler ADDRESS] [--workers N] [--keep-bags]

The sweep file (grid and/or Latin hypercube, duration, optional input bag) is read and
checked by :mod:`.sweep_plan` before anything runs; :mod:`.sweep_run` runs the cases on a
``distributed.LocalCluster`` (processes, ``--workers`` of them, one per core by default, one
thread each) or on the running scheduler at ``--scheduler`` (``dask scheduler`` /
``dask worker``, dask-jobqueue ...), each through :mod:`.sweep_case` (the ``simulate`` run
loop with the run metrics), and writes ``DIR/results.parquet``.
"""
from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` command and its options."""
    s = sub.add_parser('sweep', help='parameter sweep on Dask: DIR/results.parquet',
                       description='Run a grid and/or Latin hypercube of simulator '
                       'parameters, one offline run per case on Dask workers, and tabulate '
                       'the run metrics (DIR/results.parquet, figures). A rerun with the '
                       'same DIR completes only the missing cases.')
    s.add_argument('--params', required=True, metavar='BASE',
                   help='base parameter file (train_dynamics and optional brake_valve)')
    s.add_argument('--sweep', required=True, metavar='SWEEP.yaml', help='the sweep file')
    s.add_argument('--output', required=True, metavar='DIR', help='output directory')
    s.add_argument('--scheduler', metavar='ADDRESS',
                   help='address of a running Dask scheduler (default: a LocalCluster)')
    s.add_argument('--workers', type=int, metavar='N',
                   help='LocalCluster worker processes (default: one per core)')
    s.add_argument('--keep-bags', action='store_true',
                   help="keep each case's bag in DIR/bags (the workers must see DIR)")
    s.add_argument('--no-figures', action='store_true', help='no figures, only the table')
    s.add_argument('-q', '--quiet', action='store_true', help='no progress bar, no summary')
    s.set_defaults(func=cmd_sweep)


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run ``sweep``; return the exit status."""
    # Imported here, not at the top: dask, distributed, pandas and scipy.stats take ~2 s to
    # import, which every other train-dynamics command would otherwise pay.
    from train_dynamics.cli import sweep_run

    return sweep_run.run_sweep(args)
