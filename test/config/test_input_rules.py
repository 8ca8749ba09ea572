"""The one rule for traction commands, used by sim_node and the offline replay."""
from __future__ import annotations

import math

import pytest

from train_dynamics.input_kinds import traction_rejection


@pytest.mark.parametrize('command, reason', [
    (0.0, None), (1.0, None), (-1.0, None), (0.25, None), (1.0 + 1e-12, 'out_of_range'),
    (-1.5, 'out_of_range'), (1e300, 'out_of_range'), (math.nan, 'non_finite'),
    (math.inf, 'non_finite'), (-math.inf, 'non_finite')])
def test_traction_rule(command, reason):
    why = traction_rejection(command)
    assert (why and why[0]) == reason or (why is None and reason is None)


def test_the_node_decodes_a_command_by_its_rows_rule():
    from dataclasses import replace

    from rclpy.serialization import serialize_message
    from std_msgs.msg import Float64

    from train_dynamics.input_kinds import KINDS
    from train_dynamics.ros.command_channel import decode

    calls = []

    def rule(c, cfg):
        calls.append(c)
        return ('out_of_range', 'test') if c == 0.5 else None

    kind = replace(KINDS['traction'], rule=rule)
    assert decode(kind, serialize_message(Float64(data=0.25)), None) == (0.25, None)
    with pytest.raises(ValueError) as exc:
        decode(kind, serialize_message(Float64(data=0.5)), None)
    assert exc.value.args == ('out_of_range', 'test') and calls == [0.25, 0.5]
    with pytest.raises(ValueError) as exc:       # the table's own rule: |c| <= 1
        decode(KINDS['traction'], serialize_message(Float64(data=1.5)), None)
    assert exc.value.args[0] == 'out_of_range'
    with pytest.raises(ValueError) as exc:
        decode(KINDS['traction'], b'\x00\x01', None)
    assert exc.value.args[0] == 'malformed'
