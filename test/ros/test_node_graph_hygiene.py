"""
What the nodes put into the ROS graph, and what they refuse to start with.

- ``--help`` prints the usage and exits 0 without starting rclpy or a simulation;
- a parameter file with no section for the node is an error (one line, exit 2), not a run
  of the defaults;
- the node advertises only what it publishes: ``/clock`` while ``publish_clock``,
  ``brake_reservoirs`` with the pneumatic brake;
- ``namespaced_clock`` publishes the clock in the node's namespace; a second publisher on the
  node's clock topic is warned about (two trains on one ``/clock`` run time backwards).
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock

from train_dynamics.physics.config.table import PARAMETERS
from train_dynamics.ros.node_parameters import SIM_NODE_PARAMETERS
from train_dynamics.ros.sim_node import SimNode
from train_dynamics.testing.harness import package_env

ROOT = Path(__file__).resolve().parents[2]


def _run(module: str, *args: str, timeout: float = 120.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', module, *args], env=package_env(os.environ),
                          capture_output=True, text=True, timeout=timeout)


def test_help_prints_usage_and_exits_without_starting():
    for module, prog, param in (('train_dynamics.ros.sim_node', 'sim_node', 'publish_clock'),
                                ('train_dynamics.ros.brake_valve_node', 'brake_valve',
                                 'schedule')):
        for flag in ('--help', '-h'):
            # the old node ignored the flag and simulated until stopped (the timeout)
            out = _run(module, flag, timeout=120.0)
            assert out.returncode == 0, out.stderr
            assert out.stdout.startswith(f'usage: {prog} '), out.stdout[:200]
            assert f'  {param} (' in out.stdout
            assert 'started' not in out.stdout + out.stderr          # no node, no run
    out = _run('train_dynamics.ros.sim_node', '--help')
    listed = {line.split()[0] for line in out.stdout.splitlines() if line.startswith('  ')}
    assert set(PARAMETERS) | set(SIM_NODE_PARAMETERS) <= listed


def test_params_file_with_no_section_for_the_node_is_refused(tmp_path):
    old_style = tmp_path / 'old.yaml'          # applies to /train_dynamics only
    old_style.write_text('train_dynamics:\n  ros__parameters:\n    num_coaches: 7\n')
    out = _run('train_dynamics.ros.sim_node', '--ros-args', '--params-file', str(old_style),
               '-r', '__ns:=/train1', '-p', 'real_time_factor:=0.0', '-p', 'duration:=0.05')
    assert out.returncode == 2, out.stdout + out.stderr
    err = out.stderr.strip().splitlines()
    assert len(err) == 1, err
    assert err[0].startswith('sim_node: error: parameter file ')
    assert 'no section applies to /train1/train_dynamics' in err[0]
    assert 'started' not in out.stdout + out.stderr
    valve_only = tmp_path / 'valve.yaml'
    valve_only.write_text('/**/brake_valve:\n  ros__parameters:\n    publish_rate: 20.0\n')
    out = _run('train_dynamics.ros.sim_node', '--ros-args', '--params-file', str(valve_only),
               '-p', 'duration:=0.05')
    assert out.returncode == 2 and 'no section applies to /train_dynamics' in out.stderr


def _published_topics(harness, node) -> set[str]:
    return {name for name, _ in harness.probe.get_publisher_names_and_types_by_node(
        node.get_name(), node.get_namespace())}


def test_clock_and_reservoirs_advertised_only_when_published(harness):
    node = harness.start(real_time_factor=0.0, duration=0.2)
    assert harness.wait(lambda: '/couplers' in _published_topics(harness, node), 10.0)
    names = _published_topics(harness, node)
    assert '/clock' not in names and '/brake_reservoirs' not in names, names
    harness.set_remote('train_dynamics', {'publish_clock': True})
    assert harness.wait(lambda: '/clock' in _published_topics(harness, node), 10.0)
    harness.set_remote('train_dynamics', {'publish_clock': False})
    assert harness.wait(lambda: '/clock' not in _published_topics(harness, node), 10.0)
    harness.stop(node)
    pneumatic = harness.start(real_time_factor=0.0, duration=0.2, brake_model='pneumatic')
    assert harness.wait(
        lambda: '/brake_reservoirs' in _published_topics(harness, pneumatic), 10.0)


def _train(namespace: str, **params) -> SimNode:
    return SimNode(namespace=namespace, parameter_overrides=[
        Parameter(k, value=v) for k, v in {'publish_clock': True, 'real_time_factor': 4.0,
                                           **params}.items()])


def test_namespaced_clocks_of_two_trains_stay_apart(harness):
    clocks = {ns: harness.collect(Clock, f'/{ns}/clock') for ns in ('train1', 'train2')}
    global_clock = harness.collect(Clock, '/clock')
    nodes = [_train(ns, namespaced_clock=True) for ns in ('train1', 'train2')]
    for node in nodes:
        harness.add(node)
    assert harness.wait(lambda: all(len(c) >= 20 for c in clocks.values()), 30.0)
    assert global_clock == []
    for received in clocks.values():        # each its own time, never backwards
        t = [m.clock.sec + 1e-9 * m.clock.nanosec for m in received]
        assert all(b > a for a, b in zip(t, t[1:])), t[:20]
    harness.spin_for(2.5)                   # at least one graph check of each node
    assert all(node._outputs.clock.others == 0 for node in nodes)


def test_second_clock_publisher_is_warned_about(harness, capfd):
    nodes = [_train(ns) for ns in ('train1', 'train2')]     # both on the global /clock
    for node in nodes:
        harness.add(node)
    assert harness.wait(lambda: all(n._outputs.clock.others == 1 for n in nodes), 20.0)
    err = capfd.readouterr().err
    assert err.count('other publisher(s) on /clock') == 2, err[-2000:]
