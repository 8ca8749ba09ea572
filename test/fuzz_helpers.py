"""Helper of the property-based fuzz tests: run an accepted configuration 1 s offline."""
from __future__ import annotations

import numpy as np
import pytest

from train_dynamics.physics.brake_valve import BrakeValveModel
from train_dynamics.physics.config import SimConfig
from train_dynamics.simulation import runner


def run_one_second(cfg: SimConfig) -> None:
    """Run ``cfg`` 1 s (emergency at 0.2 s); every output finite."""
    valve = BrakeValveModel(schedule=['0.2:emergency'],
                            pipe_nominal_pressure=float(cfg.pipe_nominal_pressure),
                            full_service_pressure=float(cfg.full_service_pressure))
    outputs = []

    def sample(s):
        sim = s.sim
        outputs.append(np.concatenate([sim.x, sim.v, sim.y, sim.ydot, sim.coupler_force,
                                       sim.brake_force, sim.cylinder_pressure,
                                       sim.pipe_pressure]))

    sim = runner.run_simulation(cfg, 1.0, runner.InputSchedule('pipe_head', [], valve),
                                on_sample=sample)
    assert outputs and np.all(np.isfinite(np.asarray(outputs))), sim.fault
    if sim.fault is None:
        assert sim.t == pytest.approx(1.0)
