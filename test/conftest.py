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
``sim_node_helpers``); test modules never import from each other.
"""
from __future__ import annotations

import os
import signal
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
