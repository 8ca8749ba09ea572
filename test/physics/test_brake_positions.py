"""
The standard brake positions GP and LL in the empirical brake model.

UIC 544-1 / UIC 540: a GP or LL train has its locomotive and first wagons in G, the rest in
P. In the empirical model each vehicle's cylinder follows its own regime's filling table
(config/table.py: the UIC 540 P curve, 95 % in 4 s; G the same shape six times slower,
95 % in 24 s). Hand-checked at the tables' points: with every pipe vented at t = 0
(``pipe_per_coach``, no propagation delay) the P cylinders are at 0.41 p_max at 1 s and
full at 6 s, the G cylinders at 0.16 p_max at 1.8 s and 0.41 p_max at 6 s.
"""
from pathlib import Path

import numpy as np
import pytest

from train_dynamics.physics.config import SimConfig
from train_dynamics.physics.train import TrainSimulator

GP = ('vehicles:\n'
      '  - {type: paper_coach, brake_regime: G}\n'
      '  - {type: paper_coach, brake_regime: G}\n'
      '  - {type: paper_coach}\n'
      '  - {type: paper_coach}\n')
H = 0.001
P_MAX = 380000.0


def _gp_train(tmp_path: Path, **extra) -> TrainSimulator:
    path = tmp_path / 'gp.yaml'
    path.write_text(GP)
    cfg = SimConfig.from_dict({'consist_file': str(path), 'brake_input': 'pipe_per_coach',
                               'integration_step': H, 'max_cylinder_pressure': P_MAX,
                               'initial_speed': 10.0, **extra})
    return TrainSimulator(cfg)


def _cylinders_at(sim: TrainSimulator, times) -> dict[float, np.ndarray]:
    sim.set_pipe_pressure(0.0)       # every pipe vented at t = 0
    out, done = {}, 0
    for t in times:
        k = int(round(t / H))
        sim.advance(k - done)
        done = k
        out[t] = np.array(sim.cylinder_pressure) / P_MAX
    return out


def test_gp_train_fills_each_vehicle_along_its_own_regimes_table(tmp_path):
    """G vehicles: 0.16 at 1.8 s, 0.41 at 6 s; P vehicles: 0.41 at 1 s, 1.0 at 6 s."""
    frac = _cylinders_at(_gp_train(tmp_path), (1.0, 1.8, 6.0))
    tol = 0.002                      # one step of 1 ms on the steepest slope (0.53 /s)
    assert frac[1.0][2:] == pytest.approx([0.41, 0.41], abs=tol)
    assert frac[1.8][:2] == pytest.approx([0.16, 0.16], abs=tol)
    assert frac[6.0][:2] == pytest.approx([0.41, 0.41], abs=tol)
    assert frac[6.0][2:] == pytest.approx([1.0, 1.0], abs=tol)
    # the G vehicles at 1 s: on the first segment of the G table, 0.16 * 1.0 / 1.8
    assert frac[1.0][:2] == pytest.approx([0.16 / 1.8] * 2, abs=tol)


def test_gp_train_with_its_own_tables_fills_every_vehicle_along_them(tmp_path):
    """The parameters' own filling table is every vehicle's: linear to full in 5 s."""
    sim = _gp_train(tmp_path, cylinder_fill_time=[0.0, 5.0], cylinder_fill_fraction=[0.0, 1.0])
    frac = _cylinders_at(sim, (2.0,))
    assert frac[2.0] == pytest.approx([0.4] * 4, abs=0.002)
