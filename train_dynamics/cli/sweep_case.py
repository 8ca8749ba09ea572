"""
One case of a sweep, as a Dask worker runs it: the offline simulator and the run metrics.

:func:`run_case` is what ``train-dynamics simulate`` does (:func:`train_dynamics.physics.
runner.run_simulation` with the same brake inputs), with
:class:`train_dynamics.physics.metrics.RunMetrics` as the sink (and the bag writer of
``simulate`` with ``--keep-bags``). It returns the case's row; it never raises: an
exception or a numerical fault is the row's ``error``. No Dask here (the function is
pickled by reference and imported on the workers).
"""
from __future__ import annotations

from pathlib import Path
import shutil
import time
import traceback
from typing import Any

from train_dynamics import topics
from train_dynamics.cli import simulate
from train_dynamics.cli.errors import check_runnable, CliError
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.metrics import FLAT_KEYS
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.metrics_report import run_metrics
from train_dynamics.recording.outputs import parameters_json
from train_dynamics.recording.sinks import BagSink
from train_dynamics.simulation.runner import InputSchedule, run_simulation


def failed_row(index: int, error: str) -> dict[str, Any]:
    """Return the row of a case that produced no metrics."""
    row: dict[str, Any] = {'case': index}
    row.update(dict.fromkeys(FLAT_KEYS))
    row.update({'fault_time': None, 'error': error, 'wall_s': 0.0})
    return row


class _Metrics:
    """The run's metrics, made at the first sample from the simulator it runs."""

    def __init__(self, cfg: SimConfig) -> None:
        self.cfg, self.metrics = cfg, None

    def sample(self, s: Any) -> None:
        if self.metrics is None:
            self.metrics = run_metrics(self.cfg, s.sim)
        self.metrics.sample(s)


def run_case(index: int, params: dict[str, Any], duration: float, inputs: InputSchedule,
             bag: str | None = None) -> dict[str, Any]:
    """Run one case; return {'case', metrics of FLAT_KEYS, 'fault_time', 'error', 'wall_s'}."""
    t0 = time.perf_counter()
    try:
        cfg = SimConfig.from_dict(params)
        check_runnable(cfg)                  # a refused configuration: 'invalid parameters'
        sink = _Metrics(cfg)
        if bag is None:
            sim = run_simulation(cfg, duration, inputs, on_sample=sink.sample)
        else:
            sim = _run_with_bag(cfg, duration, inputs, sink, Path(bag))
    except CliError as exc:               # as the plan's cases of invalid parameters
        return failed_row(index, str(exc))
    except Exception as exc:  # noqa: B902 - a failing case is a row, not a crashed sweep
        text = ' '.join(str(exc).split()) or type(exc).__name__
        row = failed_row(index, f'{type(exc).__name__}: {text}')
        row['traceback'] = traceback.format_exc(limit=5)
        return row
    if sim.fault is not None:
        row = failed_row(index, f'simulation fault: {sim.fault}')
        row['fault_time'] = sim.t
    else:
        row = {'case': index, **sink.metrics.flat(), 'fault_time': None, 'error': ''}
    row['wall_s'] = time.perf_counter() - t0
    return row


def _run_with_bag(cfg: SimConfig, duration: float, inputs: InputSchedule, sink: _Metrics,
                  out: Path):
    """Run as ``simulate`` does, writing its bag to ``out`` (replaced if a try left one)."""
    if out.exists():
        shutil.rmtree(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    rec = BagRecorder(out, atomic=True, file_stem=out.name)
    try:
        for key, value in simulate._model_info(cfg, inputs, duration).items():
            rec.set_custom_data(key, value)
        rec.set_custom_data('parameters', parameters_json(cfg))
        bags = BagSink(rec, cfg)
        if inputs.valve is not None:
            rec.add_topic(topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE)
        for topic in dict.fromkeys(e.topic for e in inputs.events):
            rec.add_topic(topic, topics.FLUID_PRESSURE)

        def both(s):
            bags.sample(s)
            sink.sample(s)

        sim = run_simulation(cfg, duration, inputs, on_sample=both, on_input=bags.input)
        rec.close()
    except BaseException:
        rec.abort()
        raise
    return sim
