"""
The test suite's own marks (test/conftest.py): ``slow`` from a table, ``ros`` from the source.

The table of slow tests names tests that exist (a renamed test would silently fall out of it);
the ``ros`` mark follows what a test does, not what its docstring says.
"""
import ast
from pathlib import Path

import conftest

TEST_DIR = Path(__file__).resolve().parents[1]


def _test_functions() -> set[str]:
    """Return ``basename::function`` of every test function under test/."""
    found = set()
    for path in TEST_DIR.rglob('test_*.py'):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) \
                    and node.name.startswith('test_'):
                found.add(f'{path.name}::{node.name}')
    return found


def test_every_slow_entry_names_an_existing_test():
    assert conftest.SLOW_TESTS, 'the table of slow tests is empty'
    missing = sorted(set(conftest.SLOW_TESTS) - _test_functions())
    assert not missing, f'SLOW_TESTS names tests that do not exist: {missing}'


MODULE = '''
"""Docstring naming train_dynamics.ros.sim_node and --ros-args starts nothing."""
import subprocess
import sys

from train_dynamics.ros.recorder import BagWriter
from train_dynamics.ros.sim_node import main


def _start():
    return subprocess.Popen([sys.executable, '-m', 'train_dynamics.ros.sim_node'])


def test_starts_through_a_helper():
    _start()


def test_calls_the_nodes_main():
    main([])


def test_imports_rclpy_itself():
    from rclpy.serialization import serialize_message
    serialize_message


def test_only_writes_a_bag():
    """Run sim_node with --ros-args in words only."""
    BagWriter


def test_plain():
    assert 'sim_node' != 'brake_valve'
'''


def test_ros_mark_follows_the_code_not_the_words(tmp_path):
    path = tmp_path / 'test_probe.py'
    path.write_text(MODULE)
    source = conftest._RosSource(str(path))
    uses = {name: source.uses_ros(name) for name in source.functions if name.startswith('test_')}
    assert uses == {'test_starts_through_a_helper': True, 'test_calls_the_nodes_main': True,
                    'test_imports_rclpy_itself': True, 'test_only_writes_a_bag': False,
                    'test_plain': False}
