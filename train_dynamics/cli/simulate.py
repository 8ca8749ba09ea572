"""
``train-dynamics simulate``: run the simulator offline and write a rosbag2 (MCAP).

The output bag holds, stamped with simulation time from t = 0 at ``publish_rate``:
``couplers`` and ``coaches`` (contract), ``brake_cylinders`` (JointState, name coach_i,
position = brake-cylinder gauge pressure [Pa], effort = local brake-pipe gauge pressure [Pa])
and the brake input it used (``brake_pipe/pressure`` absolute, or the input bag's messages,
re-stamped with their simulation time); :class:`train_dynamics.recording.sinks.BagSink`
writes them. Its ``metadata.yaml`` ``custom_data`` records the model, step and input. Same
inputs -> byte-identical bag. Nothing is left under the output path unless the command wrote
a complete bag (it writes a hidden sibling directory and renames it at the end), or was
stopped by SIGINT / SIGTERM: then the bag holds the whole samples up to there (its
``custom_data`` ``interrupted`` says when) and the command exits 130 / 143 with one line; a
second signal aborts at once, leaving nothing. The bag's size
is estimated before the run (:func:`train_dynamics.recording.output_specs.output_disk`): more
than the free space is refused, more than :data:`LARGE_BAG` needs ``--allow-large``. Memory
does not grow with the duration (the samples stream to the bag). A bag estimated larger than
:data:`FILE_BYTES` is written as several MCAP files (rosbag2's splitting, whole samples per
file); when the disk fills up all the same, the finished files are kept as a closed,
readable bag (``custom_data`` ``incomplete``) and the command exits 1 with one line.
"""
from __future__ import annotations

import argparse
from pathlib import Path
import shutil

from train_dynamics import topics
from train_dynamics.cli.errors import (check_runnable, CliError, deferred_signals, error,
                                       EXIT_ERROR, EXIT_FAULT, EXIT_INTERRUPT, EXIT_OK,
                                       Interrupted, PROG)
from train_dynamics.cli.output import remove_created
from train_dynamics.cli.progress import progress_bar
from train_dynamics.cli.scenario import brake_inputs, check_duration, load_config
from train_dynamics.input_kinds import KINDS
from train_dynamics.physics.config import fmt_bytes, SimConfig
from train_dynamics.recording.bags import BagError, BagRecorder, DISK_FULL, recording_failed
from train_dynamics.recording.output_specs import output_disk
from train_dynamics.recording.outputs import run_metadata
from train_dynamics.recording.sinks import BagSink
from train_dynamics.simulation.runner import InputSchedule, run_simulation

#: [bytes] a bag estimated larger than this needs ``--allow-large`` (10 GB: ~2.5 h of the
#: paper's 3 coaches, ~20 min of 100 coaches at 100 Hz)
LARGE_BAG = 10 ** 10
#: [bytes] about the largest MCAP file of a bag: a full disk loses at most the file being
#: written (a bag estimated smaller is one file)
FILE_BYTES = 128 * 2 ** 20


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add the ``simulate`` command and its options."""
    s = sub.add_parser('simulate', help='run the simulator, write a rosbag2 (MCAP)',
                       description='Run the simulator for --duration seconds of simulation time '
                       'and write the output topics to a new rosbag2 (MCAP).')
    s.add_argument('--params', required=True, metavar='FILE',
                   help='ROS 2 parameter file (train_dynamics and optional brake_valve sections)')
    s.add_argument('--input', metavar='BAG',
                   help='rosbag2 (MCAP or sqlite3) with brake-pressure inputs (FluidPressure, '
                   'absolute Pa); without it the brake_valve schedule drives the head pipe')
    s.add_argument('--duration', required=True, type=float, metavar='T',
                   help='simulated time [s], > 0')
    s.add_argument('--output', required=True, metavar='BAG', help='new rosbag2 directory')
    s.add_argument('--namespace', default='', metavar='NS',
                   help='read the input topics under this namespace (e.g. /train1)')
    s.add_argument('--allow-large', action='store_true',
                   help=f'write a bag estimated larger than {fmt_bytes(LARGE_BAG)} (never more '
                   'than the free space)')
    s.add_argument('-q', '--quiet', action='store_true', help='no progress bar, no summary')
    s.set_defaults(func=cmd_simulate)


def cmd_simulate(args: argparse.Namespace) -> int:
    """Run ``simulate``; return the exit status."""
    duration = check_duration(args.duration)
    out = Path(args.output)
    if out.exists() or out.is_symlink():
        raise CliError(f'output {out} exists already; choose a new path (nothing was written)')
    parent = out.resolve().parent
    if parent.exists() and not parent.is_dir():
        raise CliError(f'{parent} is not a directory')
    cfg = load_config(args.params)
    check_runnable(cfg, args.params)
    inputs = brake_inputs(args, cfg)
    need = _check_disk(cfg, duration, inputs, parent, args.allow_large)
    split = duration * FILE_BYTES / need if need > FILE_BYTES else None
    created, rec = _open_recorder(out, parent, split)
    last = [0.0]                                         # [s] of the last sample written
    try:
        rec.update_custom_data(_model_info(cfg, inputs, duration))
        sink = BagSink(rec, cfg)
        if inputs.valve is not None:
            rec.add_topic(topics.HEAD_PIPE_TOPIC, topics.FLUID_PRESSURE)
        for topic in dict.fromkeys(e.topic for e in inputs.events):
            rec.add_topic(topic, topics.FLUID_PRESSURE)
        for topic, kind in dict.fromkeys((e.topic, e.kind) for e in inputs.commands):
            rec.add_topic(topic, KINDS[kind].msgtype)
        with deferred_signals() as signals:
            def on_sample(s):
                sink.sample(s)
                last[0] = s.t
                signals.check()                          # stop between two whole samples

            sim = run_simulation(cfg, duration, inputs, on_sample=on_sample,
                                 on_input=sink.input,
                                 progress=progress_bar('simulate', duration, args.quiet))
        rec.close()
    except Interrupted as stop:
        _keep_interrupted(rec, out, created, stop, last[0])
    except OSError as exc:
        if exc.errno not in DISK_FULL:
            rec.abort()
            remove_created(created)
            raise
        _keep_disk_full(rec, out, created, exc, last[0])
    except BaseException:
        rec.abort()
        remove_created(created)
        raise
    if sim.fault is not None:
        error(f'simulation fault: {sim.fault}; {out} holds the run up to t = {sim.t:.3f} s')
        return EXIT_FAULT
    if not args.quiet:
        print(f'wrote {out} ({cfg.n_coaches} coaches, {cfg.model_type}, {duration:g} s, '
              f'input: {inputs.source})')
    return EXIT_OK


def _keep_interrupted(rec: BagRecorder, out: Path, created: list[Path], stop: Interrupted,
                      t: float) -> None:
    """Close the bag of a run stopped by a signal (its samples up to ``t`` [s]); raise."""
    try:
        rec.set_custom_data('interrupted', f'{stop} at t = {t!r} s')
        rec.close()
    except BaseException:
        rec.abort()
        remove_created(created)
        raise
    what = 'interrupted' if stop.code == EXIT_INTERRUPT else 'terminated'
    raise CliError(f'{what} ({stop}) at t = {t:.3f} s; {out} holds the run up to there',
                   stop.code)


def _keep_disk_full(rec: BagRecorder, out: Path, created: list[Path], exc: OSError,
                    t: float) -> None:
    """Keep the finished files of a bag whose disk filled up at ``t`` [s]; raise (exit 1)."""
    what = exc.strerror or str(exc)
    try:
        rec.keep(f'{what} at t = {t!r} s')
    except BaseException:
        remove_created(created)
        raise CliError(f'{what} at t = {t:.3f} s: nothing could be kept of {out}',
                       EXIT_ERROR) from None
    raise CliError(recording_failed(out, f'{what} at t = {t:.3f} s', rec.saved, rec.given,
                                    rec.saved_until_ns) + '; free some space or shorten the run',
                   EXIT_ERROR)


def _check_disk(cfg: SimConfig, duration: float, inputs: InputSchedule, parent: Path,
                allow_large: bool) -> int:
    """
    Return the bag's estimated size [bytes].

    Refuse a run whose bag would not fit, or exceed :data:`LARGE_BAG` unconfirmed.
    """
    need = output_disk(cfg, duration, head_input=inputs.valve is not None,
                       traction_commands=len(inputs.commands)) + sum(
        len(e.msg.header.frame_id) + 80 for e in inputs.events)
    where = parent
    while not where.exists():
        where = where.parent
    free = shutil.disk_usage(where).free
    if need > free:
        raise CliError(f'the bag would need about {fmt_bytes(need)} ({duration:g} s of '
                       f'{cfg.n_coaches} coaches at {cfg.publish_rate:g} Hz), {where} has '
                       f'{fmt_bytes(free)} free; shorten --duration or lower publish_rate')
    if need > LARGE_BAG and not allow_large:
        raise CliError(f'the bag would need about {fmt_bytes(need)} ({duration:g} s of '
                       f'{cfg.n_coaches} coaches at {cfg.publish_rate:g} Hz), more than '
                       f'{fmt_bytes(LARGE_BAG)}: add --allow-large to write it anyway')
    return need


def _open_recorder(out: Path, parent: Path, split: float | None = None
                   ) -> tuple[list[Path], BagRecorder]:
    """Create the missing parent folders and an atomic recorder (files of ``split`` s)."""
    created = []            # parent folders to create (and to remove again on failure)
    p = parent
    while not p.exists():
        created.append(p)
        p = p.parent
    try:
        for d in reversed(created):
            d.mkdir()
        return created, BagRecorder(out, atomic=True, file_stem=out.name, split_seconds=split)
    except (BagError, FileExistsError, OSError) as exc:
        remove_created(created)
        raise CliError(str(exc)) from None


def _model_info(cfg: SimConfig, inputs: InputSchedule, duration: float) -> dict[str, str]:
    """Return the bag's ``custom_data``: the run's metadata and the valve schedule used."""
    info = run_metadata(cfg, f'{PROG} simulate', input=inputs.source,
                        duration=repr(float(duration)))
    if inputs.valve is not None:
        info['brake_valve_schedule'] = ', '.join(
            f'{e.time:g}:{e.position}' for e in inputs.valve.schedule)
    return info
