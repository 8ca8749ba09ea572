"""
The output messages of a simulator state, encoded once for publishing and recording.

``sim_node`` publishes these bytes and records the very same bytes; the offline command
writes them to its bag. Every one has ``header.stamp`` = simulation time and ``header.frame_id``
``track`` (:data:`train_dynamics.topics.TRACK_FRAME`: along the track, forward > 0). One
definition of what each output topic carries:

- ``couplers``: JointState ``coupler_1..N-1``: position y [m], velocity ydot [m/s], effort F [N];
- ``coaches``: JointState ``coach_1..N``: position x [m], velocity v [m/s], effort Fb [N];
- ``brake_cylinders``: JointState ``coach_1..N``: position = brake-cylinder gauge pressure
  [Pa], velocity empty, effort = local brake-pipe gauge pressure [Pa];
- ``brake_reservoirs`` (``brake_model: pneumatic`` only): JointState ``coach_1..N``:
  position = auxiliary-reservoir gauge pressure [Pa], velocity empty, effort =
  control-reservoir gauge pressure [Pa].
- ``brake_ep/state`` (``brake_system`` ep or ecp only): JointState ``coach_1..N``: position =
  the command the vehicle's EP valves / car control device follow [fraction of full service,
  0 with the train line lost], velocity = its cylinder valve in the last step [+1 filling,
  0 lapped, -1 venting], effort = the train line [1 healthy, 0 lost];
- ``distributed_power/state`` (remote locomotives only): JointState ``coach_<i>`` of each
  remote: position = radio link [1 up, 0 lost], velocity = age of the last radio message
  received [s], effort = pressure the remote's brake valve regulates the pipe to [Pa gauge];
- ``vehicle_forces`` (a train with resistance, gradients, curves or traction only):
  JointState ``coach_1..N``: position = traction / dynamic-brake force, velocity = running
  + curve resistance, effort = gradient force [N, on the vehicle, forward > 0].
- ``vehicle_motion``: JointState ``coach_1..N``: position = track position of the vehicle's
  front [m], velocity = v [m/s], effort = acceleration [m/s^2, forward > 0]:
  (v(t_k) - v(t_{k-1})) / (t_k - t_{k-1}) over the last output period (exact as a mean: the
  integrator's speed change), 0 at t = 0.
"""
from __future__ import annotations

import json
from typing import Any

from train_dynamics import topics
from train_dynamics.physics.config.budgets import (has_ep_state, has_reservoirs, radio_remotes,
                                                   state_topics)
from train_dynamics.recording.cdr import JointStateEncoder


def time_ns(t: float) -> int:
    """Return simulation time ``t`` [s] as the integer nanoseconds of stamps and bag times."""
    return int(round(t * 1e9))


def output_topics(cfg: Any) -> tuple[str, ...]:
    """Return the JointState output topics of a run of ``cfg``, in publishing order."""
    return state_topics(cfg)


class OutputEncoder:
    """
    CDR bytes of the output topics for a train of ``n_coaches`` (names encoded once).

    ``reservoirs``: also ``brake_reservoirs``; ``ep``: also ``brake_ep/state``; ``remotes``
    (0-based vehicles): also ``distributed_power/state`` of these remote locomotives. Every
    output has the frame ``topics.TRACK_FRAME``.
    """

    def __init__(self, n_coaches: int, reservoirs: bool = False, ep: bool = False,
                 remotes=()) -> None:
        frame = topics.TRACK_FRAME
        self._couplers = JointStateEncoder(topics.coupler_names(n_coaches), frame)
        self._coaches = JointStateEncoder(topics.coach_names(n_coaches), frame)
        self.reservoirs = bool(reservoirs)
        self.ep = bool(ep)
        self._radio = (JointStateEncoder(topics.vehicle_names(remotes), frame) if len(remotes)
                       else None)
        self._motion = self._coaches
        self._last_motion: tuple[int, Any] | None = None    # (t_ns, v) of the last call
        self.topics = topics.OUTPUT_TOPICS + (
            (topics.BRAKE_RESERVOIRS_TOPIC,) if reservoirs else ()) + (
            (topics.BRAKE_EP_STATE_TOPIC,) if self.ep else ()) + (
            (topics.RADIO_STATE_TOPIC,) if self._radio is not None else ())

    @classmethod
    def for_config(cls, cfg: Any) -> 'OutputEncoder':
        """Return the encoder of a run of ``cfg``: its topics are :func:`output_topics`."""
        return cls(cfg.n_coaches, has_reservoirs(cfg), has_ep_state(cfg), radio_remotes(cfg))

    def encode(self, t_ns: int, sim: Any) -> tuple[bytes, ...]:
        """
        Return (couplers, coaches, brake_cylinders) of ``sim``'s present state at ``t_ns``.

        In the order of :attr:`topics`: then ``brake_reservoirs``, ``brake_ep/state``,
        ``distributed_power/state`` when they are published.
        """
        out = (self._couplers(t_ns, sim.y, sim.ydot, sim.coupler_force),
               self._coaches(t_ns, sim.x, sim.v, sim.brake_force),
               self._coaches(t_ns, sim.cylinder_pressure, None, sim.pipe_pressure))
        if self.reservoirs:
            out += (self._coaches(t_ns, sim.auxiliary_pressure, None, sim.control_pressure),)
        if self.ep:
            out += (self._coaches(t_ns, *sim.ep_state),)
        if self._radio is not None:
            out += (self._radio(t_ns, *sim.radio_state),)
        return out

    def encode_forces(self, t_ns: int, sim: Any) -> bytes:
        """
        Return ``vehicle_forces`` of ``sim``'s present state: JointState ``coach_1..N``.

        position = traction / dynamic-brake force, velocity = running + curve resistance,
        effort = gradient force; each [N] on the vehicle, forward > 0.
        """
        return self._coaches(t_ns, sim.traction_force, sim.resistance_force, sim.gradient_force)

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
