"""``sim_node``'s own parameters: declared beside the node, documented from their table."""
from __future__ import annotations

import dataclasses
from pathlib import Path

from train_dynamics.physics.config import PARAMETERS, SimConfig
from train_dynamics.ros.node_parameters import markdown_table, SIM_NODE_PARAMETERS

REPO = Path(__file__).resolve().parents[2]


def test_docs_node_parameter_table_is_current():
    """docs/ros_interface.md holds the table: python -m train_dynamics.ros.node_parameters."""
    page = (REPO / 'docs' / 'ros_interface.md').read_text(encoding='utf-8')
    assert markdown_table() in page, 'regenerate: python -m train_dynamics.ros.node_parameters'
    for name in SIM_NODE_PARAMETERS:
        assert f'| `{name}` |' in markdown_table()


def test_node_parameters_are_not_the_simulators():
    """A node parameter is neither a simulator parameter nor a field of the configuration."""
    assert not set(SIM_NODE_PARAMETERS) & set(PARAMETERS)
    fields = {f.name for f in dataclasses.fields(SimConfig)}
    assert not set(SIM_NODE_PARAMETERS) & fields
    assert all(spec.dynamic for spec in SIM_NODE_PARAMETERS.values())


def test_diagnostics_come_at_the_period_set_live(harness):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter

    node = harness.start(real_time_factor=2.0, diagnostics_period=3600.0)
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    harness.spin_for(2.0)
    assert diags == []                              # the first status is an hour away
    assert not node.set_parameters([Parameter('diagnostics_period', value=0.01)])[0].successful
    assert node.set_parameters([Parameter('diagnostics_period', value=0.1)])[0].successful
    assert harness.wait(lambda: len(diags) >= 3, 60.0)    # the new period: they come
