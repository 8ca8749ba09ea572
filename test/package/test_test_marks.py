"""
The test suite's own marks and workers (test/conftest.py).

``slow`` and the ``machine`` group come from tables that name tests that exist (a renamed test
would silently fall out of them); the ``ros`` mark follows what a test does, not what its
docstring says; parallel workers never share a ROS domain.
"""
import ast
import os
from pathlib import Path
import subprocess
import sys

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


def test_every_machine_entry_names_an_existing_module_or_test():
    assert conftest.MACHINE_TABLE, 'the table of machine-hungry tests is empty'
    functions = _test_functions()
    modules = {name.split('::')[0] for name in functions}
    missing = sorted(f'{module}::{test}' for module, tests in conftest.MACHINE_TABLE.items()
                     for test in ([] if tests == conftest.ALL else tests)
                     if f'{module}::{test}' not in functions)
    missing += sorted(set(conftest.MACHINE_TABLE) - modules)
    assert not missing, f'MACHINE_TABLE names tests that do not exist: {missing}'


#: a worker's start, as pytest-xdist makes it: conftest imported with PYTEST_XDIST_WORKER set;
#: it prints its domain and holds it until its stdin closes
_WORKER = ('import os, sys, conftest; print(os.environ["ROS_DOMAIN_ID"], flush=True); '
           'sys.stdin.read()')


def _domains(workers, **env) -> list[int]:
    """Return the ROS domains that workers ``gw<k>`` (``workers``) take, all running at once."""
    base = {k: v for k, v in os.environ.items() if k != 'TRAIN_DYNAMICS_TEST_DOMAIN_ID'}
    procs = [subprocess.Popen([sys.executable, '-c', _WORKER], cwd=TEST_DIR, text=True,
                              env={**base, **env, 'PYTEST_XDIST_WORKER': f'gw{k}'},
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE)
             for k in workers]
    try:
        return [int(p.stdout.readline()) for p in procs]
    finally:
        for p in procs:
            p.stdin.close()
            p.wait(timeout=60)


def test_parallel_workers_hold_domains_of_their_own():
    """Three workers at once, beside this session: four domains."""
    domains = _domains(range(3))
    assert len(set(domains) | {int(os.environ['ROS_DOMAIN_ID'])}) == 4, domains


def test_a_forced_domain_is_the_first_worker_s_and_the_next_ones_follow():
    """TRAIN_DYNAMICS_TEST_DOMAIN_ID=40: worker gw<k> takes 40 + k, not 40 for every worker."""
    assert _domains([0, 1, 3], TRAIN_DYNAMICS_TEST_DOMAIN_ID='40') == [40, 41, 43]


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
