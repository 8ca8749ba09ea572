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

Exit status: 0 when at least one case gave its metrics, 1 when every case failed (the table
is written all the same), 2 for a bad sweep file, ``--workers`` or ``--scheduler``, or when
every case failed for invalid parameters (a configuration error, as ``simulate``'s); Ctrl-C
130 and SIGTERM 143, the finished cases kept for a resume. ``--workers`` is at most
:data:`WORKERS_PER_CORE` per core and what the available memory holds at
:data:`WORKER_MEMORY` each. ``--scheduler`` is checked (its form, its port, a TCP
connection within :data:`CONNECT_TIMEOUT`) before the client is made. The LocalCluster
serves no dashboard and no HTTP route (distributed always opens an HTTP listener: it is on a
free port of 127.0.0.1, never 8787).
"""
from __future__ import annotations

import argparse
from collections.abc import Iterator
import contextlib
import json
import logging
import os
from pathlib import Path
import signal
import socket
import sys
from typing import Any
import uuid

import dask
from distributed import as_completed, Client, LocalCluster
from distributed.comm.addressing import get_address_host_port, parse_address
import numpy as np
import pandas as pd
import psutil
from tqdm import tqdm

from train_dynamics.cli.errors import (CliError, error, EXIT_ERROR, EXIT_OK, EXIT_USAGE,
                                       INVALID_PARAMETERS)
from train_dynamics.cli.sweep_case import failed_row, run_case
from train_dynamics.cli.sweep_plan import make_plan, Plan
from train_dynamics.physics.config import fmt_bytes
from train_dynamics.physics.metrics import FLAT_KEYS
from train_dynamics.quoting import clip, quote
from train_dynamics.recording.metrics_report import sweep_figures

RESULTS = 'results.parquet'
#: the metrics drawn against each swept parameter
FIGURE_METRICS = ('max_tension', 'max_compression', 'stopping_distance', 'stopping_time',
                  'max_deceleration', 'max_jerk', 'brake_energy', 'coupler_dissipated')
_INT_KEYS = ('max_tension_coupler', 'max_compression_coupler', 'max_deceleration_vehicle',
             'max_jerk_vehicle', 'blocking_count', 'impact_count', 'limit_crossings',
             'samples')
#: LocalCluster workers per core at most (a case is CPU-bound: more only take memory)
WORKERS_PER_CORE = 4
#: [bytes] memory of a LocalCluster worker running a case (the model, its kernels, a case)
WORKER_MEMORY = 250 * 2 ** 20
#: [s] to open a TCP connection to ``--scheduler`` (a dead one is refused at once)
CONNECT_TIMEOUT = 5.0


def run_sweep(args: argparse.Namespace) -> int:
    """Run ``sweep``: plan, cases on Dask (only the missing ones), table, figures."""
    if args.workers is not None:
        check_workers(args.workers)
    if args.scheduler:
        check_scheduler(args.scheduler)
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
    failed = int(table['error'].astype(bool).sum())
    if not args.quiet:
        print(f'{len(table)} cases ({len(to_run)} run now, {len(done)} done before, '
              f'{failed} with errors): {out / RESULTS}, {len(figures)} figures')
    if failed == len(table):
        first = str(table['error'].iloc[0])
        error(f'every case failed ({failed}), the first: {first[:200]}; see {out / RESULTS}')
        invalid = table['error'].astype(str).str.startswith(INVALID_PARAMETERS).all()
        return EXIT_USAGE if invalid else EXIT_ERROR
    return EXIT_OK


def max_workers() -> tuple[int, str]:
    """Return the most LocalCluster workers of this machine, and why (for the message)."""
    cores = os.cpu_count() or 1
    available = psutil.virtual_memory().available
    n = max(1, min(WORKERS_PER_CORE * cores, available // WORKER_MEMORY))
    return n, (f'{WORKERS_PER_CORE} per core on {cores} cores, {fmt_bytes(WORKER_MEMORY)} '
               f'each of {fmt_bytes(available)} available')


def check_workers(workers: int) -> None:
    """Raise :class:`CliError` unless 1 <= ``workers`` <= :func:`max_workers`."""
    if workers < 1:
        raise CliError(f'--workers must be >= 1, got {workers}')
    n, why = max_workers()
    if workers > n:
        raise CliError(f'--workers {workers}: at most {n} on this machine ({why})')


def check_scheduler(address: str) -> None:
    """Raise :class:`CliError` for a malformed ``--scheduler`` or one nothing answers at."""
    try:
        protocol, _ = parse_address(address)
        host, port = get_address_host_port(address)
    except (ValueError, TypeError) as exc:
        raise CliError(f'--scheduler {quote(address)}: not a Dask scheduler address '
                       f'({clip(str(exc), 120)}); expected e.g. tcp://HOST:8786') from None
    if not 0 < port < 65536:
        raise CliError(f'--scheduler {quote(address)}: bad address, port {port} is not in '
                       '1..65535')
    if protocol not in ('tcp', 'tls'):
        return
    try:
        socket.create_connection((host, port), timeout=CONNECT_TIMEOUT).close()
    except OSError as exc:
        why = 'timed out' if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise CliError(f'cannot reach the Dask scheduler at {quote(address)}: {why}'
                       ) from None


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
                raise CliError(f'cannot reach the Dask scheduler at {quote(args.scheduler)}: '
                               f'{exc}') from None
        else:
            # no dashboard and no HTTP route; the listener distributed always opens is on a
            # free port of 127.0.0.1 (dashboard_address=None alone still serves :8787)
            with dask.config.set({'distributed.scheduler.http.routes': []}):
                cluster = LocalCluster(
                    n_workers=args.workers or os.cpu_count() or 1, threads_per_worker=1,
                    processes=True, host='127.0.0.1', dashboard_address=None,
                    scheduler_kwargs={'dashboard': False, 'dashboard_address': '127.0.0.1:0'},
                    silence_logs=logging.ERROR)
            client = Client(cluster)
        try:
            yield client
        except BaseException:
            # stopped (Ctrl-C, SIGTERM, an error): a busy worker would hold a graceful close
            # for ~4 s; the finished cases are on disk, the running ones are lost anyway
            if cluster is not None:
                _kill_workers(cluster)
            raise
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()


def _kill_workers(cluster: LocalCluster) -> None:
    """SIGKILL the worker processes of our LocalCluster (its nannies' children)."""
    for nanny in list(cluster.workers.values()):
        pid = getattr(nanny, 'pid', None)
        if pid:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)


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
