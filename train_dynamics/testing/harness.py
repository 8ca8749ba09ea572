"""
The controller-in-the-loop harness: a scenario, ``sim_node`` in lock-step, the user's node.

:func:`run_scenario` checks the scenario (:class:`~train_dynamics.testing.scenario.Scenario`)
and its own options, refuses an output folder that is not empty, writes the node's parameters
(``/**/train_dynamics`` section) and the controller's (``controller_parameters``, a ``/**``
section) into the run folder, starts the controller's command (``--ros-args --params-file
controller_params.yaml`` appended when there are controller parameters, ``-r __ns:=NS`` with
a namespace), then ``sim_node`` with ``sync_mode`` lockstep, ``real_time_factor`` 0,
``duration`` and ``record_bag`` ``bag`` (relative to the run folder, so that two runs' bags
are byte-identical), each in its own session (:class:`~.processes.ProcessGroup`).

It waits (on process events, not polling) until the node ends, or the controller ends first
(a controller that exits with an error status, or is killed, ends the run at once, reported
as the controller's failure; one that exits with status 0 leaves the node
``lockstep_timeout`` + :data:`CONTROLLER_EXIT_GRACE` seconds to finish by itself), or
``timeout`` passes. On every path (pass, fail, timeout, exception, Ctrl-C) both process
groups are then ended as a whole (SIGINT; SIGTERM, then SIGKILL, to what is left). The run
metrics are computed in this process (:mod:`~train_dynamics.testing.summary`; figures only
when asked) and the criteria checked. Both processes inherit the environment
(``ROS_DOMAIN_ID``, ...), with this ``train_dynamics`` first on ``PYTHONPATH``; the
controller runs in the caller's working directory, the node in the run folder.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import shutil
import signal
import sys
import threading
import time
from typing import Any, Iterator, Mapping, Sequence

from train_dynamics import topics
from train_dynamics.physics.config import ConfigError, PARAMETERS, validate_value
from train_dynamics.quoting import clip, quote
from train_dynamics.ros.node_parameters import SIM_NODE_PARAMETERS
from train_dynamics.testing.criteria import CriterionResult
from train_dynamics.testing.processes import POLL, ProcessGroup, STOP_GRACE, wait_any
from train_dynamics.testing.scenario import controller_params_document, Scenario
from train_dynamics.testing.summary import preload, run_metrics
import yaml

__all__ = ['BAG', 'run_scenario', 'RunResult', 'Scenario', 'sim_node_command']

BAG = 'bag'                  # the bag's name in the run directory
PARAMS = 'scenario_params.yaml'
CONTROLLER_PARAMS = 'controller_params.yaml'
#: [s wall] a controller that exited with status 0 leaves the node lockstep_timeout + this
#: to finish by itself (it may have quit after answering the last output)
CONTROLLER_EXIT_GRACE = 10.0
#: [s wall] how often a controller whose own process exited 0 is checked for live children
GROUP_POLL = 0.5


@dataclass
class RunResult:
    """A finished run: its bag, metrics and the criteria's verdicts."""

    directory: Path
    bag: Path
    returncode: int | None             # sim_node's exit status (None: never started)
    metrics: dict[str, Any]            # summary.json's ``train``, blending.<key> (empty: none)
    results: list[CriterionResult]
    error: str = ''                    # why the run itself failed ('' if it did not)
    controller_returncode: int | None = None     # the controller command's exit status
    timings: dict[str, float] = field(default_factory=dict)    # [s wall] per phase
    #: the process group ids, ``controller`` and ``sim_node`` (ended when the run returns)
    process_groups: dict[str, int] = field(default_factory=dict)

    @property
    def passed(self) -> bool:
        """Return True if the run ended normally and every criterion passed."""
        return not self.error and all(r.passed for r in self.results)

    @property
    def failed(self) -> list[str]:
        """Return the metrics of the failed criteria."""
        return [r.criterion.metric for r in self.results if not r.passed]

    def report(self) -> str:
        """Return the pass/fail report: one line per criterion, then the verdict."""
        lines = [r.text for r in self.results]
        if self.error:
            lines.append(f'FAIL run: {self.error}')
        lines.append(f'{"PASSED" if self.passed else "FAILED"} ({len(self.results)} criteria; '
                     f'bag {self.bag})')
        return '\n'.join(lines)


def sim_node_command(scenario: Scenario, params_file: Path, namespace: str = '',
                     real_time_factor: float = 0.0, lockstep_timeout: float = 10.0
                     ) -> list[str]:
    """Return the command that runs ``sim_node`` for ``scenario`` in lock-step."""
    cmd = [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args']
    if scenario.parameters_file is not None:
        cmd += ['--params-file', str(scenario.parameters_file)]
    cmd += ['--params-file', str(params_file)]
    if namespace:
        cmd += ['-r', f'__ns:={namespace}']
    for name, value in (('sync_mode', 'lockstep'), ('real_time_factor', real_time_factor),
                        ('duration', scenario.duration), ('record_bag', BAG),
                        ('lockstep_timeout', lockstep_timeout),
                        ('lockstep_on_timeout', 'stop')):
        cmd += ['-p', f'{name}:={value}']
    return cmd


def run_scenario(scenario: Scenario | str | os.PathLike, controller: Sequence[str] | None,
                 directory: str | os.PathLike, *, namespace: str = '',
                 real_time_factor: float = 0.0, lockstep_timeout: float = 10.0,
                 timeout: float = 300.0, env: Mapping[str, str] | None = None,
                 figures: bool | None = None) -> RunResult:
    """
    Run ``controller`` (a command; None: one started elsewhere) against ``scenario``.

    ``directory`` (created; an existing one must be empty, else :class:`ConfigError` before
    anything runs) receives the bag ``bag``, the logs ``sim_node.log`` and
    ``controller.log``, and the metrics report ``report/``. ``namespace``: both nodes run
    under it. ``timeout`` [s wall]: the whole run; then both are stopped and the run failed.
    ``figures``: draw the report's figures (default: the scenario's ``figures``, off).
    A wrong scenario, option or controller command raises :class:`ConfigError` (one line)
    before anything runs.
    """
    t0 = time.monotonic()
    if not isinstance(scenario, Scenario):
        scenario = Scenario.load(scenario)
    else:
        scenario.check()
    lockstep_timeout, real_time_factor, timeout = _check_options(
        lockstep_timeout, real_time_factor, timeout)
    environ = package_env(os.environ if env is None else env)
    cmd = _controller_command(controller, environ)
    run_dir = prepare_directory(directory)
    params_file = run_dir / PARAMS
    section = {f'/**/{topics.NODE_NAME}': {'ros__parameters': dict(scenario.parameters)}}
    params_file.write_text(yaml.safe_dump(section, sort_keys=False), encoding='utf-8')
    if cmd is not None:
        ros_args = []
        if scenario.controller_parameters:
            path = (run_dir / CONTROLLER_PARAMS).absolute()
            path.write_text(yaml.safe_dump(controller_params_document(
                scenario.controller_parameters), sort_keys=False), encoding='utf-8')
            ros_args += ['--params-file', str(path)]
        if namespace:
            ros_args += ['-r', f'__ns:={namespace}']
        cmd += ['--ros-args'] + ros_args if ros_args else []
    figures = scenario.figures if figures is None else bool(figures)
    timings = {'check': time.monotonic() - t0}
    ctl = sim = None
    code = ctl_code = None
    metrics: dict[str, Any] = {}
    error = ''
    try:
        t1 = time.monotonic()
        if cmd is not None:
            ctl = _start('controller', cmd, run_dir / 'controller.log', environ, None)
        sim = _start('sim_node', sim_node_command(scenario, params_file.absolute(), namespace,
                                                  real_time_factor, lockstep_timeout),
                     run_dir / 'sim_node.log', environ, run_dir)
        threading.Thread(target=_preload, args=(scenario.config, figures), daemon=True,
                         name='harness-preload').start()
        error = _supervise(sim, ctl, timeout, lockstep_timeout)
        timings['loop'] = time.monotonic() - t1
        if ctl is not None:
            ctl.signal(signal.SIGINT)        # stops while the metrics are computed
        code = sim.returncode
        if not error and code != 0:
            error = f'sim_node {sim.describe_exit()}: {sim.tail()}'
        if not error:
            t2 = time.monotonic()
            try:
                # figures only when asked: the seam's signature of before still works
                metrics = (_metrics(run_dir / BAG, run_dir / 'report', namespace, figures=True)
                           if figures else _metrics(run_dir / BAG, run_dir / 'report', namespace))
            except Exception as exc:  # noqa: B902 - a refused or unreadable bag fails the run
                error = f'no metrics: {clip(str(exc))}'
            timings['metrics'] = time.monotonic() - t2
    finally:
        t3 = time.monotonic()
        with _signals_deferred():
            end_all([g for g in (ctl, sim) if g is not None])
        timings['stop'] = time.monotonic() - t3
    groups = {g.name: g.pid for g in (ctl, sim) if g is not None}
    if ctl is not None:
        ctl_code = ctl.returncode
    code = sim.returncode if sim is not None else None
    if error:
        results = [CriterionResult(c, None, False, f'FAIL {c.describe()}: not checked (the '
                                   'run failed)') for c in scenario.criteria]
    else:
        results = [c.check(metrics) for c in scenario.criteria]
    timings['total'] = time.monotonic() - t0
    return RunResult(run_dir, run_dir / BAG, code, metrics, results, error, ctl_code, timings,
                     groups)


def _metrics(bag: Path, out: Path, namespace: str, figures: bool = False) -> dict[str, Any]:
    """Return the run metrics of ``bag`` (:func:`.summary.run_metrics`; tests replace this)."""
    return run_metrics(bag, out, namespace, figures)


def _check_options(lockstep_timeout: Any, real_time_factor: Any, timeout: Any
                   ) -> tuple[float, float, float]:
    """Return the options checked by the node's table (and ``timeout`` finite > 0)."""
    lockstep_timeout = validate_value('lockstep_timeout', lockstep_timeout,
                                      SIM_NODE_PARAMETERS)
    real_time_factor = validate_value('real_time_factor', real_time_factor, PARAMETERS)
    if isinstance(timeout, bool) or not isinstance(timeout, (int, float)) or \
            not math.isfinite(timeout) or timeout <= 0:
        raise ConfigError(f'timeout: expected a finite number of seconds > 0, got '
                          f'{quote(timeout)}')
    return lockstep_timeout, real_time_factor, float(timeout)


def _controller_command(controller: Sequence[str] | None, env: Mapping[str, str]
                        ) -> list[str] | None:
    """Return the controller's command as a list; refuse one that cannot be started."""
    if controller is None:
        return None
    if isinstance(controller, (str, bytes)) or not all(isinstance(a, str) for a in controller) \
            or not controller:
        raise ConfigError(f'controller: expected a command as a list of strings, got '
                          f'{quote(controller)}')
    cmd = list(controller)
    if shutil.which(cmd[0], path=env.get('PATH', os.defpath)) is None:
        raise ConfigError(f'controller: command not found or not executable: {quote(cmd[0])}')
    return cmd


def prepare_directory(directory: str | os.PathLike) -> Path:
    """
    Return the run folder, created; refuse one that already holds anything.

    A reused folder would mix two runs (the node refuses an existing bag, and the metrics
    would be read from the earlier run's): the harness never deletes files, it asks for a
    new or empty folder.
    """
    path = Path(directory)
    if path.exists() or path.is_symlink():
        if not path.is_dir():
            raise ConfigError(f'output folder {path}: exists and is not a folder')
        if next(path.iterdir(), None) is not None:
            raise ConfigError(f'output folder {path}: not empty (an earlier run?); the harness '
                              'writes a new run into a new or empty folder only')
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f'output folder {path}: {exc.strerror or exc}') from None
    return path


def package_env(env: Mapping[str, str]) -> dict[str, str]:
    """Return ``env`` with this ``train_dynamics`` first on PYTHONPATH (the nodes run it)."""
    root = str(Path(__file__).resolve().parents[2])
    path = [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p and p != root]
    return {**env, 'PYTHONPATH': os.pathsep.join([root] + path)}


def _start(name: str, cmd: list[str], log: Path, env: Mapping[str, str],
           cwd: Path | None) -> ProcessGroup:
    try:
        return ProcessGroup(name, cmd, log=log, env=env, cwd=cwd)
    except OSError as exc:
        raise ConfigError(f'{name}: cannot start {quote(cmd[0])}: {exc.strerror or exc}'
                          ) from None


def _supervise(sim: ProcessGroup, ctl: ProcessGroup | None, timeout: float,
               lockstep_timeout: float) -> str:
    """
    Wait until sim_node ends; return '' or why the run failed (controller gone, timeout).

    Event-based: the wait wakes when either command exits; a controller whose own process
    exited 0 but left processes of its group running (a wrapper that forked) is looked at
    every :data:`GROUP_POLL` s.
    """
    start = time.monotonic()
    deadline = start + timeout
    gone_at = None                  # when the controller was found gone
    grace_end = math.inf
    while sim.returncode is None:
        now = time.monotonic()
        if ctl is not None and gone_at is None and ctl.returncode is not None:
            if ctl.returncode != 0:
                return _controller_gone(ctl, sim, start)
            if not ctl.members():
                gone_at = now
                grace_end = now + lockstep_timeout + CONTROLLER_EXIT_GRACE
        if now >= grace_end:
            return _controller_gone(ctl, sim, start)
        if now >= deadline:
            return (f'sim_node did not finish within {timeout:g} s (wall)'
                    + (f'; {_controller_gone(ctl, sim, start)}' if gone_at else ''))
        wake = min(deadline, grace_end) - now
        watched = [sim]
        if ctl is not None and ctl.returncode is None:
            watched.append(ctl)
        elif ctl is not None and gone_at is None:
            wake = min(wake, GROUP_POLL)
        wait_any(watched, max(wake, POLL))
    if ctl is not None and sim.returncode != 0 and ctl.returncode is not None and (
            ctl.returncode != 0 or not ctl.members()) and ctl.exited_at is not None and \
            sim.exited_at is not None and ctl.exited_at <= sim.exited_at:
        return _controller_gone(ctl, sim, start)
    return ''


def _controller_gone(ctl: ProcessGroup, sim: ProcessGroup, start: float) -> str:
    """Return the line: the controller ended before the run, what it and sim_node said."""
    at = (ctl.exited_at or time.monotonic()) - start
    text = (f'the controller {ctl.describe_exit()} {at:.1f} s after the start, before the run '
            f'ended (controller.log: {ctl.tail() or "empty"})')
    if sim.returncode is not None and sim.returncode != 0:
        text += f'; sim_node then {sim.describe_exit()}'
    return text


def end_all(groups: Sequence[ProcessGroup], grace: float = STOP_GRACE) -> None:
    """
    End every process of ``groups``: SIGINT to all at once; SIGTERM after ``grace`` s, SIGKILL.

    A group already interrupted (the controller, while the metrics were computed) is not
    interrupted twice (a second SIGINT may cut a ROS 2 node's shutdown short).
    """
    try:
        for g in groups:
            if g.alive() and not g.interrupted:
                g.signal(signal.SIGINT)
        end = time.monotonic() + grace
        for g in groups:
            g.stop(max(end - time.monotonic(), 0.0))
    finally:
        for g in groups:
            g.close()


@contextlib.contextmanager
def _signals_deferred() -> Iterator[None]:
    """
    Hold SIGINT (Ctrl-C) and a Python-handled SIGTERM back while the processes are ended.

    A signal that came meanwhile is handed to its handler afterwards (KeyboardInterrupt for
    SIGINT), so that it is not lost and does not cut the ending short. Main thread only (the
    only one Python runs signal handlers in).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    held = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        handler = signal.getsignal(sig)
        if callable(handler):
            held[sig] = signal.signal(sig, lambda signum, frame: caught.append(signum))
    try:
        yield
    finally:
        for sig, handler in held.items():
            signal.signal(sig, handler)
        if caught:
            held[caught[0]](caught[0], None)


def _preload(cfg: Any, figures: bool) -> None:
    """Import and warm the report's code while the loop runs (errors surface in the report)."""
    try:
        preload(cfg, figures)
    except Exception:  # noqa: B902 - run_metrics imports them again and reports the error
        pass
