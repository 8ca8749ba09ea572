"""
``sim_node``'s one configuration: a set makes a new immutable one, the run's own never changes.

The node holds the configuration of its parameter values (live and pending alike); the
simulator keeps the one it was built from, untouched by live sets (they reach the run through
its setters) until the reset service builds the next run from the node's.
"""
from __future__ import annotations

from rclpy.parameter import Parameter


def test_a_live_set_makes_a_new_configuration_and_leaves_the_runs_alone(harness):
    node = harness.start(real_time_factor=2.0)
    built = node.simulator.cfg
    before = built.values
    held = node.config
    assert held.values == before
    live = [Parameter('model_type', value='sign'), Parameter('scale_factor', value=50.0)]
    assert node.set_parameters_atomically(live).successful
    assert node.set_parameters([Parameter('initial_speed', value=10.0)])[0].successful
    # the node's configuration: a new object holding both changes; the old one untouched
    cfg = node.config
    assert cfg is not held and held.values == before
    assert (cfg.model_type, cfg.scale_factor, cfg.initial_speed) == ('sign', 50.0, 10.0)
    # the run: its configuration as built, the live change in the simulator itself
    assert node.simulator.cfg is built and built.values == before
    assert built.scale_factor == 1000.0 and built.model_type == 'tanh'
    assert (node.simulator.model_type, node.simulator.u) == ('sign', 50.0)
    assert node.pending_changes() == 'initial_speed: 44.444 -> 10'
    # a refused batch leaves the node's configuration as it was
    assert not node.set_parameters([Parameter('scale_factor', value=-1.0)])[0].successful
    assert node.config is cfg

    resp = harness.reset()
    assert resp.success, resp.message
    rebuilt = node.simulator.cfg
    assert rebuilt is not built and node.pending_changes() == ''
    assert (rebuilt.model_type, rebuilt.scale_factor, rebuilt.initial_speed) == \
        ('sign', 50.0, 10.0)
    assert node.config.values == rebuilt.values
