"""
The node's run metrics off the simulation lock (ros/live_metrics.py).

The simulation thread only queues samples; they are folded in its idle time or by the
diagnostics callback, and the result is the offline accumulator's, sample for sample.
"""

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.metrics import RunMetrics
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.ros import live_metrics
from train_dynamics.ros.live_metrics import LiveMetrics


def _run(samples, feed):
    """Vent the pipe of 10 coaches and feed ``samples`` outputs (10 ms apart) to ``feed``."""
    cfg = SimConfig.from_dict({'num_coaches': 10})
    sim = TrainSimulator(cfg)
    sim.set_head_pipe_pressure(0.0)
    for _ in range(samples):
        sim.advance(5)
        feed(sim)
    return cfg, sim


def test_queued_samples_fold_in_idle_time_and_match_the_direct_metrics():
    live = LiveMetrics()
    direct = {}

    def feed(sim):
        if not direct:
            direct['m'] = RunMetrics.for_run(cfg, sim)
            live.start(RunMetrics.for_run(cfg, sim))
        direct['m'].sample(type('S', (), {'sim': sim, 't': sim.t})())
        live.put(sim)
        live.fold_if_idle(live_metrics.FOLD_SLACK / 2)          # no time: nothing folded

    cfg = SimConfig.from_dict({'num_coaches': 10})
    _run(live_metrics.FOLD_BATCH + 5, feed)
    assert len(live._queue) == live_metrics.FOLD_BATCH + 5
    live.fold_if_idle(live_metrics.FOLD_SLACK)                  # idle and a batch: folded
    assert len(live._queue) == 0
    level, message, values = live.diagnostic()
    assert (level, message) == direct['m'].diagnostic()[:2]
    assert dict(values) == dict(direct['m'].diagnostic()[2])
    assert float(dict(values)['max_compression']) > 0.0
    # the every-step envelope arrived with the samples (None would read 'n/a')
    assert float(dict(values)['max_compression_every_step']) >= float(
        dict(values)['max_compression'])


def test_the_queue_is_bounded_and_a_new_run_drops_the_old_samples():
    live = LiveMetrics()
    assert live.diagnostic() is None                           # no run yet
    cfg = SimConfig.from_dict({'num_coaches': 10})
    metrics = RunMetrics.for_run(cfg)
    live.start(metrics)
    _run(live_metrics.MAX_PENDING + 10, live.put)              # nobody folds ...
    assert len(live._queue) <= live_metrics.MAX_PENDING        # ... put did
    metrics.flush()                                            # RunMetrics' own block
    assert metrics.samples + len(live._queue) == live_metrics.MAX_PENDING + 10
    fresh = RunMetrics.for_run(cfg)
    live.start(fresh)
    assert len(live._queue) == 0 and live.diagnostic() is not None and fresh.samples == 0
