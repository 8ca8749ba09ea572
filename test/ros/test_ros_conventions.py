"""
The ROS 2 conventions users rely on: parameter files under a namespace, recorded names.

A shipped parameter file configures a namespaced ``sim_node`` (its ``/**/train_dynamics``
section); a file whose sections apply to no node of that full name is refused, by name; a
bag recorded under a namespace and a remap holds the resolved names, the offered QoS and
``ros_distro: jazzy``.
"""
from __future__ import annotations

import os
from pathlib import Path
import subprocess
import sys

from rclpy.parameter import Parameter
from ruamel.yaml import YAML
from sim_node_helpers import fluid

from train_dynamics.ros.executor import section_matches, unmatched_params_files
from train_dynamics.ros.sim_node import SimNode
from train_dynamics.testing.harness import package_env

ROOT = Path(__file__).resolve().parents[2]


def test_section_matching_follows_rcl():
    assert section_matches('/**', '/train1/train_dynamics')
    assert section_matches('/**/train_dynamics', '/train1/train_dynamics')
    assert section_matches('/**/train_dynamics', '/train_dynamics')
    assert section_matches('train_dynamics', '/train_dynamics')
    assert not section_matches('train_dynamics', '/train1/train_dynamics')
    assert section_matches('/train1/*', '/train1/train_dynamics')
    assert not section_matches('/train2/train_dynamics', '/train1/train_dynamics')
    assert not section_matches('/**/brake_valve', '/train1/train_dynamics')


def test_shipped_files_apply_under_a_namespace_and_a_mismatch_is_named(tmp_path):
    shipped = [c for c in sorted((ROOT / 'config').glob('*.yaml'))
               if 'ros__parameters' in c.read_text()]
    assert len(shipped) >= 5
    for cfg in shipped:
        assert not unmatched_params_files(['--ros-args', '--params-file', str(cfg)],
                                          '/train1/train_dynamics'), cfg
    old_style = tmp_path / 'old.yaml'
    old_style.write_text('train_dynamics:\n  ros__parameters:\n    num_coaches: 7\n')
    cmd = [sys.executable, '-m', 'train_dynamics.ros.sim_node', '--ros-args',
           '--params-file', str(ROOT / 'config' / 'passenger_loco_12.yaml'),
           '--params-file', str(old_style), '-r', '__ns:=/train1',
           '-p', 'real_time_factor:=0.0', '-p', 'duration:=0.05']
    out = subprocess.run(cmd, env=package_env(os.environ), capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 2, out.stderr               # refused: not a run without it
    log = out.stdout + out.stderr
    assert 'started' not in log
    assert f'parameter file {old_style}: no section applies to /train1/train_dynamics' in log
    assert f'parameter file {ROOT / "config"}' not in log


def test_bag_under_a_namespace_and_remap_records_resolved_names_and_qos(harness, tmp_path):
    bag = tmp_path / 'bag'
    node = SimNode(namespace='train1',
                   cli_args=['--ros-args', '-r', 'couplers:=coupler_states'],
                   parameter_overrides=[Parameter('record_bag', value=str(bag)),
                                        Parameter('wait_for_input', value=10.0),
                                        Parameter('duration', value=0.5)])
    harness.add(node)
    pub = harness.publisher('/train1/brake_pipe/pressure')
    assert harness.wait_for_subscriber(pub)
    pub.publish(fluid(4e5 + 101325.0))
    assert harness.wait(lambda: node.finished, 20.0)
    harness.stop(node)
    info = YAML(typ='safe').load((bag / 'metadata.yaml').read_text())
    info = info['rosbag2_bagfile_information']
    assert info['ros_distro'] == 'jazzy'
    topics = {t['topic_metadata']['name']: t['topic_metadata']
              for t in info['topics_with_message_count']}
    assert '/train1/coupler_states' in topics and '/train1/coaches' in topics
    assert not any(name in topics for name in ('couplers', 'coaches', '/couplers'))
    (qos,) = topics['/train1/coaches']['offered_qos_profiles']
    assert (qos['reliability'], qos['history'], qos['depth']) == ('reliable', 'keep_last', 10)
    assert '/train1/brake_pipe/pressure' in topics        # the input, resolved too
