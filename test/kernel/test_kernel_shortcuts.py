"""
The fixed-step kernel's shortcuts change no result: caches and the standstill skip.

The kernel keeps the couplers' law where (y, ydot) did not change, the static resistance and
gradient force of a vehicle that has not moved, and skips the active-set step at a
standstill whose inputs did not change (fixed_step._repeats_standstill). A twin simulator
that forgets all of it before every step must give the same numbers, bit for bit.
"""
import os

import numpy as np
import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.kernel import coupler_rows
from train_dynamics.physics.kernel.layout import CACHE, COUNT, OUTPUT, STATE, WORK
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.simulation.runner import apply_event, schedule_events

CONFIG = os.path.join(
    os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), 'config')


def _forget(sim):
    """Clear every cache and the standstill flag: the next step is computed in full."""
    sim.iv[CACHE.STEADY] = 0
    coupler_rows.invalidate_caches(sim.ws)
    sim.ws[WORK.YKEY] = np.nan


def _state(sim):
    return np.concatenate([sim.x, sim.v, sim.coupler_force, sim.coach[OUTPUT.FB_APPLIED],
                           sim.coach[OUTPUT.F_RES], sim.coach[OUTPUT.F_GRADE],
                           sim.coach[STATE.HELD], sim.sc, sim.iv[list(COUNT)]])


def _twins(cfg, phases):
    """
    Run ``cfg`` twice through ``phases`` [(seconds, head pipe pressure [Pa])].

    One simulator as is, the other forgetting its shortcuts before each step; assert equal
    states after every 0.1 s. Return the first simulator.
    """
    a, b = TrainSimulator(cfg), TrainSimulator(cfg)
    for sim in (a, b):
        for e in schedule_events(cfg):
            if e.t_ns == 0:
                apply_event(sim, e)
    per = int(round(0.1 / a.h))
    skipped = 0
    for seconds, head in phases:
        for sim in (a, b):
            sim.set_head_pipe_pressure(head)
        for _ in range(int(round(seconds / 0.1))):
            a.advance(per)
            for _ in range(per):
                _forget(b)
                b.advance(1)
            np.testing.assert_array_equal(_state(a), _state(b))
            skipped += int(a.iv[CACHE.STEADY])
    assert a.fault is None
    return a, skipped


def test_freight_standstill_and_release_bit_for_bit():
    """Freight on its gradient: brake to a standstill, hold, release and roll away again."""
    cfg = load_param_file(os.path.join(CONFIG, 'freight_750m.yaml'))
    cfg = cfg.replace(initial_speed=5.0, traction_schedule_times=[],
                      traction_schedule_commands=[])
    sim, skipped = _twins(cfg, [(45.0, 0.0), (40.0, 500000.0)])
    assert skipped > 20                # the standstill was skipped for seconds
    assert np.any(sim.v > 0.0)         # released on the falling gradient: rolling again


@pytest.mark.parametrize('model', ['tanh', 'sign'])
def test_paper_train_standstill_bit_for_bit(model):
    """The paper's train (no external forces) stops, stands, and is released."""
    cfg = SimConfig.from_dict({'num_coaches': 6, 'model_type': model, 'initial_speed': 5.0})
    sim, skipped = _twins(cfg, [(12.0, 0.0), (3.0, 500000.0)])
    assert skipped > 20
    assert np.all(sim.v == 0.0)       # flat track: released, but nothing pushes it


def test_standstill_flag_needs_every_vehicle_held():
    """A train still rolling never takes the standstill shortcut."""
    sim = TrainSimulator(SimConfig.from_dict({'num_coaches': 4, 'initial_speed': 5.0}))
    sim.advance(100)
    assert not sim.held.any()
    assert sim.iv[CACHE.STEADY] == 0
