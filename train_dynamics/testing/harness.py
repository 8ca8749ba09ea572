"""
The controller-in-the-loop harness: a scenario, ``sim_node`` in lock-step, the user's node.

A scenario file (YAML)::

    parameters_file: ../config/some_train.yaml   # optional, relative to the scenario file
    parameters:                                  # optional: sim_node parameters on top
      initial_speed: 10.0
    duration: 20.0                               # [s] simulation time
    criteria:                                    # optional (train_dynamics.testing.criteria)
      stopped: {equals: true}
      stopping_distance: {max: 120.0}

:func:`run_scenario` writes the node's parameters (``/**/train_dynamics`` section) into the
run's directory, starts the controller's command, then ``sim_node`` with ``sync_mode``
lockstep, ``real_time_factor`` 0, ``duration`` and ``record_bag`` ``bag`` (relative to the run
directory, so that two runs' bags are byte-identical), waits for the node to finish, stops the
controller (SIGINT, then SIGKILL), computes the metrics with ``train-dynamics report`` and
checks the criteria. Both processes inherit the environment (``ROS_DOMAIN_ID``, ...), with
this ``train_dynamics`` first on ``PYTHONPATH``; the controller runs in the caller's working
directory, the node in the run directory.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
from typing import Any, Mapping, Sequence

from train_dynamics import topics
from train_dynamics.physics.config import ConfigError
from train_dynamics.testing.criteria import Criterion, CriterionResult, parse_criteria
import yaml

BAG = 'bag'                  # the bag's name in the run directory
PARAMS = 'scenario_params.yaml'
STOP_GRACE = 5.0             # [s wall] a stopping process gets this long before SIGKILL
SCENARIO_KEYS = ('parameters_file', 'parameters', 'duration', 'criteria')


@dataclass
class Scenario:
    """A scenario: sim_node parameters, a duration and acceptance criteria."""

    duration: float
    parameters: dict[str, Any] = field(default_factory=dict)
    parameters_file: Path | None = None
    criteria: list[Criterion] = field(default_factory=list)
    name: str = 'scenario'

    @classmethod
    def load(cls, path: str | os.PathLike) -> Scenario:
        """Read a scenario file; raise :class:`ConfigError` (one line) when it is wrong."""
        path = Path(path)
        try:
            doc = yaml.safe_load(path.read_text(encoding='utf-8'))
        except (OSError, yaml.YAMLError) as exc:
            raise ConfigError(f'{path}: {exc}') from None
        if not isinstance(doc, Mapping) or 'duration' not in doc:
            raise ConfigError(f'{path}: a scenario is a mapping with at least duration')
        unknown = set(doc) - set(SCENARIO_KEYS)
        if unknown:
            raise ConfigError(f'{path}: unknown key(s) {", ".join(sorted(unknown))} (known: '
                              f'{", ".join(SCENARIO_KEYS)})')
        pfile = doc.get('parameters_file')
        try:
            return cls(duration=float(doc['duration']),
                       parameters=dict(doc.get('parameters') or {}),
                       parameters_file=(path.parent / pfile).resolve() if pfile else None,
                       criteria=parse_criteria(doc.get('criteria')), name=path.stem)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f'{path}: {exc}') from None


@dataclass
class RunResult:
    """A finished run: its bag, metrics and the criteria's verdicts."""

    directory: Path
    bag: Path
    returncode: int                    # sim_node's exit status
    metrics: dict[str, Any]            # summary.json's ``train`` (empty if none)
    results: list[CriterionResult]
    error: str = ''                    # why the run itself failed ('' if it did not)

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
                 timeout: float = 300.0, env: Mapping[str, str] | None = None) -> RunResult:
    """
    Run ``controller`` (a command; None: one started elsewhere) against ``scenario``.

    ``directory`` (created; must not hold a bag yet) receives the bag ``bag``, the logs
    ``sim_node.log`` and ``controller.log``, and the metrics report ``report/``.
    ``namespace``: both nodes run under it (``-r __ns:=`` is appended to the controller's
    command). ``timeout`` [s wall]: the whole run; then both are stopped and the run failed.
    """
    if not isinstance(scenario, Scenario):
        scenario = Scenario.load(scenario)
    run_dir = Path(directory)
    run_dir.mkdir(parents=True, exist_ok=True)
    params_file = run_dir / PARAMS
    section = {f'/**/{topics.NODE_NAME}': {'ros__parameters': dict(scenario.parameters)}}
    params_file.write_text(yaml.safe_dump(section, sort_keys=False), encoding='utf-8')
    environ = package_env(os.environ if env is None else env)
    ctl = None
    logs = []
    try:
        if controller:
            cmd = list(controller) + (['--ros-args', '-r', f'__ns:={namespace}']
                                      if namespace else [])
            logs.append(open(run_dir / 'controller.log', 'wb'))
            ctl = subprocess.Popen(cmd, env=environ, stdout=logs[-1],
                                   stderr=subprocess.STDOUT)
        logs.append(open(run_dir / 'sim_node.log', 'wb'))
        sim = subprocess.Popen(
            sim_node_command(scenario, params_file.resolve(), namespace, real_time_factor,
                             lockstep_timeout),
            cwd=run_dir, env=environ, stdout=logs[-1], stderr=subprocess.STDOUT)
        error = ''
        try:
            code = sim.wait(timeout)
        except subprocess.TimeoutExpired:
            _stop(sim)
            code = sim.returncode
            error = f'sim_node did not finish within {timeout:g} s (wall)'
    finally:
        if ctl is not None:
            _stop(ctl)
        for fh in logs:
            fh.close()
    bag = run_dir / BAG
    if not error and code != 0:
        tail = (run_dir / 'sim_node.log').read_text(errors='replace').strip().splitlines()[-3:]
        error = f'sim_node exited with status {code}: ' + ' | '.join(tail)
    metrics = _metrics(bag, run_dir / 'report', namespace) if bag.exists() else {}
    if not metrics and not error:
        error = 'no metrics (see report.log)'
    results = [c.check(metrics) for c in scenario.criteria]
    return RunResult(run_dir, bag, code, metrics, results, error)


def package_env(env: Mapping[str, str]) -> dict[str, str]:
    """Return ``env`` with this ``train_dynamics`` first on PYTHONPATH (the nodes run it)."""
    root = str(Path(__file__).resolve().parents[2])
    path = [p for p in env.get('PYTHONPATH', '').split(os.pathsep) if p and p != root]
    return {**env, 'PYTHONPATH': os.pathsep.join([root] + path)}


def _stop(proc: subprocess.Popen) -> None:
    """Stop ``proc``: SIGINT, then SIGKILL after :data:`STOP_GRACE` s."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(STOP_GRACE)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _metrics(bag: Path, out: Path, namespace: str) -> dict[str, Any]:
    """Return the run metrics of ``bag`` (``train-dynamics report``), {} if there are none."""
    cmd = [sys.executable, '-m', 'train_dynamics.cli.offline', 'report', str(bag),
           '--output', str(out), '-q'] + (['--namespace', namespace] if namespace else [])
    with open(out.parent / 'report.log', 'wb') as log:
        subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT, check=False)
    try:
        return json.loads((out / 'summary.json').read_text())['train']
    except (OSError, ValueError, KeyError):
        return {}
