"""
The lock-step start: t = 0 is released on events, with a fixed settle only where one is needed.

With echo answers (the default) the node releases t = 0 as soon as the controller is
connected both ways as the node sees it (a publisher on each declared input, a reader of the
outputs): the answer to the outputs of t = 0 is itself the proof that the controller has
them (reliable outputs are kept for a matched reader until it acknowledges them), so no
fixed wait is added. With ``lockstep_answer`` clock the outputs of t = 0 are not awaited:
they get :data:`~train_dynamics.ros.run_control.CONNECT_SETTLE` s of wall time to reach a
controller whose reader discovers the node later. Checked on the gate itself, with the wall
clock given by the test (no timing measured).
"""
from __future__ import annotations

from types import SimpleNamespace

from train_dynamics.ros import run_control
from train_dynamics.ros.run_control import CONNECT_SETTLE, RunControl


class _Log:

    def info(self, text: str) -> None:
        self.last = text

    warning = error = info


def _gate(answer: str) -> RunControl:
    """Return a lock-step gate whose controller is connected both ways (fake node, topics)."""
    node = SimpleNamespace(get_logger=lambda: _Log(), create_service=lambda *args: None)
    inputs = SimpleNamespace(configure_lockstep=lambda *args: None,
                             unconnected=lambda waits_for: [],
                             publisher_problems=lambda waits_for, qos=False: [])
    outputs = SimpleNamespace(subscribed=lambda: True, clock_subscribed=lambda: True)
    gate = RunControl(node, None, inputs, outputs, lambda: None)
    gate.configure('lockstep', 10.0, 'stop', 1, ('brake',), answer=answer)
    gate.start(None)
    return gate


def test_echo_lockstep_releases_t0_once_connected_without_a_fixed_wait():
    gate = _gate('echo')
    assert gate.hold_start(100.0) is False


def test_clock_lockstep_gives_the_outputs_of_t0_the_settle_time():
    assert CONNECT_SETTLE > 0.0
    gate = _gate('clock')
    assert gate.hold_start(100.0) is True
    assert gate.hold_start(100.0 + 0.5 * CONNECT_SETTLE) is True
    assert gate.hold_start(100.0 + 2.0 * CONNECT_SETTLE) is False


def test_echo_lockstep_still_holds_t0_while_the_controller_is_not_connected(monkeypatch):
    gate = _gate('echo')
    gate._outputs = SimpleNamespace(subscribed=lambda: False, clock_subscribed=lambda: False)
    monkeypatch.setattr(run_control, 'PROBE_PERIOD', 1e9)
    assert gate.hold_start(100.0) is True
    gate._outputs = SimpleNamespace(subscribed=lambda: True, clock_subscribed=lambda: True)
    assert gate.hold_start(100.1) is False
