"""
Shared test setup: a private, loopback-only ROS 2 domain per test session.

Before anything imports rclpy this sets, for this process and every subprocess it starts:

- ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``: DDS discovery never leaves the machine.
- SIGINT handled (children start with its default disposition) even where the session was
  started with it ignored, since tests signal the processes they start.
- ``ROS_DOMAIN_ID``: one domain per test process, from 1..60, held with an exclusive lock
  file (``$TMPDIR/train_dynamics_ros_domain_<id>.lock``) for the whole session, so that two
  test sessions running at once on the machine, and the parallel workers of one
  (pytest-xdist, ``make test``), never share a domain. An xdist controller runs no test and
  gives its domain back. (61..69 are kept for people running nodes by hand, 70..100 for
  ``make run``/``bench``/``soak``.) Set ``TRAIN_DYNAMICS_TEST_DOMAIN_ID`` to force one: a
  serial session takes it, worker k (``gw<k>``) of a parallel one takes it + k.
- Temporary files: pytest's ``tmp_path`` folders are per worker (xdist gives each worker its
  own base folder), and every test writes below its own.

Fixtures for tests with real rclpy (DDS on loopback, in-process):

- ``rclpy_context``: ``rclpy.init()`` on the default context before the test and
  ``rclpy.try_shutdown()`` after it; yields the context. Create nodes and executors as usual.
- ``spin_until``: ``spin_until(executor_or_node, predicate, timeout=5.0) -> bool`` spins until
  ``predicate()`` is true or ``timeout`` seconds (wall) pass.
- ``harness``: a :class:`sim_node_helpers.Harness` (nodes under test, a probe node, the
  executor), closed after the test.
- ``contract_defaults``: the product contract's parameter names and defaults.

Shared test code lives in helper modules without the ``test_`` prefix (``physics_helpers``,
``sim_node_helpers``, ``cli_helpers``, ...) in ``test/`` itself, which this file puts on
``sys.path``; the tests sit in folders that mirror the package (``test/physics``,
``test/ros``, ...) and never import from each other.

Marks, set here on collection (``pytest_collection_modifyitems``; registered in setup.cfg):

- ``ros``: the test needs rclpy or DDS: it sits in ``test/ros``, uses one of the rclpy
  fixtures below, or (read from its source and the module's functions it calls) imports
  ``rclpy`` or ``train_dynamics.ros``, starts ``sim_node``/``brake_valve`` or runs a
  controller scenario (``run_scenario``).
- ``slow``: the test is in :data:`SLOW_TABLE`, the table of the slowest tests measured.
  ``pytest -m "not slow"`` (``make test-fast``) leaves them out.
- ``xdist_group('machine')``: the test is in :data:`MACHINE_TABLE`: it needs the machine to
  itself more than the others do (a colcon build, a Dask cluster, a node kept at real time,
  a process's peak memory measured). ``make test`` runs the suite on parallel workers with
  ``--dist loadgroup``: these tests all go to one worker, one at a time, while the other
  workers run the rest; so two of them never compete with each other.

Parallel runs: each worker takes the slowest tests first (:func:`_slow_first`, from
:data:`SLOW_TABLE`), so that no long test starts last and leaves the other workers idle.
"""
from __future__ import annotations

import ast
import os
import re
import signal
import sys
import tempfile
import time

_TEST_DOMAINS = list(range(1, 61))
_domain_lock = None   # open lock file, kept for the session


def _worker_index() -> int:
    """Return this pytest-xdist worker's number (``gw<k>``: k), 0 outside a worker."""
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    return int(worker[2:]) if worker.startswith('gw') and worker[2:].isdigit() else 0


def _release_domain() -> None:
    """Give the domain lock back (a process that runs no test)."""
    global _domain_lock
    if _domain_lock is not None:
        _domain_lock.close()
        _domain_lock = None


def _choose_domain() -> int:
    """Lock and return a ROS domain id no other running test session on this machine uses."""
    global _domain_lock
    forced = os.environ.get('TRAIN_DYNAMICS_TEST_DOMAIN_ID')
    if forced:
        return int(forced) + _worker_index()
    import fcntl

    start = os.getpid() % len(_TEST_DOMAINS)
    for k in range(len(_TEST_DOMAINS)):
        domain = _TEST_DOMAINS[(start + k) % len(_TEST_DOMAINS)]
        path = os.path.join(tempfile.gettempdir(), f'train_dynamics_ros_domain_{domain}.lock')
        fh = open(path, 'a')
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _domain_lock = fh
        return domain
    return _TEST_DOMAINS[start]   # all locked (unlikely): share one


os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['ROS_DOMAIN_ID'] = str(_choose_domain())

# Tests send SIGINT to the commands and nodes they start, as Ctrl-C would. A test session
# started with SIGINT ignored (a background job of a non-interactive shell: `make test &` in
# a script) passes that on to every child, which then rightly ignores it (Python installs its
# KeyboardInterrupt handler only where SIGINT is at its default). A handled signal is reset to
# its default in a child at exec: handling it here gives every child the default disposition.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)
os.environ.setdefault('MPLBACKEND', 'Agg')

# The helper modules in test/ import as top-level modules from every test folder.
_TEST_DIR = os.path.dirname(os.path.abspath(__file__))
if _TEST_DIR not in sys.path:
    sys.path.insert(0, _TEST_DIR)

import pytest  # noqa: E402

#: the product contract's parameter defaults (shared/interface.md), written once
CONTRACT_DEFAULTS = {
    'model_type': 'tanh', 'num_coaches': 3, 'coach_mass': 45000.0, 'masses': [],
    'coach_length': 25.0, 'buffer_stiffness': 2.8e6, 'buffer_friction': 1.4e6,
    'draw_gear_stiffness': 5.46e6, 'draw_gear_friction': 2.43e6, 'gravity': 9.81,
    'max_cylinder_pressure': 380000.0, 'initial_speed': 44.444, 'brake_input': 'pipe_head',
    'brake_propagation_speed': 250.0, 'publish_rate': 100.0, 'real_time_factor': 1.0,
    'publish_clock': False, 'record_bag': '',
}


def pytest_report_header(config):
    return (f"ROS_DOMAIN_ID={os.environ['ROS_DOMAIN_ID']} "
            f"ROS_AUTOMATIC_DISCOVERY_RANGE={os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE']}")


@pytest.fixture
def contract_defaults():
    """Return the contract's parameter defaults: {name: default}."""
    return dict(CONTRACT_DEFAULTS)


@pytest.fixture
def rclpy_context():
    """Initialise rclpy (default context) for one test; shut it down afterwards."""
    import rclpy

    rclpy.init()
    try:
        yield rclpy.get_default_context()
    finally:
        rclpy.try_shutdown()


def _spin_until(spinner, predicate, timeout: float = 5.0, step: float = 0.02) -> bool:
    """Spin ``spinner`` (an executor, or a node) until ``predicate()`` or ``timeout`` [s]."""
    import rclpy

    deadline = time.monotonic() + timeout
    while True:
        if predicate():
            return True
        if time.monotonic() >= deadline:
            return False
        if hasattr(spinner, 'spin_once') and not hasattr(spinner, 'get_name'):
            spinner.spin_once(timeout_sec=step)
        else:
            rclpy.spin_once(spinner, timeout_sec=step)


@pytest.fixture
def spin_until():
    """Return the spin helper: ``f(executor_or_node, predicate, timeout=5.0) -> bool``."""
    return _spin_until


@pytest.fixture
def harness(rclpy_context):
    """Yield a sim_node test harness: ``sim_node_helpers.Harness``, closed after the test."""
    # imported here: only the tests with real rclpy load it (and rclpy)
    from sim_node_helpers import Harness

    h = Harness()
    try:
        yield h
    finally:
        h.close()


# -- marks ---------------------------------------------------------------------------------

#: the slowest tests: {module basename: {test name: seconds}}, every parameter of a
#: parametrised test. Each took 2 s or more (setup, call and teardown, all its parameters
#: summed) in a run of the whole suite here (2 cores shared, load average 4-5, 2026-12-05:
#: 580 s for all the tests, 460 s of it in these; flake8 alone), or in the first run of the
#: others (tests merged later, and test_adaptive_trace: 36.8 s when it compiles its traced
#: driver, as after any change of bench/adaptive_trace.py or the kernel; 0.03 s cached).
#: ``make test-fast`` (``-m 'not slow'``) runs the other tests. A test of seconds belongs here.
SLOW_TABLE = {
    'test_adaptive.py': {
        'test_controller_meets_its_tolerance_on_a_smooth_problem': 2.7,
        'test_unequal_masses_replayed_cylinders_within_2_percent': 6.6,
    },
    'test_adaptive_trace.py': {
        'test_traced_driver_matches_the_kernel_bit_for_bit': 36.8,
    },
    'test_blending_controller_loop.py': {
        'test_external_blending_loop_is_byte_identical_and_passes_its_criteria': 16.5,
    },
    'test_bogie_scenario.py': {
        'test_the_per_bogie_scenario_stops_between_dry_rail_and_no_conditioning': 4.5,
    },
    'test_bogie_wheelsets.py': {
        'test_two_equal_bogies_run_as_the_vehicles_lumped_wheelset_bit_for_bit': 5.8,
    },
    'test_brake_valve.py': {
        'test_node_live_position_change_and_invalid_values': 5.7,
        'test_node_publishes_absolute_pressure_following_schedule': 2.1,
    },
    'test_colcon_install.py': {
        'test_build_prebuilds_the_kernels_of_the_installed_sources': 2.1,
        'test_colcon_build_installs_where_ros2_run_looks': 2.2,
        'test_installed_sim_node_runs_with_brake_valve': 4.1,
    },
    'test_colcon_test.py': {
        'test_colcon_test_runs_the_tests_and_fails_when_one_fails': 4.9,
    },
    'test_consist_fuzz.py': {
        'test_consist_files_run_one_second_or_are_refused_in_one_line': 8.1,
    },
    'test_consist_refusals.py': {
        'test_item1_long_consist_file_is_parsed_once_by_libyaml_and_an_oversized_one_is_not_read':
            2.1,
    },
    'test_controller_loop.py': {
        'test_harness_passes_the_pi_controller_and_fails_its_harsh_twin': 7.5,
        'test_harness_reports_a_silent_controller_as_a_lockstep_timeout': 2.1,
        'test_lockstep_closed_loop_is_byte_identical_and_loses_no_command': 7.3,
        'test_lockstep_waits_for_traction_commands_and_is_byte_identical': 5.9,
    },
    'test_couplings.py': {
        'test_kernel_follows_the_reference_with_preloaded_progressive_ends': 2.2,
    },
    'test_downstream_typed_controller.py': {
        'test_a_downstream_typed_controller_stops_at_the_target_byte_identical': 37.1,
    },
    'test_flake8.py': {
        'test_flake8': 26.6,
    },
    'test_friction_brakes.py': {
        'test_low_adhesion_locks_without_wsp_not_with_builtin': 2.6,
    },
    'test_harness_hostile_inputs.py': {
        'test_command_line_exits_1_for_a_failed_criterion_and_prints_the_report': 5.4,
        'test_controller_that_exits_0_before_the_run_ends_is_reported': 2.1,
        'test_report_figures_are_off_unless_asked': 5.0,
        'test_shell_wrapped_controller_is_ended_after_a_timeout': 20.2,
    },
    'test_house.py': {
        'test_the_drawing_is_the_same_at_every_run_and_carries_its_digest': 4.6,
    },
    'test_integrators.py': {
        'test_stage_solve_matches_dense_solve_with_held_coaches': 2.6,
    },
    'test_kernel_cache.py': {
        'test_a_change_in_any_kernel_source_compiles_again': 2.4,
        'test_no_writable_cache_compiles_in_memory': 2.2,
        'test_prebuilt_kernels_are_read_before_the_user_cache': 2.2,
    },
    'test_layout.py': {
        'test_layer_loads_no_forbidden_module': 2.2,
    },
    'test_lockstep_bogie_wsp.py': {
        'test_per_bogie_wsp_in_lockstep_is_answered_per_bogie_and_reproducible': 16.3,
    },
    'test_lockstep_clock.py': {
        'test_timer_driven_controller_on_sim_time_runs_in_lockstep_byte_identical': 5.2,
    },
    'test_lockstep_hostile_inputs.py': {
        'test_a_lockstep_wait_at_real_time_is_not_counted_as_lag': 2.4,
        'test_paused_time_is_not_counted_as_lag': 2.3,
    },
    'test_multiple_units.py': {
        'test_report_books_regenerated_and_friction_energy': 6.7,
        'test_shipped_unit_stops_from_top_speed': 4.1,
    },
    'test_multirate.py': {
        'test_khz_cylinders_and_free_play_within_two_percent': 2.1,
        'test_long_step_impulses_per_coupler_balance_every_vehicle': 3.0,
    },
    'test_node_graph_hygiene.py': {
        'test_help_prints_usage_and_exits_without_starting': 2.4,
        'test_namespaced_clocks_of_two_trains_stay_apart': 2.6,
        'test_second_clock_publisher_is_warned_about': 2.1,
    },
    'test_node_hostile_inputs.py': {
        'test_sigint_during_the_run_never_reports_a_timer_exception': 4.6,
        'test_wrong_type_publisher_on_an_input_topic_is_reported_in_diagnostics': 2.0,
    },
    'test_node_parameters.py': {
        'test_diagnostics_come_at_the_period_set_live': 4.7,
    },
    'test_offline_memory_bounds.py': {
        'test_compare_memory_is_independent_of_duration': 12.2,
        'test_simulate_memory_is_independent_of_duration': 4.5,
    },
    'test_offline_signals.py': {
        'test_sim_node_at_a_tolerance_no_step_meets_stops_promptly': 8.9,
        'test_simulate_at_a_tolerance_no_step_meets_stops_promptly': 4.2,
        'test_simulate_signal_stops_promptly_and_keeps_the_bag': 2.1,
        'test_sweep_signal_stops_promptly_and_keeps_finished_cases': 3.4,
    },
    'test_output_specs.py': {
        'test_report_gives_the_stop_error_of_a_braked_run': 5.0,
    },
    'test_pep257.py': {
        'test_pep257': 2.5,
    },
    'test_plot.py': {
        'test_plot_of_a_recorded_bag_many_couplers_namespace_and_reset': 2.1,
        'test_plot_of_a_simulated_bag': 3.2,
    },
    'test_pneumatic_train.py': {
        'test_reservoir_topic_encoded_and_recorded': 3.5,
    },
    'test_recorder_hostile_inputs.py': {
        'test_sim_node_with_a_short_flush_period_records_every_output': 2.5,
    },
    'test_recording_refusals.py': {
        'test_sim_node_full_disk_reports_what_was_written_and_exits_nonzero': 3.4,
    },
    'test_report.py': {
        'test_report_fatigue_counts_every_sample_of_the_bag': 3.3,
        'test_report_of_a_bag_recorded_by_sim_node': 10.1,
        'test_report_of_an_offline_bag_equals_the_live_metrics': 3.5,
        'test_report_reads_slack_and_strokes_from_the_consist_as_the_simulator_does': 7.3,
        'test_report_without_parameters_has_no_limits': 3.3,
    },
    'test_report_hostile_inputs.py': {
        'test_a_sound_bag_is_reported_and_plotted': 2.3,
    },
    'test_run_control.py': {
        'test_two_publishers_on_the_active_input_raise_a_warn': 3.0,
    },
    'test_sim_node.py': {
        'test_cylinder_inputs_over_topics_match_the_core_run_offline': 2.4,
        'test_live_model_switches_take_effect_with_continuous_state': 2.2,
        'test_wait_for_input_holds_t0_until_a_publisher_connects': 2.1,
    },
    'test_sim_node_blending_lockstep.py': {
        'test_demand_emergency_and_trip_in_lockstep_give_byte_identical_bags': 5.7,
    },
    'test_sim_node_bogie_wsp.py': {
        'test_a_bogie_valve_topic_vents_that_bogie_only': 2.5,
        'test_the_example_controller_protects_each_bogie': 18.5,
    },
    'test_sim_node_brake_state.py': {
        'test_ecp_line_loss_is_published_recorded_and_diagnosed': 3.2,
        'test_radio_loss_is_published_and_diagnosed': 2.1,
    },
    'test_sim_node_ep.py': {
        'test_ep_command_applied_validated_and_train_line_supervised': 2.1,
    },
    'test_sim_node_ed_force_stale.py': {
        'test_stale_ed_force_command_releases_the_ed_brake': 2.9,
    },
    'test_sim_node_hardening.py': {
        'test_bad_inputs_are_rejected_counted_and_a_flood_does_not_slow_the_node': 8.1,
        'test_long_free_run_memory_flat_stamps_monotonic_exact_counts': 3.2,
        'test_numerical_fault_stops_reports_keeps_the_bag_and_reset_recovers': 2.1,
        'test_rapid_live_model_switching_keeps_the_state_continuous': 2.1,
        'test_sigkill_loses_at_most_the_unflushed_part': 3.5,
        'test_signal_during_recorded_run_leaves_a_complete_bag': 5.3,
        'test_stale_input_emergency_then_fresh_then_hold': 5.8,
    },
    'test_sim_node_metrics.py': {
        'test_node_reports_running_maxima_and_warns_past_the_force_limit': 2.2,
    },
    'test_sim_node_traction_refusals.py': {
        'test_node_traction_for_non_locomotive_counted': 4.1,
    },
    'test_sim_node_traction_stale.py': {
        'test_stale_traction_command_in_diagnostics_emergency_then_fresh_then_hold': 9.1,
    },
    'test_sim_node_wsp.py': {
        'test_external_wsp_node_keeps_the_wheels_turning': 25.0,   # at real time
    },
    'test_standstill.py': {
        'test_energy_balance_through_the_standstill_paper_law': 2.7,
        'test_error_controlled_stepping_brings_the_train_to_rest_too': 3.0,
        'test_iteration_cap_is_counted_and_the_step_finishes': 9.3,
        'test_long_train_is_at_rest_and_held_within_2_s_and_stays_so': 4.9,
        'test_momentum_and_energy_balance_through_the_standstill': 5.0,
    },
    'test_stream_plot_report.py': {
        'test_block_wise_report_equals_the_in_memory_one': 22.3,
        'test_bounded_curves_equal_the_full_ones_then_keep_the_extremes': 3.1,
        'test_plot_and_report_memory_is_independent_of_the_bag_length': 28.1,
        'test_report_and_plot_of_a_bag_with_a_reset_take_the_last_run': 2.3,
    },
    'test_sweep.py': {
        'test_a_killed_worker_s_case_is_rescheduled': 16.3,
        'test_resume_after_an_interrupted_sweep_runs_only_the_missing_cases': 21.1,
        'test_sweep_on_a_local_cluster_and_on_dask_workers_equals_sequential_runs': 17.6,
    },
    'test_sweep_refusals.py': {
        'test_sweep_consist_file_relative_to_the_sweep_file': 2.5,
        'test_sweep_resume_refuses_an_edited_consist': 2.0,
    },
    'test_typed_commands.py': {
        'test_a_stamped_traction_command_answers_the_output_of_its_stamp': 2.7,
    },
    'test_wheel_slide_train.py': {
        'test_wheelset_solve_against_bisection': 2.5,
    },
}
SLOW_TESTS = frozenset(f'{module}::{test}' for module, tests in SLOW_TABLE.items()
                       for test in tests)

#: the xdist group of the tests in MACHINE_TABLE
MACHINE_GROUP = 'machine'
#: a whole module in MACHINE_TABLE
ALL = '*'
#: tests that need the machine more than the others: {module basename: ALL or {test name}}.
#: ``--dist loadgroup`` (``make test``) runs them on one worker, one after the other, while
#: the other workers run the rest: their verdicts never depend on how busy the machine is
#: (they wait on events with generous bounds), but two of them at once would take both cores
#: for minutes.
MACHINE_TABLE = {
    'test_colcon_install.py': ALL,          # a colcon build, then the installed nodes
    'test_colcon_test.py': ALL,             # a colcon build and colcon test
    'test_sweep.py': {                      # Dask clusters of several worker processes
        'test_sweep_on_a_local_cluster_and_on_dask_workers_equals_sequential_runs',
        'test_resume_after_an_interrupted_sweep_runs_only_the_missing_cases',
        'test_a_killed_worker_s_case_is_rescheduled',
    },
    'test_sim_node_wsp.py': {               # a controller in the loop at real time
        'test_external_wsp_node_keeps_the_wheels_turning',
    },
    'test_sim_node_hardening.py': {         # the node's pace and its wall-clock timeouts
        'test_bad_inputs_are_rejected_counted_and_a_flood_does_not_slow_the_node',
        'test_stale_input_emergency_then_fresh_then_hold',
    },
    'test_sim_node_traction_stale.py': {    # wall-clock staleness of the traction command
        'test_stale_traction_command_in_diagnostics_emergency_then_fresh_then_hold',
    },
}

#: fixtures (here and in sim_node_helpers) that initialise rclpy
_ROS_FIXTURES = frozenset({'rclpy_context', 'spin_until', 'harness'})
#: callables that start sim_node (and a controller) as processes
_ROS_CALLS = frozenset({'run_scenario'})
#: strings in a test that start a node: its module's name, ROS arguments
_ROS_STRINGS = ('train_dynamics.ros', '--ros-args')
_REPO = os.path.dirname(_TEST_DIR)
_RCLPY_LINE = re.compile(r'^\s*(?:import|from)\s+rclpy\b', re.M)
_ROS_IMPORT = re.compile(r'^\s*from\s+(?:train_dynamics\.ros|\.)\.?(\w+)\s+import', re.M)
_LOADS_RCLPY: dict = {}


def _loads_rclpy(module: str) -> bool:
    """Whether importing ``module`` loads rclpy: rclpy, or a module of ros/ importing it."""
    if module == 'rclpy' or module.startswith('rclpy.'):
        return True
    if not module.startswith('train_dynamics.ros.'):
        return False
    if module not in _LOADS_RCLPY:
        _LOADS_RCLPY[module] = False     # an import cycle reads as "no"
        path = os.path.join(_REPO, *module.split('.')) + '.py'
        try:
            with open(path, encoding='utf-8') as fh:
                text = fh.read()
        except OSError:
            return False
        _LOADS_RCLPY[module] = bool(_RCLPY_LINE.search(text)) or any(
            _loads_rclpy(f'train_dynamics.ros.{m}') for m in _ROS_IMPORT.findall(text))
    return _LOADS_RCLPY[module]


def _ros_import(node) -> list:
    """Return the names an import statement binds to modules that load rclpy."""
    if isinstance(node, ast.Import):
        return [(a.asname or a.name).split('.')[0] for a in node.names if _loads_rclpy(a.name)]
    if isinstance(node, ast.ImportFrom) and node.module:
        if node.module == 'train_dynamics.ros':        # submodules: from ... import sim_node
            return [a.asname or a.name for a in node.names
                    if _loads_rclpy(f'train_dynamics.ros.{a.name}')]
        if _loads_rclpy(node.module):
            return [a.asname or a.name for a in node.names]
    return []


class _RosSource:
    """Which functions of a test module use rclpy or start a node (read from the source)."""

    def __init__(self, path: str):
        with open(path, encoding='utf-8') as fh:
            tree = ast.parse(fh.read(), path)
        self.ros_names = set(_ROS_CALLS)     # module-level names bound to ROS code
        self.functions = {}                  # module-level (and class-level) functions
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                self.ros_names.update(_ros_import(node))
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                self.functions[node.name] = node
            elif isinstance(node, ast.ClassDef):
                for sub in node.body:
                    if isinstance(sub, (ast.FunctionDef, ast.AsyncFunctionDef)):
                        self.functions[f'{node.name}.{sub.name}'] = sub
        self._memo = {}

    def _direct(self, fn) -> tuple[bool, set]:
        """Return (uses ROS itself, names of the module's functions it refers to)."""
        calls = set()
        body = fn.body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]                  # the docstring names nodes without starting them
        args = fn.args
        calls.update(a.arg for a in args.args + args.kwonlyargs + args.posonlyargs)
        for stmt in body:
            for node in ast.walk(stmt):
                if isinstance(node, ast.Name):
                    if node.id in self.ros_names:
                        return True, calls
                    calls.add(node.id)
                elif isinstance(node, (ast.Import, ast.ImportFrom)) and _ros_import(node):
                    return True, calls
                elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                    if any(s in node.value for s in _ROS_STRINGS):
                        return True, calls
        return False, calls

    def uses_ros(self, name: str, seen: frozenset = frozenset()) -> bool:
        """Whether function ``name`` or a module function it refers to uses ROS."""
        if name in self._memo:
            return self._memo[name]
        fn = self.functions.get(name)
        if fn is None or name in seen:
            return False
        direct, calls = self._direct(fn)
        result = direct or any(self.uses_ros(c, seen | {name}) for c in calls
                               if c in self.functions)
        self._memo[name] = result
        return result


_ROS_SOURCES: dict = {}


def _needs_ros(item) -> bool:
    """Whether a collected test needs rclpy or DDS (see the module docstring)."""
    path = str(item.path)
    if os.path.relpath(path, _TEST_DIR).split(os.sep)[0] == 'ros':
        return True
    if _ROS_FIXTURES & set(getattr(item, 'fixturenames', ())):
        return True
    function = getattr(item, 'function', None)
    if function is None:
        return False
    if path not in _ROS_SOURCES:
        _ROS_SOURCES[path] = _RosSource(path)
    source = _ROS_SOURCES[path]
    name = function.__qualname__
    fixtures = [f for f in getattr(item, 'fixturenames', ()) if f in source.functions]
    return source.uses_ros(name) or any(source.uses_ros(f) for f in fixtures)


def _slow_key(item) -> str:
    return f'{item.path.name}::{getattr(item, "originalname", item.name)}'


def _machine_key(item) -> bool:
    """Whether the test is in :data:`MACHINE_TABLE` (its module whole, or by name)."""
    tests = MACHINE_TABLE.get(item.path.name)
    return tests is not None and (tests == ALL or getattr(item, 'originalname', item.name)
                                  in tests)


def _module_fixture(item) -> bool:
    """Whether the test uses a module-scoped fixture (built once per worker that runs it)."""
    info = getattr(item, '_fixtureinfo', None)
    defs = info.name2fixturedefs.values() if info is not None else ()
    return any(d and d[-1].scope == 'module' for d in defs)


def _slow_first(items) -> None:
    """Order ``items`` the slowest first (:data:`SLOW_TABLE`), the rest as collected."""
    seconds = {f'{module}::{test}': t for module, tests in SLOW_TABLE.items()
               for test, t in tests.items()}
    items.sort(key=lambda item: -seconds.get(_slow_key(item), 0.0))


@pytest.hookimpl(tryfirst=True)     # before xdist reads the xdist_group marks
def pytest_collection_modifyitems(config, items):
    """Mark ``ros``, ``slow`` and the xdist groups (see the module docstring)."""
    for item in items:
        if _needs_ros(item):
            item.add_marker(pytest.mark.ros)
        if _slow_key(item) in SLOW_TESTS:
            item.add_marker(pytest.mark.slow)
        if _machine_key(item):
            item.add_marker(pytest.mark.xdist_group(MACHINE_GROUP))
        elif _module_fixture(item):      # the module's fixture built once, on one worker
            item.add_marker(pytest.mark.xdist_group(item.path.name))
    if os.environ.get('PYTEST_XDIST_WORKER'):
        _slow_first(items)


def pytest_configure(config):
    """Give the domain back in a pytest-xdist controller: its workers run the tests."""
    if getattr(config.option, 'numprocesses', None) and not hasattr(config, 'workerinput'):
        _release_domain()
