"""
One CommandChannel per row of the input table: what the row says is what the channel does.

No DDS: the channel is given a stand-in node (it subscribes, the test calls the callbacks with
serialised messages) and a stand-in simulator that records the setter calls. What differs
between the kinds (fail-safe, staleness policy, train line, stamped answers) comes from
their rows of ``train_dynamics/input_kinds.py``.
"""
from __future__ import annotations

from dataclasses import replace
import time
from types import SimpleNamespace

import pytest
from rclpy.serialization import serialize_message
from sensor_msgs.msg import FluidPressure
from std_msgs.msg import Float64, Int8

from train_dynamics.input_kinds import KINDS
from train_dynamics.ros.command_channel import CommandChannel

CFG = SimpleNamespace(external_forces=True, consist=SimpleNamespace(commanded=[0, 2]),
                      n_coaches=3, wsp='external', ep_commanded=True, blending='none',
                      atmospheric_pressure=101325.0, brake_input='pipe_head',
                      pipe_nominal_pressure=5e5)


class Node:
    """The part of an rclpy node a channel uses; keeps the callbacks by topic."""

    def __init__(self):
        self.callbacks = {}
        self.logged = []

    def get_logger(self):
        return SimpleNamespace(warning=self.logged.append, info=self.logged.append)

    def resolve_topic_name(self, rel):
        return '/' + rel

    def create_subscription(self, cls, name, cb, qos, raw=True):
        self.callbacks[name] = cb
        return SimpleNamespace(topic_name=name, get_publisher_count=lambda: 1)

    def destroy_subscription(self, sub):
        del self.callbacks[sub.topic_name]


class Sim:
    """A simulator that records the setter calls (``t`` [s])."""

    t = 1.0

    def __init__(self):
        self.calls = []

    def __getattr__(self, name):
        return lambda *args: self.calls.append((name, *args))


def _channel(kind):
    node, rejected, records = Node(), [], []
    ch = CommandChannel(kind, node, None, lambda *a: rejected.append(a))
    ch.start(CFG)
    return ch, node, rejected, records


def test_a_channel_takes_the_vehicles_of_its_row_and_refuses_by_its_rule():
    ch, node, rejected, records = _channel(KINDS['traction'])
    assert sorted(node.callbacks) == ['/coach_1/traction/command', '/coach_3/traction/command']
    node.callbacks['/coach_3/traction/command'](serialize_message(Float64(data=-0.5)))
    node.callbacks['/coach_1/traction/command'](serialize_message(Float64(data=1.5)))
    sim = Sim()
    ch.apply(time.monotonic(), sim, lambda *r: records.append(r), 0.0, False)
    assert sim.calls == [('set_traction_command', -0.5, 2)]
    assert [r[:2] for r in records] == [('coach_3/traction/command', 'std_msgs/msg/Float64')]
    assert [r[:2] for r in rejected] == [('/coach_1/traction/command', 'out_of_range')]


@pytest.mark.parametrize('policy_emergency', [False, True])
def test_a_stale_valve_falls_to_normal_whatever_the_policy_a_traction_command_by_it(
        policy_emergency):
    for name, value, msg, setter in (('wsp', 2, Int8(data=2), 'set_wsp_valve'),
                                     ('traction', 0.5, Float64(data=0.5),
                                      'set_traction_command')):
        ch, node, _, records = _channel(KINDS[name])
        topic = sorted(node.callbacks)[0]
        node.callbacks[topic](serialize_message(msg))
        sim = Sim()
        ch.apply(time.monotonic(), sim, lambda *r: records.append(r), 1.0, policy_emergency)
        assert sim.calls == [(setter, value, 0)]
        ch.apply(time.monotonic() + 5.0, sim, lambda *r: records.append(r), 1.0,
                 policy_emergency)
        failsafe = name == 'wsp' or policy_emergency
        assert ch.stale_names == [topic[1:]]
        assert ch.emergency == failsafe
        assert sim.calls[1:] == ([(setter, 0, 0)] if failsafe else [])
        node.callbacks[topic](serialize_message(msg))       # fresh again: the value holds
        ch.apply(time.monotonic(), sim, lambda *r: records.append(r), 1.0, policy_emergency)
        assert sim.calls[-1] == (setter, value, 0) and not ch.emergency


def test_a_silent_ep_command_loses_the_train_line_until_the_next():
    ch, node, _, records = _channel(KINDS['ep'])
    node.callbacks['/brake_ep/command'](serialize_message(Float64(data=0.4)))
    sim = Sim()
    ch.apply(time.monotonic(), sim, lambda *r: records.append(r), 1.0, False)
    ch.apply(time.monotonic() + 5.0, sim, lambda *r: records.append(r), 1.0, False)
    assert sim.calls == [('set_ep_command', 0.4), ('set_train_line', False)]
    assert ch.stale_names == [] and ch.max_age(time.monotonic()) == 0.0   # not reported
    node.callbacks['/brake_ep/command'](serialize_message(Float64(data=0.4)))
    ch.apply(time.monotonic(), sim, lambda *r: records.append(r), 1.0, False)
    assert sim.calls[-2:] == [('set_ep_command', 0.4), ('set_train_line', True)]


def _stamped(t_ns, pressure=2e5):
    msg = FluidPressure(fluid_pressure=pressure)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
    return serialize_message(msg)


def test_a_stamped_kind_answers_the_output_of_its_header_stamp():
    """A row saying ``stamped``: its messages answer by header stamp, not by arrival."""
    kind = replace(KINDS[CFG.brake_input], name='stamped_command', family='test')
    ch, node, _, records = _channel(kind)
    ch.dedupe = True
    ch.output_published(3_000_000_000)           # arrival after this output does not matter
    node.callbacks['/brake_pipe/pressure'](_stamped(2_000_000_000))
    node.callbacks['/brake_pipe/pressure'](_stamped(2_000_000_000, 3e5))   # a second answer
    sim = Sim()
    ch.apply(time.monotonic(), sim, lambda *r: records.append(r), 0.0, False)
    assert sim.calls == [('set_head_pipe_pressure', 2e5 - CFG.atmospheric_pressure)]
    assert ch.duplicates == 1
    assert ch.unanswered(2_000_000_000) == []
    assert ch.unanswered(3_000_000_000) == ['brake_pipe/pressure']
    assert ch.unanswered(1_500_000_000, clock=True) == []    # stamped at or after it
    assert ch.unanswered(2_500_000_000, clock=True) == ['brake_pipe/pressure']
