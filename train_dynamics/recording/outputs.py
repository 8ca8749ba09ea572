"""
The output messages of a simulator state, encoded once for publishing and recording.

``sim_node`` publishes these bytes and records the very same bytes; the offline command
writes them to its bag. One definition of what each output topic carries:

- ``couplers``: JointState ``coupler_1..N-1``: position y [m], velocity ydot [m/s], effort F [N];
- ``coaches``: JointState ``coach_1..N``: position x [m], velocity v [m/s], effort Fb [N];
- ``brake_cylinders``: JointState ``coach_1..N``: position = brake-cylinder gauge pressure
  [Pa], velocity empty, effort = local brake-pipe gauge pressure [Pa];
- ``brake_reservoirs`` (``brake_model: pneumatic`` only): JointState ``coach_1..N``:
  position = auxiliary-reservoir gauge pressure [Pa], velocity empty, effort =
  control-reservoir gauge pressure [Pa].
- ``vehicle_forces`` (a train with resistance, gradients, curves or traction only):
  JointState ``coach_1..N``: position = traction / dynamic-brake force, velocity = running
  + curve resistance, effort = gradient force [N, on the vehicle, forward > 0].
- ``vehicle_motion``: JointState ``coach_1..N``, ``frame_id`` ``track``: position = track
  position of the vehicle's front [m], velocity = v [m/s], effort = acceleration [m/s^2,
  forward > 0]: (v(t_k) - v(t_{k-1})) / (t_k - t_{k-1}) over the last output period (exact
  as a mean: the integrator's speed change), 0 at t = 0.
- ``wheelsets`` (a train with rotating wheelsets only): JointState ``coach_1..N``: position =
  available adhesion [-], velocity = wheel peripheral speed [m/s], effort = creep force [N]
  (:data:`train_dynamics.topics.WHEELSETS_TOPIC`).
"""
from __future__ import annotations

import json
from typing import Any

from train_dynamics import topics
from train_dynamics.physics.config.budgets import has_reservoirs
from train_dynamics.recording.cdr import JointStateEncoder


def time_ns(t: float) -> int:
    """Return simulation time ``t`` [s] as the integer nanoseconds of stamps and bag times."""
    return int(round(t * 1e9))


def output_topics(cfg: Any) -> tuple[str, ...]:
    """Return the JointState output topics of a run of ``cfg``, in publishing order."""
    if has_reservoirs(cfg):
        return topics.OUTPUT_TOPICS + (topics.BRAKE_RESERVOIRS_TOPIC,)
    return topics.OUTPUT_TOPICS


class OutputEncoder:
    """CDR bytes of the output topics for a train of ``n_coaches`` (names encoded once)."""

    def __init__(self, n_coaches: int, reservoirs: bool = False) -> None:
        self._couplers = JointStateEncoder(topics.coupler_names(n_coaches))
        self._coaches = JointStateEncoder(topics.coach_names(n_coaches))
        self.reservoirs = bool(reservoirs)
        self._motion = JointStateEncoder(topics.coach_names(n_coaches), topics.TRACK_FRAME)
        self._last_motion: tuple[int, Any] | None = None    # (t_ns, v) of the last call
        self.topics = topics.OUTPUT_TOPICS + (
            (topics.BRAKE_RESERVOIRS_TOPIC,) if reservoirs else ())

    def encode(self, t_ns: int, sim: Any) -> tuple[bytes, ...]:
        """
        Return (couplers, coaches, brake_cylinders) of ``sim``'s present state at ``t_ns``.

        In the order of :attr:`topics`; ``brake_reservoirs`` last when it is published.
        """
        out = (self._couplers(t_ns, sim.y, sim.ydot, sim.coupler_force),
               self._coaches(t_ns, sim.x, sim.v, sim.brake_force),
               self._coaches(t_ns, sim.cylinder_pressure, None, sim.pipe_pressure))
        if self.reservoirs:
            out += (self._coaches(t_ns, sim.auxiliary_pressure, None, sim.control_pressure),)
        return out

    def encode_forces(self, t_ns: int, sim: Any) -> bytes:
        """
        Return ``vehicle_forces`` of ``sim``'s present state: JointState ``coach_1..N``.

        position = traction / dynamic-brake force, velocity = running + curve resistance,
        effort = gradient force; each [N] on the vehicle, forward > 0.
        """
        return self._coaches(t_ns, sim.traction_force, sim.resistance_force, sim.gradient_force)

    def encode_wheelsets(self, t_ns: int, sim: Any) -> bytes:
        """Return ``wheelsets``: available adhesion, wheel speed [m/s], creep force [N]."""
        return self._coaches(t_ns, sim.adhesion_available, sim.wheel_speed, sim.creep_force)

    def encode_motion(self, t_ns: int, sim: Any) -> bytes:
        """
        Return ``vehicle_motion`` of ``sim``'s present state (call it at every output).

        The acceleration is the mean over the time since the previous call (0 at the first,
        or when the time went back: a reset).
        """
        v = sim.v
        last = self._last_motion
        if last is None or t_ns <= last[0]:
            accel = v * 0.0
        else:
            accel = (v - last[1]) / ((t_ns - last[0]) * 1e-9)
        self._last_motion = (t_ns, v)
        return self._motion(t_ns, sim.track_position, v, accel)


def run_metadata(cfg: Any, generator: str, **extra: str) -> dict[str, str]:
    """
    Return the ``custom_data`` of a run's ``metadata.yaml``: model, step, train, input.

    ``extra`` adds or overrides keys (e.g. the node name, the input source, the duration).
    """
    info = {'generator': generator, 'model_type': str(cfg.model_type),
            'scale_factor': repr(float(cfg.scale_factor)),
            'integration_step': repr(float(cfg.integration_step)),
            'publish_rate': repr(float(cfg.publish_rate)), 'num_coaches': str(cfg.n_coaches),
            'brake_input': str(cfg.brake_input)}
    info.update(extra)
    return info


def parameters_json(cfg: Any) -> str:
    """Return every simulator parameter of the run as JSON (``custom_data['parameters']``)."""
    return json.dumps(cfg.values, sort_keys=True)
