"""
Test a brake controller in the loop: ``sim_node`` in lock-step beside the controller's node.

:func:`run_scenario` starts the simulator with a scenario file (its parameters, duration and
acceptance criteria) in ``sync_mode`` lockstep at ``real_time_factor`` 0 beside the
controller's command, runs it to the end, and returns a :class:`RunResult`: the bag, the run
metrics (those of ``train-dynamics report``) and the pass/fail report of the criteria. The
pytest fixture ``train_loop`` (:mod:`train_dynamics.testing.fixture`) does the same in a
test's temporary directory. See docs/controller_testing.md.
"""
from train_dynamics.testing.criteria import Criterion, CriterionResult
from train_dynamics.testing.harness import run_scenario, RunResult, Scenario

__all__ = ['Criterion', 'CriterionResult', 'RunResult', 'run_scenario', 'Scenario']
