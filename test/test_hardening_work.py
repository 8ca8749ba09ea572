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


def test_item4_a_budget_that_could_spin_for_minutes_is_refused_with_the_limit():
    with pytest.raises(ConfigError) as exc:
        SimConfig.from_dict({'integration_tolerance': 1e-15, 'integration_max_steps': 1000000})
    msg = str(exc.value)
    assert 'integration_max_steps 1000000' in msg and str(max_period_steps(3)) in msg
    # fixed step: the budget is not used, any value is accepted
    SimConfig.from_dict({'integration_max_steps': 1000000})
    assert max_period_steps(3) > 10000 > max_period_steps(1000) > 100
