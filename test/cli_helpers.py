"""
Helpers of the tests of refused parameters and consists: the offline command in-process.

``run_cli``: its exit status and stderr lines; ``params_file``: a ROS 2 parameter file of both
nodes; ``assert_one_line_error``: exit 2 with one ``train-dynamics: error:`` line.
"""
from __future__ import annotations

from pathlib import Path

from train_dynamics.cli import offline as cli


def run_cli(capsys, *args) -> tuple[int, list[str]]:
    """Run the offline command in-process; return its status and its stderr lines."""
    code = cli.main([str(a) for a in args])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    return code, err


def params_file(path: Path, sim: str = '', valve: str = '', raw: str = '') -> Path:
    text = raw or ('train_dynamics:\n  ros__parameters:\n    num_coaches: 3\n' + sim)
    if valve:
        text += 'brake_valve:\n  ros__parameters:\n' + valve
    path.write_text(text)
    return path


def assert_one_line_error(code: int, err: list[str]) -> None:
    assert code == 2, err
    assert len(err) == 1 and err[0].startswith('train-dynamics: error: '), err
