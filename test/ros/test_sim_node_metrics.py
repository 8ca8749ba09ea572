"""
sim_node's run metrics in /diagnostics: the running maxima and the limit WARN.

The node feeds :class:`train_dynamics.physics.metrics.RunMetrics` with every published sample,
as the offline command does, so its maxima equal the ones of the samples it recorded.
"""
from __future__ import annotations

import numpy as np
import pytest

from sim_node_helpers import diag_values, fluid

ATM = 101325.0
RUN_METRICS = 'train_dynamics: run metrics'


def test_node_reports_running_maxima_and_warns_past_the_force_limit(harness, tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.parameter import Parameter

    from train_dynamics.recording.bags import read_topics

    bag = tmp_path / 'metrics'
    diags = harness.collect(DiagnosticArray, '/diagnostics')
    node = harness.start(real_time_factor=0.0, duration=6.0, record_bag=str(bag),
                         coupler_force_limit=1.0e9, wait_for_input=5.0)
    head = harness.publisher('brake_pipe/pressure')
    assert harness.wait_for_subscriber(head)
    head.publish(fluid(ATM))                     # pipe vented: emergency from t = 0
    assert harness.wait(lambda: node.finished, 30.0)
    assert harness.wait(lambda: (diag_values(diags, RUN_METRICS) or {}).get('_level') == 0,
                        5.0)
    d = diag_values(diags, RUN_METRICS)
    assert d['_message'] == 'no limit crossed'   # 1e9 N is never reached
    harness.stop(node)                           # finishes the bag
    # The maxima are those of the samples the node published (and recorded).
    efforts = np.array([msg.effort for topic, _, msg in read_topics(bag) if topic == 'couplers'])
    assert len(efforts) == 601
    worst = float(-efforts.min())
    assert worst > 1.0e3                          # the couplers did compress
    assert float(d['max_compression']) == pytest.approx(worst, rel=1e-4)
    assert d['max_compression_coupler'] in ('1', '2')      # coupler number
    # ... and the envelope over every integration step is the node simulator's
    assert float(d['max_compression_every_step']) == pytest.approx(
        node.simulator.coupler_force_envelope[1].max(), rel=1e-4)
    assert float(d['max_compression_every_step']) >= float(d['max_compression'])
    # The same run with a limit set live below that force (while t = 0 waits for the input):
    # WARN naming the coupler, value and time.
    diags.clear()
    node = harness.start(real_time_factor=0.0, duration=6.0, coupler_force_limit=1.0e9,
                         wait_for_input=5.0)
    assert node.set_parameters([Parameter('coupler_force_limit', value=worst / 2)])[0].successful
    head = harness.publisher('brake_pipe/pressure')
    assert harness.wait_for_subscriber(head)
    head.publish(fluid(ATM))
    assert harness.wait(lambda: node.finished, 30.0)
    assert harness.wait(lambda: (diag_values(diags, RUN_METRICS) or {}).get('_level') == 1,
                        5.0)
    d = diag_values(diags, RUN_METRICS)
    assert 'limit crossing' in d['_message'] and 'coupler_' in d['_message']
    assert int(d['limit_crossings']) >= 1
    assert float(d['max_compression']) == pytest.approx(worst, rel=1e-4)
    harness.stop(node)
