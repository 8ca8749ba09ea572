"""
``sim_node`` under hostile live sets: every failure of a set is a rejection with a bounded reason.

A consist of a hundred million vehicles, a check that fails with something other than a
ValueError (MemoryError), a consist of mixed brake regimes (taken), a masses list past the vehicle
limit: each set is refused at once with one line, the executor keeps answering and the
running simulation is untouched.
"""
from __future__ import annotations

import time

import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.ros import parameters as ros_parameters
from train_dynamics.ros import sim_node as sim_node_mod


def _set(harness, params):
    t0 = time.perf_counter()
    results = harness.set_remote('train_dynamics', params)
    return results[0], time.perf_counter() - t0


def test_item1_live_consist_of_a_huge_count_is_rejected_at_once_with_a_reason(tmp_path, harness):
    huge = tmp_path / 'huge.yaml'
    huge.write_text('vehicles: [{type: paper_coach, count: 100000000}]\n')
    node = harness.start(real_time_factor=0.0)
    result, took = _set(harness, {'consist_file': str(huge)})
    assert not result.successful and 'count' in result.reason and '100000' in result.reason
    assert took < 5.0 and len(result.reason) <= ros_parameters.MAX_REASON
    assert node.simulator.n == 3 and node.pending_changes() == ''
    assert _set(harness, {'num_coaches': 4})[0].successful      # the service still answers


def test_item1_any_failure_of_a_set_check_is_a_rejection_never_a_traceback(harness, monkeypatch):
    node = harness.start(real_time_factor=0.0)

    def out_of_memory(self, **changes):
        raise MemoryError()
    monkeypatch.setattr(SimConfig, 'replace', out_of_memory)
    result, _ = _set(harness, {'num_coaches': 5})
    assert not result.successful and result.reason == 'MemoryError'
    monkeypatch.undo()
    assert node.simulator.n == 3 and _set(harness, {'num_coaches': 5})[0].successful


def test_item9_live_consist_of_mixed_regimes_is_taken_at_set_time(tmp_path, harness):
    mixed = tmp_path / 'mixed.yaml'
    mixed.write_text('vehicles: [{type: paper_coach}, {type: paper_coach, brake_regime: G}]\n')
    harness.start(real_time_factor=0.0)
    result, _ = _set(harness, {'consist_file': str(mixed)})
    assert result.successful, result.reason


def test_item2_live_masses_past_the_limit_are_refused_and_logs_show_arrays_cut():
    assert sim_node_mod._fmt([45000.0] * 200001).endswith('... (200001 values)]')
    assert len(sim_node_mod._fmt([45000.0] * 200001)) < 100
    assert sim_node_mod._fmt('x' * 10**6).startswith("'xxx") and len(
        sim_node_mod._fmt('x' * 10**6)) < 100


@pytest.mark.parametrize('exc, reason', [(ValueError('a\nb'), 'a b'),
                                         (MemoryError(), 'MemoryError'),
                                         (RuntimeError('x' * 10**6), 'RuntimeError: xxx')])
def test_item1_rejection_reasons_are_one_bounded_line(exc, reason):
    text = ros_parameters.rejection_reason(exc)
    assert text.startswith(reason) and '\n' not in text
    assert len(text) <= ros_parameters.MAX_REASON


def test_item2_live_masses_past_the_vehicle_limit_are_rejected_by_the_node(harness):
    node = harness.start(real_time_factor=0.0)
    result, _ = _set(harness, {'masses': [45000.0] * 200001})
    assert not result.successful and '200001 values' in result.reason
    assert len(result.reason) < 200 and node.pending_changes() == ''
