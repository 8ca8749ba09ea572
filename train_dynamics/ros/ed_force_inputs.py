"""
The ED force commands of ``sim_node``: ``coach_<i>/ed_brake/force`` (``blending: external``).

``std_msgs/Float64``, the ED brake force [N, >= 0] commanded of motor car i (a vehicle with
``max_dynamic_brake_force`` > 0 that takes commands), subscribed for every motor car while
``blending`` is ``external``, beside its fraction command ``coach_<i>/traction/command``
(:mod:`train_dynamics.physics.ed_force`: the force becomes the fraction of the ED available
at the car's speed, refreshed every ``blending_period``). A command takes effect at the next
integration step and is recorded as received. Rejected and counted with the traction
commands' reasons: ``non_finite``, ``out_of_range`` (< 0), ``malformed``. Lock-step: part of
the ``blending`` family (:mod:`train_dynamics.ros.blending_inputs`), answered as a traction
command is.

Staleness (``input_timeout`` > 0): a motor car whose force command has not been refreshed for
``input_timeout`` wall seconds after a first one gets 0 N, whatever ``on_input_timeout``
says: its ED brake fades out at its build-up rate (an ED force held from a dead controller
would brake on unsupervised; without it the friction brake the controller commands, or the
driver's, brakes alone), recorded as a 0 command; the next command restores it.
"""
from __future__ import annotations

from typing import Any

from train_dynamics import topics
from train_dynamics.physics.ed_force import ed_force_rejection, ed_motor_cars
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.ros.traction_inputs import float64_command, TractionInputs


def _rule(value: float) -> tuple[str, str] | None:
    why = ed_force_rejection(value)
    return None if why is None else (why, f'ED force {value:g} N (finite, >= 0)')


def ed_force_command(data: bytes) -> float:
    """Return the force [N] of a raw ED force Float64; raise ValueError(reason, detail)."""
    return float64_command(data, _rule)


class EdForceInputs(TractionInputs):
    """Subscribe to, check and hold every motor car's ED force command."""

    LABEL = 'ED force command'
    FAILSAFE = 0.0          # [N]: the ED released
    ALWAYS_FAILSAFE = True
    topic = staticmethod(topics.ed_force_topic)
    decode = staticmethod(ed_force_command)

    @staticmethod
    def put(sim: TrainSimulator, value: Any, index: int) -> None:
        """Hand ED force ``value`` [N] of motor car ``index`` (0-based) to the simulator."""
        sim.ed_force.set_force(float(value), index)


def motor_cars(cfg: Any) -> list[int]:
    """Return the motor cars (0-based) of ``cfg``'s train that take ED force commands."""
    return ed_motor_cars(cfg)
