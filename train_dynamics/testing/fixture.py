"""
The pytest fixture ``train_loop``: run a controller against a scenario in the test's tmp dir.

In a ``conftest.py``: ``pytest_plugins = ['train_dynamics.testing.fixture']``; then::

    def test_my_controller(train_loop):
        result = train_loop('scenarios/stop.yaml', ['ros2', 'run', 'my_pkg', 'controller'])
        assert result.passed, result.report()

Each call runs in its own sub-directory of ``tmp_path`` (``run1``, ``run2``, ...); keyword
arguments go to :func:`train_dynamics.testing.run_scenario`.
"""
from __future__ import annotations

import pytest

from train_dynamics.testing.harness import run_scenario


@pytest.fixture
def train_loop(tmp_path):
    """Return ``run(scenario, controller, **options) -> RunResult`` (see the module)."""
    count = [0]

    def run(scenario, controller, **options):
        count[0] += 1
        return run_scenario(scenario, controller, tmp_path / f'run{count[0]}', **options)

    return run
