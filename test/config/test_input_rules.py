"""The one rule for traction commands, used by sim_node and the offline replay."""
from __future__ import annotations

import math

import pytest

from train_dynamics.physics.config import traction_rejection


@pytest.mark.parametrize('command, reason', [
    (0.0, None), (1.0, None), (-1.0, None), (0.25, None), (1.0 + 1e-12, 'out_of_range'),
    (-1.5, 'out_of_range'), (1e300, 'out_of_range'), (math.nan, 'non_finite'),
    (math.inf, 'non_finite'), (-math.inf, 'non_finite')])
def test_traction_rule(command, reason):
    why = traction_rejection(command)
    assert (why and why[0]) == reason or (why is None and reason is None)


def test_node_and_offline_use_the_one_rule(monkeypatch):
    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64

    from train_dynamics.ros import traction_inputs

    calls = []

    def rule(c):
        calls.append(c)
        return ('out_of_range', 'test') if c == 0.5 else None

    monkeypatch.setattr(traction_inputs, 'traction_rejection', rule)
    assert traction_inputs.traction_command(serialize_message(Float64(data=0.25))) == 0.25
    with pytest.raises(ValueError) as exc:
        traction_inputs.traction_command(serialize_message(Float64(data=0.5)))
    assert exc.value.args == ('out_of_range', 'test') and calls == [0.25, 0.5]
