"""
Test a brake controller in the loop: ``sim_node`` in lock-step beside the controller's node.

:func:`run_scenario` starts the simulator with a scenario file (its parameters, duration,
controller parameters and acceptance criteria, all checked when it is read) in ``sync_mode``
lockstep at ``real_time_factor`` 0 beside the controller's command, runs it to the end, ends
both process groups, and returns a :class:`RunResult`: the bag, the run metrics (those of
``train-dynamics report``) and the pass/fail report of the criteria. The pytest fixture
``train_loop`` (:mod:`train_dynamics.testing.fixture`) does the same in a test's temporary
directory; ``python -m train_dynamics.testing`` from a shell. See docs/controller_testing.md.
"""
from train_dynamics.testing.criteria import Criterion, CriterionResult
from train_dynamics.testing.harness import run_scenario, RunResult
from train_dynamics.testing.scenario import Scenario

__all__ = ['Criterion', 'CriterionResult', 'RunResult', 'run_scenario', 'Scenario']
