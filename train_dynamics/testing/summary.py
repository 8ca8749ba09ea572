"""
The run metrics of a harness run, computed in the harness's own process from the bag.

The numbers are those of ``train-dynamics report`` (the same code: the bag read block by
block by :func:`train_dynamics.cli.report.read_run`, the same refusals of a bag without
``couplers``/``coaches`` or with non-finite values); ``summary.json`` and ``summary.md`` are
written into the report folder. The figures (``figures=True``) are the whole report of that
command, written by its own function; they are off by default: they cost more than the run
metrics and a CI job rarely looks at them.

:func:`preload` imports the report's modules (the plotting library only for figures) and
warms the run metrics ahead of time: the harness calls it in a thread while the simulation
runs, so that the report after the loop costs little more than the reading of the bag.
Without figures only ``couplers`` and ``coaches`` are read, and the bag is opened once.
"""
from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

from train_dynamics.testing.criteria import criteria_metrics


def preload(cfg: Any = None, figures: bool = False) -> None:
    """
    Import what :func:`run_metrics` needs; with the run's configuration, warm its metrics.

    ``figures``: import the plotting modules (matplotlib) too.

    The warm-up feeds two zero samples to the run's
    :class:`~train_dynamics.physics.metrics.RunMetrics` and takes their result: the compiled
    functions the report calls (the couplers' elastic energy) are loaded then, not after the
    run (0.3 s of CPU measured with 13 vehicles). Nothing is written.
    """
    import numpy as np

    import train_dynamics.cli.report  # noqa: F401
    from train_dynamics.physics.metrics import RunMetrics
    import train_dynamics.recording.metrics_report  # noqa: F401

    if figures:
        import train_dynamics.recording.plots  # noqa: F401

    if cfg is not None:
        metrics = RunMetrics.for_run(cfg)
        n = int(cfg.n_coaches)
        couplers, vehicles = np.zeros((2, n - 1)), np.zeros((2, n))
        metrics.add_block(np.array([0.0, 0.01]), couplers, couplers, couplers, vehicles,
                          vehicles, vehicles)
        metrics.result()


def run_metrics(bag: Path, out: Path, namespace: str = '', figures: bool = False
                ) -> dict[str, Any]:
    """
    Return the criteria's metrics of ``bag``, written into ``out`` with ``summary.md``.

    ``summary.json``'s ``train``, and its ``blending`` as ``blending.<key>``
    (:func:`~train_dynamics.testing.criteria.criteria_metrics`).

    Raises :class:`train_dynamics.cli.errors.CliError` (one line) where ``train-dynamics
    report`` would refuse the bag.
    """
    from train_dynamics.cli import report
    from train_dynamics.recording.metrics_report import summary_markdown

    args = argparse.Namespace(bag=str(bag), output=str(out), params=None, namespace=namespace,
                              coupler_force_limit=None, jerk_limit=None, quiet=True)
    if figures:
        report.cmd_report(args)
        return criteria_metrics(json.loads((out / 'summary.json').read_text(encoding='utf-8')))
    result, _, source = report.run_result(args, {}, curves=False)
    doc = {'source': {**source,
                      'figures': 'off (figures: true in the scenario to draw them)'},
           **result}
    out.mkdir(parents=True, exist_ok=True)
    _write(out / 'summary.json', json.dumps(doc, indent=2, allow_nan=False) + '\n')
    _write(out / 'summary.md', summary_markdown(doc))
    return criteria_metrics(result)


def _write(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` whole (a temporary file renamed into place)."""
    tmp = path.with_name(f'.{path.name}.{os.getpid()}')
    tmp.write_text(text, encoding='utf-8')
    os.replace(tmp, path)
