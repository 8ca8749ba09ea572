"""
Builtin blending on a low-adhesion rail: the unit counts on the ED force the rail carries.

The FLIRT at 20 m/s on 0.06 adhesion (at low speed), 0.3 of full service (0.33 m/s^2): each
motor car's ED is limited by its ``traction_adhesion`` scaled by the track's adhesion
(0.06 / 0.331, as the kernel applies it), about 0.045 m g at 20 m/s, far below its power
limit; the unit must see that limit, or it leaves the make-up to an ED that is not there
and the train brakes at two thirds of the demand. With it, ED and friction together give
the demanded force (the friction, about 0.01 g a car, is within what the rail carries).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from train_dynamics.param_files import load_param_file
from train_dynamics.physics.blending import ed_available
from train_dynamics.physics.kernel.layout import VEHICLE
from train_dynamics.physics.kernel.step import available_braking_force
from train_dynamics.physics.kernel.traction import traction_force
from train_dynamics.physics.train import TrainSimulator

ROOT = Path(__file__).resolve().parents[2]


def test_builtin_blending_makes_up_the_ed_the_low_adhesion_rail_cannot_carry():
    cfg = load_param_file(str(ROOT / 'config' / 'emu_flirt_4.yaml'))
    cfg = cfg.replace(demand_schedule_times=[], demand_schedule_values=[],
                      initial_speed=20.0, track_adhesion_positions=[-1.0e6],
                      track_adhesion=[0.06], adhesion_limit=True)
    sim = TrainSimulator(cfg)
    motors = [i for i in range(sim.n) if sim.coach[VEHICLE.DB_FORCE, i] > 0.0]
    c = sim.coach
    # the unit's ED limit is the kernel's dynamic brake at full command
    for i, avail in zip(motors, ed_available(c, motors)):
        mu0 = c[VEHICLE.T_ADH, i] * 0.06 / 0.3315
        want = -traction_force(-1.0, 20.0, c[VEHICLE.T_FORCE, i], c[VEHICLE.T_POWER, i],
                               c[VEHICLE.DB_FORCE, i], c[VEHICLE.DB_POWER, i],
                               c[VEHICLE.DB_FADE, i], mu0, c[VEHICLE.WEIGHT, i])
        assert avail == pytest.approx(want, rel=2e-3)
        assert avail < 0.5 * c[VEHICLE.DB_POWER, i] / 20.0
    sim.bcu.set_demand(0.3)
    sim.advance_to(6.0)                 # past the jerk-limited ramp (0.33 / 1.0 s) and lag
    assert sim.bcu.demanded_deceleration == pytest.approx(0.33, rel=1e-9)
    # the ED force plus the friction brakes' force at the wheels (the cylinders' pressures
    # through the brake law) is the demanded force; on this rail the vehicles run on
    # wheelsets (implied), whose creep force is that less what turns the wheels down
    at_wheels = np.empty(sim.n)
    available_braking_force(sim.coach.copy(), sim.sc, at_wheels)
    total = sim.bcu.ed_force().sum() + at_wheels.sum()
    assert total == pytest.approx(sim.bcu.force_demand, rel=5e-3)
    assert np.all(at_wheels > 1.0e3)                # every car's friction makes up
