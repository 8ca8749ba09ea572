"""
Running a sweep on Dask: the cluster, the cases as they finish, the table and its figures.

Output directory::

    DIR/sweep.json            what the sweep is (parameters swept, cases, a digest of the plan)
    DIR/cases/case_NNNNN.json one file per finished case (written atomically as it finishes)
    DIR/results.parquet       the table: one row per case (consolidated at the end)
    DIR/figures/*.png         each metric against each swept parameter
    DIR/bags/case_NNNNN/      each case's bag (--keep-bags; the workers write them)

Resume: a rerun with the same output directory and the same plan runs only the cases that
have no file in ``DIR/cases``; a different plan is refused. Dask reschedules the cases of a
worker that dies (a case that kills workers repeatedly ends as a row with the error).
"""
from __future__ import annotations

import argparse
from collections.abc import Iterator
import contextlib
import json
import logging
import os
from pathlib import Path
import sys
from typing import Any
import uuid

from distributed import as_completed, Client, LocalCluster
import numpy as np
import pandas as pd
from tqdm import tqdm

from train_dynamics.cli.errors import CliError, EXIT_OK
from train_dynamics.cli.sweep_case import failed_row, run_case
from train_dynamics.cli.sweep_plan import make_plan, Plan
from train_dynamics.physics.metrics import FLAT_KEYS
from train_dynamics.recording.metrics_report import sweep_figures

RESULTS = 'results.parquet'
#: the metrics drawn against each swept parameter
FIGURE_METRICS = ('max_tension', 'max_compression', 'stopping_distance', 'stopping_time',
                  'max_deceleration', 'max_jerk', 'brake_energy', 'coupler_dissipated')
_INT_KEYS = ('max_tension_coupler', 'max_compression_coupler', 'max_deceleration_vehicle',
             'max_jerk_vehicle', 'blocking_count', 'impact_count', 'limit_crossings',
             'samples')


def run_sweep(args: argparse.Namespace) -> int:
    """Run ``sweep``: plan, cases on Dask (only the missing ones), table, figures."""
    if args.workers is not None and args.workers < 1:
        raise CliError(f'--workers must be >= 1, got {args.workers}')
    plan = make_plan(args.params, args.sweep)          # every check before any case runs
    out = Path(args.output)
    done = prepare_output(out, plan)
    todo = [c for c in plan.cases if c.index not in done]
    for c in todo:
        if c.error:
            write_case(out, plan, failed_row(c.index, c.error))
    to_run = [c for c in todo if not c.error]
    if to_run:
        with cluster_client(args) as client:
            execute(client, plan, to_run, out, args)
    table = consolidate(out, plan)
    figures = [] if args.no_figures else sweep_figures(
        {c: table[c].to_numpy() for c in table.columns}, plan.swept,
        [m for m in FIGURE_METRICS if m in table], out / 'figures',
        failed=table['error'].astype(bool).to_numpy())
    if not args.quiet:
        failed = int(table['error'].astype(bool).sum())
        print(f'{len(table)} cases ({len(to_run)} run now, {len(done)} done before, '
              f'{failed} with errors): {out / RESULTS}, {len(figures)} figures')
    return EXIT_OK


def prepare_output(out: Path, plan: Plan) -> set[int]:
    """Create or check ``out`` for ``plan``; return the cases already done (resume)."""
    meta = out / 'sweep.json'
    if out.exists() and not out.is_dir():
        raise CliError(f'--output {out} is not a directory')
    if meta.exists():
        try:
            old = json.loads(meta.read_text(encoding='utf-8'))
        except (OSError, ValueError) as exc:
            raise CliError(f'{meta}: unreadable ({exc}); choose a new --output') from None
        if old.get('digest') != plan.digest:
            raise CliError(f'{out} holds another sweep (its plan differs from this one); '
                           'choose a new --output, or rerun the same sweep to resume it')
    elif out.exists() and any(out.iterdir()):
        raise CliError(f'--output {out} exists and is not a sweep directory')
    (out / 'cases').mkdir(parents=True, exist_ok=True)
    _write_json(meta, plan.describe())
    done = set()
    for c in plan.cases:
        path = _case_path(out, c.index)
        try:
            doc = json.loads(path.read_text(encoding='utf-8'))
        except (OSError, ValueError):
            continue
        if doc.get('digest') == plan.digest:
            done.add(c.index)
    return done


@contextlib.contextmanager
def cluster_client(args: argparse.Namespace) -> Iterator[Client]:
    """Yield a client of the scheduler at ``--scheduler`` or of a new LocalCluster."""
    for name in ('distributed', 'distributed.nanny', 'distributed.scheduler',
                 'distributed.worker', 'distributed.core'):
        logging.getLogger(name).setLevel(logging.ERROR)
    cluster = None
    try:
        if args.scheduler:
            try:
                client = Client(args.scheduler, timeout='20s')
            except (OSError, TimeoutError, ValueError) as exc:
                raise CliError(f'cannot reach the Dask scheduler at {args.scheduler}: '
                               f'{exc}') from None
        else:
            cluster = LocalCluster(n_workers=args.workers or os.cpu_count() or 1,
                                   threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


def execute(client: Client, plan: Plan, cases: list, out: Path,
            args: argparse.Namespace) -> None:
    """Submit ``cases``; write each case's file as it finishes; show a progress bar."""
    token = uuid.uuid4().hex[:8]
    futures = {}
    for c in cases:
        bag = str((out / 'bags' / f'case_{c.index:05d}').resolve()) if args.keep_bags else None
        fut = client.submit(run_case, c.index, c.params, plan.duration, c.inputs, bag,
                            key=f'train-dynamics-case-{c.index:05d}-{token}', pure=False)
        futures[fut] = c.index
    bar = tqdm(total=len(plan.cases), initial=len(plan.cases) - len(cases), desc='sweep',
               unit='case', file=sys.stderr, disable=True if args.quiet else None,
               ascii='.#', dynamic_ncols=False)
    try:
        for fut in as_completed(list(futures)):
            try:
                row = fut.result()
            except Exception as exc:  # noqa: B902 - e.g. KilledWorker: the case's row
                row = failed_row(futures[fut], f'{type(exc).__name__}: {exc}')
            write_case(out, plan, row)
            fut.release()
            bar.update(1)
    finally:
        bar.close()


def write_case(out: Path, plan: Plan, row: dict[str, Any]) -> None:
    """Write a finished case's file (atomically): its swept values and its row."""
    case = plan.cases[row['case']]
    _write_json(_case_path(out, case.index), {'digest': plan.digest, 'swept': case.swept,
                                              'row': row})


def consolidate(out: Path, plan: Plan) -> pd.DataFrame:
    """Return the table of every case (by case number) and write ``results.parquet``."""
    rows = []
    for c in plan.cases:
        doc = json.loads(_case_path(out, c.index).read_text(encoding='utf-8'))
        row = doc['row']
        rows.append({'case': c.index, **c.swept, **{k: row.get(k) for k in FLAT_KEYS},
                     'fault_time': row.get('fault_time'), 'error': row.get('error') or '',
                     'wall_s': row.get('wall_s')})
    table = pd.DataFrame(rows)
    for k in FLAT_KEYS + ('fault_time', 'wall_s'):
        if k == 'stopped':
            table[k] = table[k].astype('boolean')
        elif k in _INT_KEYS:
            table[k] = pd.array(table[k], dtype='Int64')
        else:
            table[k] = np.asarray(table[k].to_numpy(dtype=float, na_value=np.nan), dtype=float)
    tmp = out / f'.{RESULTS}.tmp'
    table.to_parquet(tmp, index=False)
    os.replace(tmp, out / RESULTS)
    return table


def _case_path(out: Path, index: int) -> Path:
    return out / 'cases' / f'case_{index:05d}.json'


def _write_json(path: Path, doc: Any) -> None:
    tmp = path.with_name(f'.{path.name}.tmp{os.getpid()}')
    tmp.write_text(json.dumps(doc, sort_keys=True, default=_plain) + '\n',
                   encoding='utf-8')
    os.replace(tmp, path)


def _plain(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f'not JSON serialisable: {type(value).__name__}')
