"""Acceptance criteria over the brake blending metrics (``blending.<key>``) of a run."""
from __future__ import annotations

import pytest

from train_dynamics.physics.config import ConfigError
from train_dynamics.testing.criteria import criteria_metrics, Criterion, parse_criteria

SUMMARY = {'train': {'stopping_distance': 305.7, 'max_jerk': 0.82},
           'blending': {'friction_share': 0.012, 'energy_regenerated': 3.0e7,
                        'max_jerk': None}}


def test_blending_criteria_bound_the_blending_section_beside_the_train_metrics():
    metrics = criteria_metrics(SUMMARY)
    assert metrics['stopping_distance'] == 305.7
    assert metrics['blending.friction_share'] == 0.012
    crits = parse_criteria({'blending.friction_share': {'max': 0.05},
                            'blending.energy_regenerated': {'min': 2.5e7},
                            'stopping_distance': {'max': 330.0}})
    assert all(c.check(metrics).passed for c in crits)
    tight = Criterion.parse('blending.friction_share', {'max': 0.01}).check(metrics)
    assert not tight.passed and tight.value == 0.012
    # the train's max_jerk and the blending one are different metrics
    assert Criterion.parse('max_jerk', {'max': 1.0}).check(metrics).passed
    unproduced = Criterion.parse('blending.max_jerk', {'max': 1.0}).check(metrics)
    assert not unproduced.passed and 'has no blending.max_jerk' in unproduced.text


def test_blending_criterion_fails_on_a_run_without_blending():
    result = Criterion.parse('blending.friction_share', {'max': 0.5}).check(
        criteria_metrics({'train': {'stopping_distance': 100.0}}))
    assert not result.passed and result.value is None


@pytest.mark.parametrize('name, hint', [('blending.friction_shar', 'blending.friction_share'),
                                        ('blending.stopped', None),
                                        ('friction_share', 'blending.friction_share')])
def test_unknown_blending_metric_is_refused(name, hint):
    with pytest.raises(ConfigError, match='no such run metric') as err:
        Criterion.parse(name, {'max': 1.0})
    if hint is not None:
        assert f'did you mean {hint}' in str(err.value)
