"""``train-dynamics``: the offline command (simulate, plot, compare) on the node's model code.

    train-dynamics simulate --params FILE [--input BAG] --duration T --output BAG
    train-dynamics plot BAG --output DIR
    train-dynamics compare --params FILE --duration T --output DIR
                           [--scale-factors 100,1000,10000] [--steps 0.001,0.0001]

``simulate`` runs :class:`train_dynamics.physics.train.TrainSimulator` (the class ``sim_node`` runs)
as fast as the machine allows. Brake input:

* ``--input BAG`` (MCAP or sqlite3 rosbag2): the contract's input topics
  (``brake_pipe/pressure``, ``coach_<i>/brake_pipe/pressure``,
  ``coach_<i>/brake_cylinder/pressure``; ``sensor_msgs/FluidPressure``, ABSOLUTE Pa; a leading
  '/' and a ``--namespace`` prefix are accepted); only those of the file's ``brake_input`` are
  used. A message takes effect at its bag time relative to the bag's first message, at the
  first integration step starting at or after that time, and holds until the next one
  (zero-order hold), exactly as the node applies a message at its next step.
* no input bag (``pipe_head`` only): the head-pipe pressure follows the ``brake_valve``
  section of the same parameter file (the ``brake_valve`` node's schedule and rates, see
  :mod:`train_dynamics.physics.brake_valve`), sampled at every integration step; without that
  section: emergency braking at t = 1 s.

The output bag (MCAP) holds, stamped with simulation time from t = 0 at ``publish_rate``:
``couplers`` and ``coaches`` (contract), ``brake_cylinders`` (JointState, name coach_i,
position = brake-cylinder gauge pressure [Pa], effort = local brake-pipe gauge pressure [Pa])
and the brake input it used (``brake_pipe/pressure`` absolute, or the input bag's messages,
re-stamped with their simulation time). Its ``metadata.yaml`` ``custom_data`` records the
model, step and input. Same inputs -> byte-identical bag.

Errors print one line ``train-dynamics: error: ...`` and exit with 2 (bad input: parameter
file, bag, duration, existing output) or 1 (anything else); a simulation fault (diverged
state) keeps the bag up to the fault and exits 3; Ctrl-C exits 130, SIGTERM 143. Nothing is left under
the output path unless the command wrote a complete bag (it writes a hidden sibling
directory and renames it at the end).
"""
from __future__ import annotations

import argparse
import math
import os
import re
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.runner import (BrakeInputs, InputEvent, Sample, run_simulation,
                                           step_of)
from train_dynamics.recording.outputs import OutputEncoder, run_metadata, time_ns

PROG = 'train-dynamics'
EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_FAULT, EXIT_INTERRUPT, EXIT_TERMINATED = 0, 1, 2, 3, 130, 143

#: input topic patterns (relative names) -> (brake_input mode, has coach index)
INPUT_TOPICS = {
    'pipe_head': re.compile(r'brake_pipe/pressure'),
    'pipe_per_coach': re.compile(r'coach_(\d+)/brake_pipe/pressure'),
    'cylinder_per_coach': re.compile(r'coach_(\d+)/brake_cylinder/pressure'),
}
FLUID_PRESSURE = 'sensor_msgs/msg/FluidPressure'
JOINT_STATE = 'sensor_msgs/msg/JointState'
DEFAULT_VALVE_SCHEDULE = ['0.0:release', '1.0:emergency']


class CliError(Exception):
    """A one-line error for the user; ``code`` is the exit status."""

    def __init__(self, message: str, code: int = EXIT_USAGE) -> None:
        super().__init__(' '.join(str(message).split()))
        self.code = code


def _warn(text: str) -> None:
    print(f'{PROG}: warning: {text}', file=sys.stderr)


# -- brake inputs ------------------------------------------------------------------------------

def read_input_bag(path: str, cfg, *, namespace: str = '') -> BrakeInputs:
    """The events of ``cfg.brake_input`` from a bag; :class:`CliError` if none is usable."""
    from train_dynamics.recording.bags import BagError, bag_info, read_topics

    mode = cfg.brake_input
    pattern = INPUT_TOPICS[mode]
    ns = namespace.strip('/')
    try:
        info = bag_info(path)
    except BagError as exc:
        raise CliError(f'input bag: {exc}') from None
    selected: dict[str, int | None] = {}
    other_modes = []
    for topic, (msgtype, count) in info.topics.items():
        rel = topic
        if ns:
            if not topic.startswith(ns + '/'):
                continue
            rel = topic[len(ns) + 1:]
        m = pattern.fullmatch(rel)
        if m is None:
            if any(p.fullmatch(rel) for p in INPUT_TOPICS.values()):
                other_modes.append(rel)
            continue
        if msgtype != FLUID_PRESSURE:
            _warn(f'input bag: {topic} has type {msgtype}, not {FLUID_PRESSURE}; ignored')
            continue
        if count == 0:
            continue
        index = None
        if m.groups():
            i = int(m.group(1))
            if not 1 <= i <= cfg.n_coaches:
                _warn(f'input bag: {topic} names coach {i}, the train has coaches '
                      f'1..{cfg.n_coaches}; ignored')
                continue
            index = i - 1
        selected[topic] = index
    if not selected:
        want = {'pipe_head': 'brake_pipe/pressure',
                'pipe_per_coach': 'coach_<i>/brake_pipe/pressure',
                'cylinder_per_coach': 'coach_<i>/brake_cylinder/pressure'}[mode]
        hint = f' (it has {", ".join(sorted(other_modes))}: set brake_input to match)' \
            if other_modes else ''
        raise CliError(f'input bag {path}: no usable input topic for brake_input {mode}: '
                       f'needs {want} ({FLUID_PRESSURE}){hint}')
    if mode != 'pipe_head':
        have = {i for i in selected.values()}
        missing = [i + 1 for i in range(cfg.n_coaches) if i not in have]
        if missing:
            held = 'pipe_nominal_pressure' if mode == 'pipe_per_coach' else '0 Pa'
            _warn(f'input bag: no input for coach(es) {_ranges(missing)}; held at {held}')
    atm = float(cfg.atmospheric_pressure)
    h = float(cfg.integration_step)
    events: list[InputEvent] = []
    rejected = 0
    try:
        for topic, t_ns, msg in read_topics(path, list(selected)):
            p = float(msg.fluid_pressure)
            if not math.isfinite(p) or p < 0.0:
                rejected += 1
                continue
            rel_ns = t_ns - info.start_ns
            rel_topic = topic[len(ns) + 1:] if ns else topic
            events.append(InputEvent(step_of(rel_ns, h), rel_ns, selected[topic], p - atm,
                                     rel_topic, msg))
    except BagError as exc:
        raise CliError(f'input bag: {exc}') from None
    if rejected:
        _warn(f'input bag: {rejected} message(s) with a non-finite or negative absolute '
              'pressure rejected')
    if not events:
        raise CliError(f'input bag {path}: no usable input message for brake_input {mode}')
    events.sort(key=lambda e: e.t_ns)           # stable: bag order for equal times
    return BrakeInputs(mode, events, None, f'bag {Path(path).name}')


def _ranges(numbers: Sequence[int]) -> str:
    out, start, prev = [], None, None
    for n in list(numbers) + [None]:
        if start is None:
            start = prev = n
        elif n is not None and n == prev + 1:
            prev = n
        else:
            out.append(str(start) if start == prev else f'{start}-{prev}')
            start = prev = n
    return ','.join(out)


def valve_from_param_file(path: str, cfg):
    """The brake valve of the ``brake_valve`` section (strict); default emergency at t = 1 s.

    The valve's running and full-service pressures default to the simulator's, so that a
    released valve leaves the distributors released.
    """
    from train_dynamics.physics.brake_valve import BrakeValveModel
    from train_dynamics.physics.parameters import ConfigError, read_param_file

    try:
        params = dict(read_param_file(path, 'brake_valve'))
    except ConfigError as exc:
        raise CliError(str(exc)) from None
    if 'schedule' not in params and 'position' not in params:
        params['schedule'] = list(DEFAULT_VALVE_SCHEDULE)
    params.setdefault('pipe_nominal_pressure', float(cfg.pipe_nominal_pressure))
    params.setdefault('full_service_pressure', float(cfg.full_service_pressure))
    try:
        return BrakeValveModel.from_params(params, strict=True)
    except ValueError as exc:
        raise CliError(f'{path}: brake_valve: {exc}') from None


# -- the run loop ------------------------------------------------------------------------------

class BagSink:
    """Writes the output topics of each sample (and the inputs used) to a BagRecorder.

    Messages are encoded with :mod:`train_dynamics.recording.bags`'s direct CDR encoders (the same bytes
    rosbags would write, several times faster).
    """

    def __init__(self, rec, cfg) -> None:
        from train_dynamics.recording import bags as bagio

        self.bagio = bagio
        self.rec = rec
        self.atm = float(cfg.atmospheric_pressure)
        self.encoder = OutputEncoder(cfg.n_coaches)
        for topic in topics.OUTPUT_TOPICS:
            rec.add_topic(topic, topics.JOINT_STATE)

    def sample(self, s: Sample) -> None:
        write = self.rec.write
        t_ns = time_ns(s.t)
        for topic, data in zip(topics.OUTPUT_TOPICS, self.encoder.encode(t_ns, s.sim)):
            write(topic, t_ns, data)
        if s.head_gauge is not None:
            write(topics.HEAD_PIPE_TOPIC, t_ns,
                  self.bagio.encode_fluid_pressure(t_ns, s.head_gauge + self.atm))

    def input(self, e: InputEvent) -> None:
        b = self.bagio
        msg = e.msg
        msg.header.stamp = b.stamp(e.t_ns, ns=True)
        self.rec.write_msg(e.topic, e.t_ns, msg)


class ArraySink:
    """Collects y, ydot, F (and x, v, Fb) of each sample into arrays (for ``compare``)."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.x: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.fb: list[np.ndarray] = []

    def sample(self, s: Sample) -> None:
        self.t.append(s.t)
        self.x.append(s.sim.x)
        self.v.append(s.sim.v)
        self.fb.append(s.sim.brake_force)

    def history(self, sim, label: str = ''):
        """A :class:`train_dynamics.recording.plots.History` (F from the simulator's force law)."""
        from train_dynamics.physics import couplers
        from train_dynamics.recording.plots import History, JointSeries

        t = np.asarray(self.t)
        x, v = np.asarray(self.x), np.asarray(self.v)
        y, yd = x[:, :-1] - x[:, 1:], v[:, :-1] - v[:, 1:]
        m = y.shape[1]
        tile = lambda a: np.tile(a, len(t))             # noqa: E731
        force = couplers.coupler_force(y.ravel(), yd.ravel(), tile(sim.ke), tile(sim.kf),
                                       tile(sim.kec), tile(sim.kfc), sim.model, sim.u
                                       ).reshape(len(t), m)
        n = x.shape[1]
        cp = JointSeries(t, [f'coupler_{i}' for i in range(1, n)], y, yd, force)
        co = JointSeries(t, [f'coach_{i}' for i in range(1, n + 1)], x, v, np.asarray(self.fb))
        return History(couplers=cp, coaches=co, label=label)


class Progress:
    """A one-line progress bar on stderr (only when stderr is a terminal)."""

    def __init__(self, label: str, total_s: float, enabled: bool | None = None) -> None:
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.label, self.total = label, total_s
        self.start = time.monotonic()
        self.last = 0.0
        self.done = False

    def __call__(self, frac: float) -> None:
        if not self.enabled or self.done:
            return
        self.done = frac >= 1.0
        now = time.monotonic()
        if frac < 1.0 and now - self.last < 0.1:
            return
        self.last = now
        width = 30
        fill = int(round(frac * width))
        elapsed = now - self.start
        rate = frac * self.total / elapsed if elapsed > 0 else 0.0
        sys.stderr.write(f'\r{self.label} [{"#" * fill}{"." * (width - fill)}] {frac * 100:5.1f} % '
                         f't = {frac * self.total:7.2f}/{self.total:g} s  {rate:6.1f}x real time ')
        if frac >= 1.0:
            sys.stderr.write('\n')
        sys.stderr.flush()


# -- commands ----------------------------------------------------------------------------------

def _load_config(path: str):
    from train_dynamics.physics.parameters import ConfigError, load_param_file

    if not Path(path).is_file():
        raise CliError(f'parameter file not found: {path}')
    try:
        return load_param_file(path)
    except ConfigError as exc:
        raise CliError(str(exc)) from None


def _check_duration(duration: float) -> float:
    if not math.isfinite(duration) or duration <= 0.0:
        raise CliError(f'--duration must be a finite number > 0 s, got {duration:g}')
    return duration


def _inputs_for(args, cfg) -> BrakeInputs:
    if args.input:
        return read_input_bag(args.input, cfg, namespace=args.namespace)
    if cfg.brake_input != 'pipe_head':
        raise CliError(f'brake_input {cfg.brake_input} needs --input BAG with its pressures '
                       '(without an input bag only pipe_head, driven by the brake_valve '
                       'section, is possible)')
    return BrakeInputs('pipe_head', [], valve_from_param_file(args.params, cfg),
                       'brake_valve schedule')


def _model_info(cfg, inputs: BrakeInputs, duration: float) -> dict[str, str]:
    info = run_metadata(cfg, 'train-dynamics simulate', input=inputs.source,
                        duration=repr(float(duration)))
    if inputs.valve is not None:
        info['brake_valve_schedule'] = ', '.join(
            f'{e.time:g}:{e.position}' for e in inputs.valve.schedule)
    return info


def cmd_simulate(args) -> int:
    from train_dynamics.recording.bags import BagError, BagRecorder

    duration = _check_duration(args.duration)
    out = Path(args.output)
    if out.exists() or out.is_symlink():
        raise CliError(f'output {out} exists already; choose a new path (nothing was written)')
    parent = out.resolve().parent
    if parent.exists() and not parent.is_dir():
        raise CliError(f'{parent} is not a directory')
    cfg = _load_config(args.params)
    inputs = _inputs_for(args, cfg)
    missing = []            # parent folders to create (and to remove again on failure)
    p = parent
    while not p.exists():
        missing.append(p)
        p = p.parent
    try:
        for d in reversed(missing):
            d.mkdir()
        rec = BagRecorder(out, atomic=True, file_stem=out.name)
    except (BagError, FileExistsError, OSError) as exc:
        _remove_empty(missing)
        raise CliError(str(exc)) from None
    try:
        for key, value in _model_info(cfg, inputs, duration).items():
            rec.set_custom_data(key, value)
        sink = BagSink(rec, cfg)
        if inputs.valve is not None:
            rec.add_topic('brake_pipe/pressure', FLUID_PRESSURE)
        for topic in dict.fromkeys(e.topic for e in inputs.events):
            rec.add_topic(topic, FLUID_PRESSURE)
        progress = Progress('simulate', duration, None if not args.quiet else False)
        sim = run_simulation(cfg, duration, inputs, on_sample=sink.sample, on_input=sink.input,
                             progress=progress)
        rec.close()
    except BaseException:
        rec.abort()
        _remove_empty(missing)
        raise
    if sim.fault is not None:
        print(f'{PROG}: error: simulation fault: {sim.fault}; {out} holds the run up to '
              f't = {sim.t:.3f} s', file=sys.stderr)
        return EXIT_FAULT
    if not args.quiet:
        print(f'wrote {out} ({cfg.n_coaches} coaches, {cfg.model_type}, {duration:g} s, '
              f'input: {inputs.source})')
    return EXIT_OK


def _remove_empty(folders) -> None:
    """Remove the folders this run created (innermost first), if they are still empty."""
    for d in folders:
        try:
            d.rmdir()
        except OSError:
            pass


def cmd_plot(args) -> int:
    from train_dynamics.recording.bags import BagError
    from train_dynamics.recording.plots import PlotError, plot_bag

    if not Path(args.bag).exists():
        raise CliError(f'bag not found: {args.bag}')
    try:
        paths = plot_bag(args.bag, args.output, namespace=args.namespace, title=args.title)
    except (BagError, PlotError) as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f'cannot write figures to {args.output}: {exc.strerror or exc}',
                       EXIT_ERROR) from None
    if not args.quiet:
        for p in paths:
            print(p)
    return EXIT_OK


def _parse_floats(text: str, what: str) -> list[float]:
    try:
        vals = [float(v) for v in text.split(',') if v.strip()]
    except ValueError:
        raise CliError(f'{what}: expected comma-separated numbers, got {text!r}') from None
    if not vals or not all(math.isfinite(v) and v > 0 for v in vals):
        raise CliError(f'{what}: expected numbers > 0, got {text!r}')
    return vals


def _fmt_step(h: float) -> str:
    return f'{h * 1e3:g} ms'


def cmd_compare(args) -> int:
    from train_dynamics.physics.parameters import ConfigError
    from train_dynamics.recording.plots import plot_comparison, sign_changes_per_second

    duration = _check_duration(args.duration)
    base = _load_config(args.params)
    inputs = _inputs_for(args, base)
    us = _parse_floats(args.scale_factors, '--scale-factors')
    h0 = float(base.integration_step)
    steps = _parse_floats(args.steps, '--steps') if args.steps else [h0, h0 / 10.0]
    # every run is sampled on the same grid: the finest of the sign runs' steps, at most 10 kHz
    variants: list[tuple[str, dict]] = []
    variants += [(f'sign, h = {_fmt_step(h)}', {'model_type': 'sign', 'integration_step': h})
                 for h in steps]
    variants += [(f'tanh, u = {u:g} s/m, h = {_fmt_step(h0)}',
                  {'model_type': 'tanh', 'scale_factor': u}) for u in us]
    out = Path(args.output)
    runs = []
    table = []
    for label, change in variants:
        try:
            cfg = base.replace(**change)
        except ConfigError as exc:
            raise CliError(f'{label}: {exc}') from None
        h = float(cfg.integration_step)
        dt_sample = max(h, 1.0 / args.sample_rate)
        n = int(math.floor(duration / dt_sample + 1e-9))
        sample_steps = sorted({int(math.floor(j * dt_sample / h + 0.5)) for j in range(n + 1)})
        if inputs.events:
            run_inputs = BrakeInputs(inputs.mode, [
                InputEvent(step_of(e.t_ns, h), e.t_ns, e.index, e.gauge, e.topic, e.msg)
                for e in inputs.events], None, inputs.source)
        else:
            run_inputs = inputs
        sink = ArraySink()
        t0 = time.monotonic()
        sim = run_simulation(cfg, duration, run_inputs, on_sample=sink.sample,
                             sample_steps=sample_steps,
                             progress=Progress(f'{label:<34}', duration,
                                               None if not args.quiet else False))
        wall = time.monotonic() - t0
        if sim.fault is not None:
            _warn(f'{label}: simulation fault: {sim.fault}')
        hist = sink.history(sim, label)
        runs.append((label, hist))
        c = hist.couplers
        changes = sign_changes_per_second(c.t, c.velocity, tol=0.0)
        for j, name in enumerate(c.names):
            table.append((label, name, float(np.nanmax(c.effort[:, j])) * 1e-3,
                          float(np.nanmin(c.effort[:, j])) * 1e-3, changes[j], wall))
    zoom = _zoom_window(runs, duration)
    sampling = ('curves sampled at every integration step'
                if 1.0 / args.sample_rate <= min(steps + [h0]) * (1 + 1e-9) else
                f'curves sampled every {_fmt_step(1.0 / args.sample_rate)} (or step)')
    title = (f'{base.n_coaches} coaches, {Path(args.params).name}, brake input: '
             f'{inputs.source}; {sampling}')
    try:
        paths = plot_comparison(runs, out, title=title, zoom=zoom)
    except OSError as exc:
        raise CliError(f'cannot write figures to {out}: {exc.strerror or exc}',
                       EXIT_ERROR) from None
    print(f'{"run":<34} {"coupler":<10} {"max F [kN]":>11} {"min F [kN]":>11} '
          f'{"ydot sign changes/s":>20} {"wall [s]":>9}')
    for label, name, fmax, fmin, ch, wall in table:
        print(f'{label:<34} {name:<10} {fmax:11.2f} {fmin:11.2f} {ch:20.1f} {wall:9.2f}')
    if not args.quiet:
        for p in paths:
            print(p)
    return EXIT_OK


def _zoom_window(runs, duration: float, width: float = 0.2) -> tuple[float, float, int]:
    """(t0, t1, coupler index): the ``width`` [s] with the most ydot sign flips of a sign run."""
    best, where, coupler = -1, duration / 2, 0
    for label, hist in runs:
        if not label.startswith('sign'):
            continue
        c = hist.couplers
        for j in range(c.velocity.shape[1]):
            s = np.sign(c.velocity[:, j])
            keep = s != 0
            ts, s = c.t[keep], s[keep]
            tf = ts[1:][s[1:] != s[:-1]]
            if tf.size == 0:
                continue
            counts = np.searchsorted(tf, tf + width) - np.arange(tf.size)
            k = int(np.argmax(counts))
            if counts[k] > best:
                span = tf[k:k + counts[k]]
                best, where, coupler = int(counts[k]), float(span[0] + span[-1]) / 2, j
    half = min(width, duration) / 2
    t0 = min(max(0.0, where - half), max(0.0, duration - 2 * half))
    return t0, t0 + 2 * half, coupler


# -- entry point ---------------------------------------------------------------------------------

class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2 (argparse's own convention)
        self.print_usage(sys.stderr)
        raise CliError(message)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog=PROG, description='Longitudinal train dynamics, offline: simulate, plot '
                'and compare coupler models (the sim_node model, as fast as possible).')
    p.add_argument('--version', action='version', version=f'%(prog)s {_version()}')
    sub = p.add_subparsers(dest='command', required=True, metavar='COMMAND', parser_class=_Parser)

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
    s.add_argument('-q', '--quiet', action='store_true', help='no progress bar, no summary')
    s.set_defaults(func=cmd_simulate)

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

    c = sub.add_parser('compare', help='sign vs tanh (several u), sign at several steps',
                       description='The paper\'s comparison: the same scenario with the sign '
                       'model at several integration steps and the tanh model at several scale '
                       'factors u; one figure per quantity and a table on stdout.')
    c.add_argument('--params', required=True, metavar='FILE', help='ROS 2 parameter file')
    c.add_argument('--input', metavar='BAG', help='brake-input bag (as for simulate)')
    c.add_argument('--duration', required=True, type=float, metavar='T',
                   help='simulated time [s], > 0')
    c.add_argument('--output', required=True, metavar='DIR', help='directory for the PNGs')
    c.add_argument('--scale-factors', default='100,1000,10000', metavar='U,U,...',
                   help='tanh scale factors u [s/m] (default 100,1000,10000)')
    c.add_argument('--steps', default=None, metavar='H,H,...',
                   help='integration steps [s] for the sign model (default: the file\'s step '
                   'and a tenth of it)')
    c.add_argument('--sample-rate', type=float, default=10000.0, metavar='HZ',
                   help='sampling of the curves [Hz] (default 10000, at most one per step)')
    c.add_argument('--namespace', default='', metavar='NS', help='input topics namespace')
    c.add_argument('-q', '--quiet', action='store_true', help='no progress bar, no file list')
    c.set_defaults(func=cmd_compare)
    return p


def _version() -> str:
    from train_dynamics import __version__
    return __version__


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    previous = _install_sigterm()
    try:
        args = parser.parse_args(argv)
        if getattr(args, 'sample_rate', 1.0) <= 0 or not math.isfinite(
                getattr(args, 'sample_rate', 1.0)):
            raise CliError('--sample-rate must be > 0')
        return args.func(args)
    except CliError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return exc.code
    except SystemExit as exc:          # --help, --version
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        print(f'{PROG}: interrupted', file=sys.stderr)
        return EXIT_INTERRUPT
    except BrokenPipeError:
        return EXIT_ERROR
    except _Terminated:
        print(f'{PROG}: terminated', file=sys.stderr)
        return EXIT_TERMINATED
    except Exception as exc:  # noqa: BLE001 - last resort: still one line
        text = ' '.join(str(exc).split()) or type(exc).__name__
        print(f'{PROG}: error: {type(exc).__name__}: {text}', file=sys.stderr)
        if os.environ.get('TRAIN_DYNAMICS_DEBUG'):
            raise
        return EXIT_ERROR
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)


class _Terminated(BaseException):
    """SIGTERM, raised like KeyboardInterrupt so that partial output is cleaned up."""


def _install_sigterm():
    if threading.current_thread() is not threading.main_thread():
        return None

    def handler(signum, frame):
        raise _Terminated()

    try:
        return signal.signal(signal.SIGTERM, handler)
    except (ValueError, OSError):
        return None


if __name__ == '__main__':
    sys.exit(main())
