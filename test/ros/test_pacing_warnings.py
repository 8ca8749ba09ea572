"""
The simulation thread's warnings while it is behind: decided before the logger is called.

A pacing iteration that finds the simulation behind schedule warns at most once per
:data:`train_dynamics.ros.throttle.WARN_PERIOD` per kind, and keeps suppressed warnings away
from the logger: rclpy's own ``throttle_duration_sec`` inspects the caller's source on every
call, and those calls kept a node that had fallen behind from catching up
(:mod:`train_dynamics.ros.throttle`). The logger is replaced by a recorder; no timing is
asserted (the wall clock is passed in).
"""
from __future__ import annotations

from types import SimpleNamespace

from train_dynamics.ros import pacing
from train_dynamics.ros.throttle import Throttle, WARN_PERIOD

H = 0.002     # [s] integration step


class _Log:

    def __init__(self):
        self.calls = []

    def warning(self, text, **kwargs):
        self.calls.append((text, kwargs))


def _behind_pacer(behind: float):
    """Return a pacer at rtf 1 whose simulation is ``behind`` [s wall] late at wall 100."""
    pacer = pacing.Pacer(pacing.SimulationLock(), _Log(), None, None, None)
    pacer.sim = SimpleNamespace(steps=1000, t=1000 * H)
    pacer._h = H
    pacer.real_time_factor = 1.0
    pacer._anchor_wall, pacer._anchor_sim = 100.0 - behind - H, 1000 * H
    return pacer


def test_falling_behind_warns_once_per_period_and_never_asks_the_logger_to_throttle():
    pacer = _behind_pacer(0.2)
    for k in range(500):               # 500 iterations within 0.5 s, all behind
        target = pacer._target_step(100.0 + k * 1e-3)
        assert target > 1000           # catching up: the wall clock asks for later steps
    assert len(pacer._log.calls) == 1
    text, kwargs = pacer._log.calls[0]
    assert text.startswith('falling behind real time: 200 ms behind') and kwargs == {}
    assert abs(pacer.behind - (0.2 + 0.499)) < 1e-9      # still measured at every iteration
    pacer._target_step(100.0 + WARN_PERIOD + 0.1)
    assert len(pacer._log.calls) == 2


def test_dropping_the_lag_is_counted_every_time_and_warned_once_per_period():
    pacer = _behind_pacer(2.0)
    for k in range(50):
        now = 100.0 + k * 1e-3
        pacer._anchor_wall = now - 2.0 - H      # 2 s behind again at every iteration
        assert pacer._target_step(now) == 1001  # the lag dropped: the next step only
    assert pacer.lag_events == 50
    assert abs(pacer.lag_dropped - 50 * 2.0) < 1e-6
    assert len(pacer._log.calls) == 1
    assert pacer._log.calls[0][0].startswith('cannot keep up') and pacer._log.calls[0][1] == {}


def test_throttle_counts_what_it_suppressed_per_key():
    throttle = Throttle(period=5.0)
    assert throttle('a', 0.0) == 0
    assert throttle('a', 1.0) is None and throttle('a', 4.9) is None
    assert throttle('b', 2.0) == 0                 # keys are independent
    assert throttle('a', 5.0) == 2                 # due again: two were suppressed
    assert throttle('a', 6.0) is None
