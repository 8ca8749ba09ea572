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
- ``wheelsets`` (a train with rotating wheelsets only): JointState ``coach_1..N``: position =
  available adhesion [-], velocity = wheel peripheral speed [m/s], effort = creep force [N]
  (:data:`train_dynamics.topics.WHEELSETS_TOPIC`).
"""
from __future__ import annotations

import json
from typing import Any

from train_dynamics import topics
from train_dynamics.physics.config.budgets import (has_ep_state, has_reservoirs, radio_remotes,
                                                   state_topics)
from train_dynamics.physics.wheelset import speed_sensor
from train_dynamics.recording.cdr import (fluid_pressure_layout, joint_state_layout,
                                          JointStateEncoder)


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
        coaches = topics.coach_names(n_coaches)
        self._couplers = JointStateEncoder(topics.coupler_names(n_coaches), frame)
        self._coaches = JointStateEncoder(coaches, frame)
        self.reservoirs = bool(reservoirs)
        self.ep = bool(ep)
        radio = topics.vehicle_names(remotes) if len(remotes) else None
        self._radio = JointStateEncoder(radio, frame) if radio is not None else None
        self._motion = self._coaches
        self._last_motion: tuple[int, Any] | None = None    # (t_ns, v) of the last call
        self.topics = topics.OUTPUT_TOPICS + (
            (topics.BRAKE_RESERVOIRS_TOPIC,) if reservoirs else ()) + (
            (topics.BRAKE_EP_STATE_TOPIC,) if self.ep else ()) + (
            (topics.RADIO_STATE_TOPIC,) if self._radio is not None else ())
        #: the encoder of each of :attr:`topics`
        self._encoders = (self._couplers,) + (self._coaches,) * (
            len(self.topics) - 1 - (self._radio is not None)) + (
            (self._radio,) if self._radio is not None else ())
        #: (names, frame_id) of each of :attr:`topics`, then vehicle_motion, vehicle_forces,
        #: wheelsets
        self.joints = ((topics.coupler_names(n_coaches), frame),) + ((coaches, frame),) * (
            len(self.topics) - 1 - (radio is not None)) + (
            ((radio, frame),) if radio is not None else ()) + ((coaches, frame),) * 3

    @classmethod
    def for_config(cls, cfg: Any) -> 'OutputEncoder':
        """Return the encoder of a run of ``cfg``: its topics are :func:`output_topics`."""
        return cls(cfg.n_coaches, has_reservoirs(cfg), has_ep_state(cfg), radio_remotes(cfg))

    def fields(self, sim: Any) -> tuple[tuple[Any, Any, Any], ...]:
        """
        Return (position, velocity, effort) of each of :attr:`topics` for ``sim``'s state.

        None: an empty array.
        """
        out = ((sim.y, sim.ydot, sim.coupler_force),
               (sim.x, sim.v, sim.brake_force),
               (sim.cylinder_pressure, None, sim.pipe_pressure))
        if self.reservoirs:
            out += ((sim.auxiliary_pressure, None, sim.control_pressure),)
        if self.ep:
            out += (tuple(sim.ep_state),)
        if self._radio is not None:
            out += (tuple(sim.radio_state),)
        return out

    def encode(self, t_ns: int, sim: Any) -> tuple[bytes, ...]:
        """
        Return (couplers, coaches, brake_cylinders) of ``sim``'s present state at ``t_ns``.

        In the order of :attr:`topics`: then ``brake_reservoirs``, ``brake_ep/state``,
        ``distributed_power/state`` when they are published.
        """
        return tuple(enc(t_ns, *f) for enc, f in zip(self._encoders, self.fields(sim)))

    @staticmethod
    def forces_fields(sim: Any) -> tuple[Any, Any, Any]:
        """
        Return the fields of ``vehicle_forces``: JointState ``coach_1..N``.

        position = traction / dynamic-brake force, velocity = running + curve resistance,
        effort = gradient force; each [N] on the vehicle, forward > 0.
        """
        return sim.traction_force, sim.resistance_force, sim.gradient_force

    def encode_forces(self, t_ns: int, sim: Any) -> bytes:
        """Return ``vehicle_forces`` of ``sim``'s present state (:meth:`forces_fields`)."""
        return self._coaches(t_ns, *self.forces_fields(sim))

    @staticmethod
    def wheelsets_fields(t_ns: int, sim: Any) -> tuple[Any, Any, Any]:
        """
        Return the fields of ``wheelsets`` at ``t_ns``: JointState ``coach_1..N``.

        position = available adhesion [-], velocity = wheel peripheral speed [m/s] as the
        speed sensor reports it (``wheel_speed_resolution``, ``wheel_speed_noise``:
        :func:`~train_dynamics.physics.wheelset.speed_sensor`), effort = creep force [N,
        positive retarding].
        """
        cfg = sim.cfg
        return sim.adhesion_available, speed_sensor(
            sim.wheel_speed, t_ns, cfg.wheel_speed_resolution, cfg.wheel_speed_noise,
            cfg.wheel_speed_seed), sim.creep_force

    def encode_wheelsets(self, t_ns: int, sim: Any) -> bytes:
        """Return ``wheelsets`` of ``sim``'s present state (:meth:`wheelsets_fields`)."""
        return self._coaches(t_ns, *self.wheelsets_fields(t_ns, sim))

    def motion_fields(self, t_ns: int, sim: Any) -> tuple[Any, Any, Any]:
        """
        Return the fields of ``vehicle_motion`` at ``t_ns`` (call it at every output).

        position = track position of the front [m], velocity = v [m/s], effort = the mean
        acceleration over the time since the previous call [m/s^2] (0 at the first, or when
        the time went back: a reset).
        """
        v = sim.v
        last = self._last_motion
        if last is None or t_ns <= last[0]:
            accel = v * 0.0
        else:
            accel = (v - last[1]) / ((t_ns - last[0]) * 1e-9)
        self._last_motion = (t_ns, v)
        return sim.track_position, v, accel

    def encode_motion(self, t_ns: int, sim: Any) -> bytes:
        """Return ``vehicle_motion`` of ``sim``'s present state (:meth:`motion_fields`)."""
        return self._motion(t_ns, *self.motion_fields(t_ns, sim))


class OutputRows:
    """
    The output topics of each sample as rows of a :class:`RecordBlock` (the offline bag).

    The messages of :class:`OutputEncoder` (its topics, ``vehicle_motion``, ``vehicle_forces``
    when ``forces``, ``wheelsets`` when ``wheelsets``, the head-pipe FluidPressure ABSOLUTE
    [Pa] when ``head_pipe``), byte for byte, but encoded in place: the values of a sample are
    copied once into the block's rows and a whole block goes to the bag at once
    (:meth:`BagRecorder.attach`).
    """

    def __init__(self, encoder: OutputEncoder, forces: bool, head_pipe: bool,
                 capacity: int | None = None, wheelsets: bool = False) -> None:
        self.encoder = encoder
        self.capacity = capacity                     # rows per block (None: about 1 MiB)
        self.forces = bool(forces)
        self.wheelsets = bool(wheelsets)
        self.head_pipe = bool(head_pipe)
        self.topics = encoder.topics + (topics.VEHICLE_MOTION_TOPIC,) + (
            (topics.VEHICLE_FORCES_TOPIC,) if forces else ()) + (
            (topics.WHEELSETS_TOPIC,) if self.wheelsets else ()) + (
            (topics.HEAD_PIPE_TOPIC,) if head_pipe else ())
        self.block: Any = None                       # the RecordBlock, made at the first row
        self._views: list[list[Any]] = []

    def _fields(self, t_ns: int, sim: Any, head: float | None) -> tuple[Any, ...]:
        enc = self.encoder
        out = enc.fields(sim) + (enc.motion_fields(t_ns, sim),)
        if self.forces:
            out += (enc.forces_fields(sim),)
        if self.wheelsets:
            out += (enc.wheelsets_fields(t_ns, sim),)
        if self.head_pipe:
            out += ((head, 0.0),)
        return out

    def _build(self, fields: tuple[Any, ...]) -> Any:
        """Make the block for samples shaped like ``fields`` (array lengths, empty arrays)."""
        from train_dynamics.recording.mcap_rows import RecordBlock  # here: the node needs no bags
        layouts = []
        joints = self.encoder.joints
        for (names, frame), f in zip(joints[:len(self.encoder.topics) + 1]
                                     + ((joints[-2],) if self.forces else ())
                                     + ((joints[-1],) if self.wheelsets else ()), fields):
            layouts.append(joint_state_layout(names, [0 if a is None else len(a) for a in f],
                                              frame))
        if self.head_pipe:
            layouts.append(fluid_pressure_layout())
        block = RecordBlock(self.topics, layouts, self.capacity)
        self._views = [[block.field(m, i) if n else None for i, n in enumerate(lay.lengths)]
                       for m, lay in enumerate(layouts)]
        return block

    def write(self, rec: Any, t_ns: int, sim: Any, head: float | None = None) -> None:
        """Write the outputs of ``sim`` at ``t_ns`` [ns] as one row of ``rec``'s block."""
        fields = self._fields(t_ns, sim, head)
        if self.block is None:
            self.block = self._build(fields)
            rec.attach(self.block)
        k = rec.row(t_ns)
        for views, values in zip(self._views, fields):
            for view, a in zip(views, values):
                if view is not None:
                    view[k] = a


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
