"""The ED brake commanded as a force [N] (``blending: external``, physics/ed_force.py)."""
from __future__ import annotations

from pathlib import Path

import pytest

from train_dynamics.physics.blending import ed_forces
from train_dynamics.physics.config import load_param_file
from train_dynamics.physics.train import TrainSimulator

ROOT = Path(__file__).resolve().parents[1]
V0 = 83.333            # [m/s] the ICE 3's initial speed (config/hs_ice3_8.yaml)
P_DB = 2.0e6           # [W] ED power limit of an ICE 3 motor car (config/consist_ice3_8.yaml)


def _ice3_external() -> TrainSimulator:
    cfg = load_param_file(str(ROOT / 'config' / 'hs_ice3_8.yaml'))
    cfg = cfg.replace(blending='external', demand_schedule_times=[],
                      demand_schedule_values=[])
    return TrainSimulator(cfg)


def test_ed_force_command_gives_that_force_and_no_more_than_available():
    sim = _ice3_external()
    assert sim.bcu is None and sim.ed_force.motors == [0, 2, 5, 7]
    sim.ed_force.set_force(10.0e3, 0)   # below the power limit P / v = 24 kN at 300 km/h
    sim.ed_force.set_force(60.0e3, 2)   # above it: the car gives what it has
    sim.advance_to(3.0)                 # past the 2 s build-up
    ed = ed_forces(sim)
    assert ed[0] == pytest.approx(10.0e3, rel=2e-3)
    assert ed[2] == pytest.approx(P_DB / abs(float(sim.v[2])), rel=2e-3)
    assert ed[5] == 0.0 and ed[1] == 0.0           # no command; a trailer
    sim.ed_force.set_force(0.0, 0)                  # released: the ED fades out
    sim.advance_to(6.0)
    assert ed_forces(sim)[0] == 0.0


@pytest.mark.parametrize('value, index, why', [(-1.0, 0, 'finite and >= 0'),
                                                (float('nan'), 0, 'finite and >= 0'),
                                                (1.0e3, 1, 'not a motor car')])
def test_ed_force_command_refuses_a_bad_value_or_a_trailer(value, index, why):
    with pytest.raises(ValueError, match=why):
        _ice3_external().ed_force.set_force(value, index)
