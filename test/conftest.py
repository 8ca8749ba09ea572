"""
Shared test setup: a private, loopback-only ROS 2 domain per test session.

Before anything imports rclpy this sets, for this process and every subprocess it starts:

- ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: DDS discovery never leaves the machine.
- SIGINT handled (children start with its default disposition) even where the session was
  started with it ignored, since tests signal the processes they start.
- ``ROS_DOMAIN_ID``: one domain per pytest session, from 1..60, held with an exclusive lock
  file (``$TMPDIR/train_dynamics_ros_domain_<id>.lock``) for the whole session, so that two
  test sessions running at once on the machine never share a domain. (61..69 are kept for
  people running nodes by hand, 70..100 for ``make run``/``bench``/``soak``.) Set
  ``TRAIN_DYNAMICS_TEST_DOMAIN_ID`` to force one.

Fixtures for tests with real rclpy (DDS on loopback, in-process):

- ``rclpy_context``: ``rclpy.init()`` on the default context before the test and
  ``rclpy.try_shutdown()`` after it; yields the context. Create nodes and executors as usual.
- ``spin_until``: ``spin_until(executor_or_node, predicate, timeout=5.0) -> bool`` spins until
  ``predicate()`` is true or ``timeout`` seconds (wall) pass.
- ``harness``: a :class:`sim_node_helpers.Harness` (nodes under test, a probe node, the
  executor), closed after the test.
- ``contract_defaults``: the product contract's parameter names and defaults.

Shared test code lives in helper modules without the ``test_`` prefix (``physics_helpers``,
``sim_node_helpers``, ``cli_helpers``, ...) in ``test/`` itself, which this file puts on
``sys.path``; the tests sit in folders that mirror the package (``test/physics``,
``test/ros``, ...) and never import from each other.

Marks, set here on collection (``pytest_collection_modifyitems``; registered in setup.cfg):

- ``ros``: the test needs rclpy or DDS: it sits in ``test/ros``, uses one of the rclpy
  fixtures below, or (read from its source and the module's functions it calls) imports
  ``rclpy`` or ``train_dynamics.ros``, starts ``sim_node``/``brake_valve`` or runs a
  controller scenario (``run_scenario``).
- ``slow``: the test is in :data:`SLOW_TESTS`, the table of the slowest tests measured.
  ``pytest -m "not slow"`` (``make test-fast``) leaves them out.
"""
from __future__ import annotations

import ast
import os
import re
import signal
import sys
import tempfile
import time

_TEST_DOMAINS = list(range(1, 61))
_domain_lock = None   # open lock file, kept for the session


def _choose_domain() -> int:
    """Lock and return a ROS domain id no other running test session on this machine uses."""
    global _domain_lock
    forced = os.environ.get('TRAIN_DYNAMICS_TEST_DOMAIN_ID')
    if forced:
        return int(forced)
    import fcntl

    start = os.getpid() % len(_TEST_DOMAINS)
    for k in range(len(_TEST_DOMAINS)):
        domain = _TEST_DOMAINS[(start + k) % len(_TEST_DOMAINS)]
        path = os.path.join(tempfile.gettempdir(), f'train_dynamics_ros_domain_{domain}.lock')
        fh = open(path, 'a')
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _domain_lock = fh
        return domain
    return _TEST_DOMAINS[start]   # all locked (unlikely): share one


os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['ROS_DOMAIN_ID'] = str(_choose_domain())

# Tests send SIGINT to the commands and nodes they start, as Ctrl-C would. A test session
# started with SIGINT ignored (a background job of a non-interactive shell: `make test &` in
# a script) passes that on to every child, which then rightly ignores it (Python installs its
# KeyboardInterrupt handler only where SIGINT is at its default). A handled signal is reset to
# its default in a child at exec: handling it here gives every child the default disposition.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
os.environ.setdefault('MPLBACKEND', 'Agg')

# The helper modules in test/ import as top-level modules from every test folder.
_TEST_DIR = os.path.dirname(os.path.abspath(__file__))
if _TEST_DIR not in sys.path:
    sys.path.insert(0, _TEST_DIR)

import pytest  # noqa: E402

#: the product contract's parameter defaults (shared/interface.md), written once
CONTRACT_DEFAULTS = {
    'model_type': 'tanh', 'num_coaches': 3, 'coach_mass': 45000.0, 'masses': [],
    'coach_length': 25.0, 'buffer_stiffness': 2.8e6, 'buffer_friction': 1.4e6,
    'draw_gear_stiffness': 5.46e6, 'draw_gear_friction': 2.43e6, 'gravity': 9.81,
    'max_cylinder_pressure': 380000.0, 'initial_speed': 44.444, 'brake_input': 'pipe_head',
    'brake_propagation_speed': 250.0, 'publish_rate': 100.0, 'real_time_factor': 1.0,
    'publish_clock': False, 'record_bag': '',
}


def pytest_report_header(config):
    return (f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}")


@pytest.fixture
def contract_defaults():
    """Return the contract's parameter defaults: {name: default}."""
    return dict(CONTRACT_DEFAULTS)


@pytest.fixture
def rclpy_context():
    """Initialise rclpy (default context) for one test; shut it down afterwards."""
    import rclpy

    rclpy.init()
    try:
        yield rclpy.get_default_context()
    finally:
        rclpy.try_shutdown()


def _spin_until(spinner, predicate, timeout: float = 5.0, step: float = 0.02) -> bool:
    """Spin ``spinner`` (an executor, or a node) until ``predicate()`` or ``timeout`` [s]."""
    import rclpy

    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() >= deadline:
            return False
        if hasattr(spinner, 'spin_once') and not hasattr(spinner, 'get_name'):
            spinner.spin_once(timeout_sec=step)
        else:
            rclpy.spin_once(spinner, timeout_sec=step)


@pytest.fixture
def spin_until():
    """Return the spin helper: ``f(executor_or_node, predicate, timeout=5.0) -> bool``."""
    return _spin_until


@pytest.fixture
def harness(rclpy_context):
    """Yield a sim_node test harness: ``sim_node_helpers.Harness``, closed after the test."""
    # imported here: only the tests with real rclpy load it (and rclpy)
    from sim_node_helpers import Harness

    h = Harness()
    try:
        yield h
    finally:
        h.close()


# -- marks ---------------------------------------------------------------------------------

#: the slowest tests, ``module basename::test name`` (every parameter of a parametrised test):
#: each took 20 s or more in a whole-suite run here (``pytest --durations``, call and setup,
#: 2 cores, loaded); ``make test-fast`` runs the others. The figure is that run's.
SLOW_TESTS = {
}

#: fixtures (here and in sim_node_helpers) that initialise rclpy
_ROS_FIXTURES = frozenset({'rclpy_context', 'spin_until', 'harness'})
#: callables that start sim_node (and a controller) as processes
_ROS_CALLS = frozenset({'run_scenario'})
#: strings in a test that start a node: its module's name, ROS arguments
_ROS_STRINGS = ('train_dynamics.ros', '--ros-args')
_REPO = os.path.dirname(_TEST_DIR)
_RCLPY_LINE = re.compile(r'^\s*(?:import|from)\s+rclpy\b', re.M)
_ROS_IMPORT = re.compile(r'^\s*from\s+(?:train_dynamics\.ros|\.)\.?(\w+)\s+import', re.M)
_LOADS_RCLPY: dict = {}


def _loads_rclpy(module: str) -> bool:
    """Whether importing ``module`` loads rclpy: rclpy, or a module of ros/ importing it."""
    if module == 'rclpy' or module.startswith('rclpy.'):
        return True
    if not module.startswith('train_dynamics.ros.'):
        return False
    if module not in _LOADS_RCLPY:
        _LOADS_RCLPY[module] = False     # an import cycle reads as "no"
        path = os.path.join(_REPO, *module.split('.')) + '.py'
        try:
            with open(path, encoding='utf-8') as fh:
                text = fh.read()
        except OSError:
            return False
        _LOADS_RCLPY[module] = bool(_RCLPY_LINE.search(text)) or any(
            _loads_rclpy(f'train_dynamics.ros.{m}') for m in _ROS_IMPORT.findall(text))
    return _LOADS_RCLPY[module]


def _ros_import(node) -> list:
    """Return the names an import statement binds to modules that load rclpy."""
    if isinstance(node, ast.Import):
        return [(a.asname or a.name).split('.')[0] for a in node.names if _loads_rclpy(a.name)]
    if isinstance(node, ast.ImportFrom) and node.module:
        if node.module == 'train_dynamics.ros':        # submodules: from ... import sim_node
            return [a.asname or a.name for a in node.names
                    if _loads_rclpy(f'train_dynamics.ros.{a.name}')]
        if _loads_rclpy(node.module):
            return [a.asname or a.name for a in node.names]
    return []


class _RosSource:
    """Which functions of a test module use rclpy or start a node (read from the source)."""

    def __init__(self, path: str):
        with open(path, encoding='utf-8') as fh:
            tree = ast.parse(fh.read(), path)
        self.ros_names = set(_ROS_CALLS)     # module-level names bound to ROS code
        self.functions = {}                  # module-level (and class-level) functions
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                self.ros_names.update(_ros_import(node))
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                self.functions[node.name] = node
            elif isinstance(node, ast.ClassDef):
                for sub in node.body:
                    if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)):
                        self.functions[f'{node.name}.{sub.name}'] = sub
        self._memo = {}

    def _direct(self, fn) -> tuple[bool, set]:
        """Return (uses ROS itself, names of the module's functions it refers to)."""
        calls = set()
        body = fn.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]                  # the docstring names nodes without starting them
        args = fn.args
        calls.update(a.arg for a in args.args + args.kwonlyargs + args.posonlyargs)
        for stmt in body:
            for node in ast.walk(stmt):
                if isinstance(node, ast.Name):
                    if node.id in self.ros_names:
                        return True, calls
                    calls.add(node.id)
                elif isinstance(node, (ast.Import, ast.ImportFrom)) and _ros_import(node):
                    return True, calls
                elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                    if any(s in node.value for s in _ROS_STRINGS):
                        return True, calls
        return False, calls

    def uses_ros(self, name: str, seen: frozenset = frozenset()) -> bool:
        """Whether function ``name`` or a module function it refers to uses ROS."""
        if name in self._memo:
            return self._memo[name]
        fn = self.functions.get(name)
        if fn is None or name in seen:
            return False
        direct, calls = self._direct(fn)
        result = direct or any(self.uses_ros(c, seen | {name}) for c in calls
                               if c in self.functions)
        self._memo[name] = result
        return result


_ROS_SOURCES: dict = {}


def _needs_ros(item) -> bool:
    """Whether a collected test needs rclpy or DDS (see the module docstring)."""
    path = str(item.fspath)
    if os.path.relpath(path, _TEST_DIR).split(os.sep)[0] == 'ros':
        return True
    if _ROS_FIXTURES & set(getattr(item, 'fixturenames', ())):
        return True
    function = getattr(item, 'function', None)
    if function is None:
        return False
    if path not in _ROS_SOURCES:
        _ROS_SOURCES[path] = _RosSource(path)
    source = _ROS_SOURCES[path]
    name = function.__qualname__
    fixtures = [f for f in getattr(item, 'fixturenames', ()) if f in source.functions]
    return source.uses_ros(name) or any(source.uses_ros(f) for f in fixtures)


def _slow_key(item) -> str:
    return f'{os.path.basename(str(item.fspath))}::{getattr(item, "originalname", item.name)}'


def pytest_collection_modifyitems(config, items):
    """Mark ``ros`` and ``slow`` tests (see the module docstring)."""
    for item in items:
        if _needs_ros(item):
            item.add_marker(pytest.mark.ros)
        if _slow_key(item) in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
