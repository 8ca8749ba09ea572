"""
Error control under a work bound: the accepted steps of an output period are bounded.

``integration_max_steps`` is bounded per output period by the number of vehicles (one period
is one kernel call, signals are taken between two): a tolerance of 1e-15 with a budget of a
million steps is refused with the limit.
"""
from __future__ import annotations

import pytest

from train_dynamics.physics.config import ConfigError, SimConfig
from train_dynamics.physics.config.budgets import max_period_steps
from train_dynamics.physics.train import TrainSimulator


def test_item4_a_budget_that_could_spin_for_minutes_is_refused_with_the_limit():
    with pytest.raises(ConfigError) as exc:
        SimConfig.from_dict({'integration_tolerance': 1e-15, 'integration_max_steps': 1000000})
    msg = str(exc.value)
    assert 'integration_max_steps 1000000' in msg and str(max_period_steps(3)) in msg
    # fixed step: the budget is not used, any value is accepted
    SimConfig.from_dict({'integration_max_steps': 1000000})
    assert max_period_steps(3) > 10000 > max_period_steps(1000) > 100


def test_item4_a_tolerance_no_step_meets_returns_every_period_within_the_budget():
    """
    Tolerance 1e-15 at the highest budget: every output period returns, in bounded work.

    A step landing a hair above the smallest step (half of what is left of the period) was
    rejected for ever: the rejected steps now count against the budget too, so a period
    takes at most the budget accepted, the budget rejected and the budget equal steps.
    """
    budget = max_period_steps(3)
    sim = TrainSimulator(SimConfig.from_dict({'integration_tolerance': 1e-15,
                                              'integration_max_steps': budget}))
    sim.advance(1)
    sim.set_head_pipe_pressure(0.0)             # braking: the couplers carry forces
    for k in range(3):
        before = sim.integration_stats
        sim.advance(5)                          # one output period (100 Hz, 2 ms)
        after = sim.integration_stats
        assert after['fallback_periods'] == before['fallback_periods'] + 1
        assert after['rejected'] - before['rejected'] <= budget
        assert after['steps_last_period'] <= 2 * budget
    assert sim.t == pytest.approx(0.032)
