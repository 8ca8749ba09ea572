"""
The output topics of a run, declared once: the :data:`OUTPUTS` table of :class:`OutputSpec`.

One row per output topic: its name, message type, the names of its joints for a train, the
meaning of each field, when a run has it, how its values are read off the simulator, and the
words of the docs. Everything that handles outputs reads this table:

- :class:`train_dynamics.recording.outputs.OutputEncoder` (the node's bytes) and
  :class:`~train_dynamics.recording.outputs.OutputRows` (the offline bag's rows) encode the
  rows a run has (:func:`active`), through the byte layout of each (:meth:`OutputSpec.layout`);
- ``sim_node``'s publishers (:mod:`train_dynamics.ros.publishers`), the QoS it offers and
  what its recorder declares;
- the disk estimate (:func:`output_disk`: the exact bytes of each message);
- the topics table of docs/ros_interface.md (:func:`markdown_table`, checked by a test).

A new output is one row here plus the simulator property it reads. No rclpy here; the
message types the rows use must have a layout form (:data:`FORMS`).
"""
from __future__ import annotations

from dataclasses import dataclass
import math
import struct
from typing import Any, Callable, Sequence

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.blending import ed_forces
from train_dynamics.physics.wheelset import speed_sensor
from train_dynamics.recording import typed_msgs
from train_dynamics.recording.cdr import (_cdr_align, _cdr_header, _cdr_string, _ENCAPSULATION,
                                          joint_state_layout, Layout)

#: [bytes] MCAP record and index overhead per message (opcode, length, channel, sequence,
#: two times; message-index entry)
BAG_BYTES_PER_MESSAGE = 48
#: [bytes] a recorded head brake-pipe pressure (FluidPressure) per output instant
HEAD_INPUT_BYTES = 40 + BAG_BYTES_PER_MESSAGE
#: [bytes] a recorded traction command (Float64)
TRACTION_COMMAND_BYTES = 12 + BAG_BYTES_PER_MESSAGE
#: [bytes] a recorded /clock (rosgraph_msgs/Clock)
CLOCK_BYTES = 12 + BAG_BYTES_PER_MESSAGE

#: the three float64 arrays of a ``sensor_msgs/JointState``
JOINT_FIELDS = ('position', 'velocity', 'effort')
#: the float64 fields of ``nav_msgs/Odometry`` an output sets (the rest stay as in the
#: template: orientation the identity quaternion, covariances 0)
ODOMETRY_FIELDS = ('pose.pose.position.x', 'twist.twist.linear.x')


def _joint_state_layout(names: Sequence[str], fields: Sequence[str]) -> Layout:
    """Return the layout of a JointState of ``names``; an empty meaning: an empty array."""
    return joint_state_layout(names, [len(names) if f else 0 for f in fields],
                              topics.TRACK_FRAME)


def odometry_bytes(t_ns: int, child_frame_id: str, x: float, v: float) -> bytes:
    """
    Return the CDR bytes of a ``nav_msgs/msg/Odometry`` along the track.

    Header frame ``track`` (:data:`~train_dynamics.topics.TRACK_FRAME`), stamp ``t_ns``;
    pose: position (x, 0, 0) [m], orientation the identity (the vehicle faces forward along
    the track line); twist in ``child_frame_id``: linear (v, 0, 0) [m/s], angular 0;
    covariances 0 (the simulated state is exact).
    """
    out = bytearray(_ENCAPSULATION)
    _cdr_header(out, t_ns, topics.TRACK_FRAME)
    _cdr_string(out, child_frame_id)
    _cdr_align(out, 8)
    out += struct.pack('<7d', float(x), 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    out += bytes(8 * 36)
    out += struct.pack('<6d', float(v), 0.0, 0.0, 0.0, 0.0, 0.0)
    out += bytes(8 * 36)
    return bytes(out)


def _odometry_layout(names: Sequence[str], fields: Sequence[str]) -> Layout:
    """Return the layout of :func:`odometry_bytes`: fields position.x, twist linear.x."""
    data = odometry_bytes(0, names[0], 0.0, 0.0)
    twist_x = len(data) - 8 * 36 - 8 * 6
    pose_x = twist_x - 8 * 36 - 8 * 7
    return Layout(data, (pose_x, twist_x), (1, 1))


#: message type -> layout of a message of that type: ``form(names, fields) -> Layout``
FORMS: dict[str, Callable[[Sequence[str], Sequence[str]], Layout]] = {
    topics.JOINT_STATE: _joint_state_layout,
    topics.ODOMETRY: _odometry_layout,
    topics.TRAIN_STATE: typed_msgs.stamped_arrays_layout,
    topics.COUPLER_STATE: typed_msgs.stamped_arrays_layout,
    topics.BRAKE_STATE: typed_msgs.stamped_arrays_layout,
}


@dataclass(frozen=True)
class OutputSpec:
    """
    One output topic (a row of :data:`OUTPUTS`).

    ``names(cfg)``: the joint names for a run of ``cfg`` (Odometry: the child frame);
    ``names_text``: them in the docs. ``fields``: the meaning of each field of the message
    type's form (JointState: position, velocity, effort; '' = an empty array), with units.
    ``read(sim, t_ns, run)``: the values of the fields (None for an empty one) of ``sim``'s
    present state at ``t_ns`` [ns]; ``run`` is the :class:`OutputRun` (state kept between
    outputs, the stopping target). ``when(cfg)``: whether a run of ``cfg`` has the topic;
    ``when_text``: that in the docs ('' = always). ``field_when``: per field, None or
    ``when(cfg)``: whether a run of ``cfg`` fills it (else its array is empty).
    """

    topic: str
    msgtype: str
    names: Callable[[Any], list[str]]
    names_text: str
    fields: tuple[str, ...]
    read: Callable[[Any, int, Any], tuple]
    when: Callable[[Any], bool] = lambda cfg: True
    when_text: str = ''
    field_when: tuple[Callable[[Any], bool] | None, ...] = ()

    def fields_of(self, cfg: Any) -> tuple[str, ...]:
        """Return :attr:`fields` of a run of ``cfg``: '' where ``field_when`` says empty."""
        if not self.field_when:
            return self.fields
        return tuple(meaning if when is None or when(cfg) else ''
                     for meaning, when in zip(self.fields, self.field_when))

    def layout(self, cfg: Any) -> Layout:
        """Return the byte layout of this topic's messages in a run of ``cfg`` (stamp 0)."""
        return FORMS[self.msgtype](self.names(cfg), self.fields_of(cfg))

    def content(self) -> str:
        """Return the docs' words for the message: names and each field's meaning."""
        if self.msgtype == topics.JOINT_STATE:
            parts = [f'name {self.names_text}'] + [
                f'{name} = {meaning}' for name, meaning in zip(JOINT_FIELDS, self.fields)
                if meaning]
            empty = [name for name, meaning in zip(JOINT_FIELDS, self.fields) if not meaning]
            if empty:
                parts.append(' and '.join(empty) + ' empty')
            return '; '.join(parts)
        if self.msgtype in TYPED:
            return '; '.join(f'{name} = {meaning}' for name, meaning in
                             zip(typed_msgs.array_fields(self.msgtype), self.fields))
        return f'child_frame_id {self.names_text}; ' + '; '.join(
            f'{name} = {meaning}' for name, meaning in zip(ODOMETRY_FIELDS, self.fields))


class OutputRun:
    """
    What the outputs of one run keep between two outputs (one per encoder).

    ``memo``: topic -> its own state (e.g. ``vehicle_motion``'s last speeds);
    ``target_stop_position``: the stopping target [m, track position] or None (set from
    ``target_stop_position``, moved by its input topic).
    """

    def __init__(self, cfg: Any = None) -> None:
        self.memo: dict[str, Any] = {}
        self.target_stop_position = target_of(cfg) if cfg is not None else None


def target_of(cfg: Any) -> float | None:
    """Return the stopping target of ``cfg`` [m] (``target_stop_position``), None if unset."""
    values = getattr(cfg, 'values', {}).get('target_stop_position') or []
    return float(values[0]) if len(values) else None


# -- how each output reads the simulator --------------------------------------------------------
def _mean_acceleration(sim: Any, t_ns: int, run: OutputRun, key: str) -> np.ndarray:
    """
    Return each vehicle's mean acceleration [m/s^2] since the previous output of ``key``.

    (v(t_k) - v(t_{k-1})) / (t_k - t_{k-1}) (0 at the first, or when the time went back: a
    reset); ``run.memo[key]`` keeps (t_k, v(t_k)).
    """
    v = sim.v
    last = run.memo.get(key)
    if last is None or t_ns <= last[0]:
        accel = v * 0.0
    else:
        accel = (v - last[1]) / ((t_ns - last[0]) * 1e-9)
    run.memo[key] = (t_ns, v)
    return accel


def _acceleration(sim: Any, t_ns: int, run: OutputRun) -> tuple:
    """``vehicle_motion``: front track position [m], v [m/s], mean acceleration [m/s^2]."""
    return (sim.track_position, sim.v,
            _mean_acceleration(sim, t_ns, run, topics.VEHICLE_MOTION_TOPIC))


def _train_state(sim: Any, t_ns: int, run: OutputRun) -> tuple:
    """``train_state``: front track position [m], v [m/s], mean acceleration, Fb [N]."""
    return (sim.track_position, sim.v,
            _mean_acceleration(sim, t_ns, run, topics.TRAIN_STATE_TOPIC), sim.brake_force)


def _brake_state(sim: Any, t_ns: int, run: OutputRun) -> tuple:
    """``brake_state``: pipe, cylinder, auxiliary and control reservoir pressures [Pa gauge]."""
    return (sim.pipe_pressure, sim.cylinder_pressure, sim.auxiliary_pressure,
            sim.control_pressure)


def _wheelsets(sim: Any, t_ns: int, run: OutputRun) -> tuple:
    """``wheelsets``: available adhesion, sensed wheel speed (speed_sensor), creep force."""
    cfg = sim.cfg
    if cfg.bogie_wheelsets:     # per bogie: coach_<i>/bogie_<j>
        return sim.wheelset_adhesion_available, speed_sensor(
            sim.wheelset_speeds, t_ns, cfg.wheel_speed_resolution, cfg.wheel_speed_noise,
            cfg.wheel_speed_seed), sim.wheelset_creep_forces
    return sim.adhesion_available, speed_sensor(
        sim.wheel_speed, t_ns, cfg.wheel_speed_resolution, cfg.wheel_speed_noise,
        cfg.wheel_speed_seed), sim.creep_force


def _distance_to_go(sim: Any, t_ns: int, run: OutputRun) -> tuple:
    """``distance_to_go``: target - front of vehicle 1 [m], v_1 [m/s], the target [m]."""
    target = run.target_stop_position
    front = sim.track_position[:1]
    return target - front, sim.v[:1], np.full(1, target)


def _blending_per_car(sim: Any, t_ns: int, run: Any) -> tuple:
    """Per car: achieved ED force, friction brake force, track + eddy-current force [N]."""
    bcu = getattr(sim, 'bcu', None)
    if bcu is None:      # blending external: the controller under test is the unit
        return ed_forces(sim), sim.brake_force, np.zeros(sim.n)
    return bcu.ed_force(), sim.brake_force, bcu.track.force


def _demand_state(sim: Any, t_ns: int, run: Any) -> tuple:
    """Demanded and achieved deceleration [m/s^2], brake force [N], ED force [N]."""
    bcu = sim.bcu
    ed = bcu.ed_force()
    achieved = float(ed.sum() + sim.brake_force.sum() + bcu.track.force.sum())
    return (np.array([bcu.demanded_deceleration, achieved / float(sim.inertia.sum())]),
            np.array([bcu.force_demand, achieved]),
            np.array([float(np.sum(bcu.ed_command)), float(ed.sum())]))


def has_blending(cfg: Any) -> bool:
    """Return whether a run of ``cfg`` has a brake control unit (blending builtin or external)."""
    return getattr(cfg, 'blending', 'none') != 'none'


def has_reservoirs(cfg: Any) -> bool:
    """Return whether a run of ``cfg`` has reservoirs to publish (pneumatic brake)."""
    return (getattr(cfg, 'brake_model', 'empirical') == 'pneumatic'
            and cfg.brake_input != topics.CYLINDER_PER_COACH)


def has_ep_state(cfg: Any) -> bool:
    """Return whether a run of ``cfg`` publishes ``brake_ep/state`` (brake_system ep, ecp)."""
    return has_reservoirs(cfg) and getattr(cfg, 'brake_system', 'pneumatic') != 'pneumatic'


def radio_remotes(cfg: Any) -> tuple[int, ...]:
    """Return the remotes (0-based) whose ``distributed_power/state`` a run of ``cfg`` has."""
    if not (has_reservoirs(cfg) and getattr(cfg, 'consist_file', '')):
        return ()
    return tuple(cfg.consist.remotes)


def _couplers(cfg: Any) -> list[str]:
    return topics.coupler_names(cfg.n_coaches)


def _vehicles(cfg: Any) -> list[str]:
    return topics.coach_names(cfg.n_coaches)


def _lead(cfg: Any) -> list[str]:
    return topics.coach_names(1)


_EVERY_VEHICLE = '`coach_1`..`coach_N`'
#: the typed messages (package train_dynamics_msgs): a header and float64 arrays
TYPED = (topics.TRAIN_STATE, topics.COUPLER_STATE, topics.BRAKE_STATE)


def _typed(cfg: Any) -> bool:
    """Return True where the typed messages' definitions are found (always in the docs)."""
    return typed_msgs.available()


#: every output topic, in the order a run publishes and records them
OUTPUTS: tuple[OutputSpec, ...] = (
    OutputSpec(topics.COUPLERS_TOPIC, topics.JOINT_STATE, _couplers,
               '`coupler_1`..`coupler_{N-1}`',
               ('y_i [m]', 'ydot_i [m/s]', 'F_i [N], > 0 tension'),
               lambda sim, t_ns, run: (sim.y, sim.ydot, sim.coupler_force)),
    OutputSpec(topics.COACHES_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ('x_i [m], distance travelled since t = 0', 'v_i [m/s]',
                'braking force Fb_i [N, >= 0]'),
               lambda sim, t_ns, run: (sim.x, sim.v, sim.brake_force)),
    OutputSpec(topics.BRAKE_CYLINDERS_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ('brake-cylinder gauge pressure [Pa]', '', 'local brake-pipe gauge pressure [Pa]'),
               lambda sim, t_ns, run: (sim.cylinder_pressure, None, sim.pipe_pressure)),
    OutputSpec(topics.BRAKE_RESERVOIRS_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ('auxiliary-reservoir gauge pressure [Pa]', '',
                'control-reservoir gauge pressure [Pa]'),
               lambda sim, t_ns, run: (sim.auxiliary_pressure, None, sim.control_pressure),
               has_reservoirs, '`brake_model: pneumatic` (brake_input not cylinder_per_coach)'),
    OutputSpec(topics.BRAKE_EP_STATE_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ("the command the vehicle's EP valves / car control device follow [fraction of "
                'full service; 0 with the train line lost]',
                'its cylinder valve in the last step [+1 filling, 0 lapped, -1 venting]',
                'the train line [1 healthy, 0 lost]'),
               lambda sim, t_ns, run: tuple(sim.ep_state),
               has_ep_state, '`brake_system` ep or ecp'),
    OutputSpec(topics.RADIO_STATE_TOPIC, topics.JOINT_STATE,
               lambda cfg: topics.vehicle_names(radio_remotes(cfg)), '`coach_<i>` of each remote',
               ('radio link [1 up, 0 lost: 2 s without a message]',
                'age of the last radio message received [s]',
                "pressure the remote's brake valve regulates the pipe to [Pa gauge]"),
               lambda sim, t_ns, run: tuple(sim.radio_state),
               lambda cfg: bool(radio_remotes(cfg)),
               'remote locomotives (consist field `remote`)'),
    OutputSpec(topics.VEHICLE_MOTION_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ("track position of the vehicle's front [m] (`initial_position` minus the "
                'lengths ahead at t = 0, plus x_i)', 'v_i [m/s]',
                'acceleration [m/s^2, forward > 0], the mean over the last output period '
                '(0 at t = 0)'),
               _acceleration),
    OutputSpec(topics.VEHICLE_FORCES_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ('traction / dynamic-brake force [N, forward > 0]',
                'running + curve resistance [N, forward > 0]', 'gradient force [N, forward > 0]'),
               lambda sim, t_ns, run: (sim.traction_force, sim.resistance_force,
                                       sim.gradient_force),
               lambda cfg: bool(cfg.external_forces),
               'a train with resistance, track or traction'),
    OutputSpec(topics.WHEELSETS_TOPIC, topics.JOINT_STATE,
               lambda cfg: topics.wheelset_names(cfg.n_coaches, bool(cfg.bogie_wheelsets)),
               _EVERY_VEHICLE + ' (`coach_<i>/bogie_<j>`, j = 1, 2, with `bogie_wheelsets`)',
               ("available adhesion at the vehicle's speed [-]",
                'wheel peripheral speed [m/s] as the speed sensor reports it',
                'creep force [N, positive retarding]'),
               _wheelsets, lambda cfg: bool(cfg.has_wheelsets),
               'rotating wheelsets (`wheelsets`, `wsp`, low `track_adhesion`)'),
    OutputSpec(topics.BOGIE_CYLINDERS_TOPIC, topics.JOINT_STATE,
               lambda cfg: topics.wheelset_names(cfg.n_coaches, True),
               '`coach_<i>/bogie_<j>`, j = 1, 2',
               ("bogie's brake-cylinder gauge pressure [Pa] (behind its slide-protection "
                'valves; `brake_cylinders` shows the vehicle brake feeding both)', '',
                "bogie's slide-protection valve state of the last step (0 normal, 1 hold, "
                '2 vent)'),
               lambda sim, t_ns, run: (sim.bogie_cylinder_pressures, None,
                                       sim.wheelset_valves.astype(float)),
               lambda cfg: bool(cfg.bogie_wheelsets), '`bogie_wheelsets`'),
    OutputSpec('train_brake_force', topics.JOINT_STATE, lambda cfg: ['train'], '`train`',
               ('', '', "the train's braking force [N, >= 0]: the sum of every Fb_i"),
               lambda sim, t_ns, run: (None, None, [sim.total_brake_force])),
    OutputSpec(topics.LEAD_ODOMETRY_TOPIC, topics.ODOMETRY, _lead, '`coach_1`',
               ("track position of vehicle 1's front [m] (y, z 0; orientation the identity: "
                'facing forward along the track)', 'v_1 [m/s] (angular 0; covariances 0)'),
               lambda sim, t_ns, run: (sim.track_position[:1], sim.v[:1])),
    OutputSpec(topics.DISTANCE_TO_GO_TOPIC, topics.JOINT_STATE, _lead, '`coach_1`',
               ("distance to go [m]: the target minus the track position of vehicle 1's "
                'front (< 0: past the target)', 'v_1 [m/s]',
                'the target stopping point [m, track position]'),
               _distance_to_go, lambda cfg: target_of(cfg) is not None,
               '`target_stop_position` set'),
    OutputSpec(topics.BRAKE_BLENDING_TOPIC, topics.JOINT_STATE, _vehicles, _EVERY_VEHICLE,
               ('achieved electro-dynamic brake force [N, >= 0; 0 for trailers]',
                'friction brake force [N, >= 0]',
                'magnetic track + eddy-current brake force [N, >= 0; 0 with external]'),
               _blending_per_car, has_blending, '`blending` builtin or external'),
    OutputSpec(topics.BRAKE_DEMAND_STATE_TOPIC, topics.JOINT_STATE,
               lambda cfg: ['demand', 'achieved'], '`demand`, `achieved`',
               ('deceleration [m/s^2] (demand: after the jerk limit; achieved: ED + friction + '
                'track forces over the inertial mass, resistance and gradient not counted)',
                'brake force [N] (demand: asked of the brakes; achieved: ED + friction + track)',
                'electro-dynamic brake force of the train [N] (demand: commanded; achieved)'),
               _demand_state, lambda cfg: getattr(cfg, 'blending', 'none') == 'builtin',
               '`blending: builtin`'),
    OutputSpec(topics.TRAIN_STATE_TOPIC, topics.TRAIN_STATE, _vehicles, _EVERY_VEHICLE,
               ("track position of the vehicle's front [m] (as `vehicle_motion`)", 'v_i [m/s]',
                'acceleration [m/s^2, forward > 0], the mean over the last output period',
                'braking force Fb_i [N, >= 0]'),
               _train_state, _typed),
    OutputSpec(topics.COUPLER_STATE_TOPIC, topics.COUPLER_STATE, _couplers,
               '`coupler_1`..`coupler_{N-1}`',
               ('F_i [N], > 0 tension', 'y_i [m], > 0 extension', 'ydot_i [m/s]'),
               lambda sim, t_ns, run: (sim.coupler_force, sim.y, sim.ydot), _typed),
    OutputSpec(topics.BRAKE_STATE_TOPIC, topics.BRAKE_STATE, _vehicles, _EVERY_VEHICLE,
               ('local brake-pipe gauge pressure [Pa]', 'brake-cylinder gauge pressure [Pa]',
                'auxiliary-reservoir gauge pressure [Pa] (empty unless `brake_reservoirs` is '
                'published)', 'control-reservoir gauge pressure [Pa] (empty as the former)'),
               _brake_state, _typed,
               field_when=(None, None, has_reservoirs, has_reservoirs)),
)

#: topic -> its row
BY_TOPIC: dict[str, OutputSpec] = {spec.topic: spec for spec in OUTPUTS}


def active(cfg: Any) -> tuple[OutputSpec, ...]:
    """Return the rows a run of ``cfg`` publishes and records, in :data:`OUTPUTS` order."""
    return tuple(spec for spec in OUTPUTS if spec.when(cfg))


def output_type(topic: str) -> str:
    """Return the message type of output ``topic``."""
    return BY_TOPIC[topic].msgtype


def output_bytes_per_sample(cfg: Any) -> int:
    """Return the bag bytes of one output instant: every active row's message and record."""
    return sum(len(spec.layout(cfg).template) + BAG_BYTES_PER_MESSAGE for spec in active(cfg))


def output_disk(cfg: Any, duration: float, head_input: bool = True,
                traction_commands: int = 0, clock: bool = False) -> int:
    """
    Return an estimate [bytes] of the bag of ``duration`` [s] of ``cfg``.

    Every recorded topic: at each output instant the messages of :func:`active` (exact
    sizes), the head brake-pipe pressure when ``head_input`` (the brake valve drives it),
    ``/clock`` when ``clock``; and ``traction_commands`` Float64 commands. Messages of an
    input bag are the caller's to add (their sizes are known).
    """
    samples = math.floor(duration * float(cfg.publish_rate) + 1e-9) + 1
    per_sample = output_bytes_per_sample(cfg)
    if head_input:
        per_sample += HEAD_INPUT_BYTES
    if clock:
        per_sample += CLOCK_BYTES
    return int(samples * per_sample + traction_commands * TRACTION_COMMAND_BYTES)


def markdown_table() -> str:
    """Return the outputs table of docs/ros_interface.md (``python -m`` this module)."""
    lines = ['| topic | type | when | content |', '| --- | --- | --- | --- |']
    for spec in OUTPUTS:
        when = (spec.when_text or 'always').replace('|', '/')
        lines.append(f'| `{spec.topic}` | `{spec.msgtype}` | {when} | '
                     f'{spec.content().replace("|", "/")} |')
    return '\n'.join(lines)


if __name__ == '__main__':   # python -m train_dynamics.recording.output_specs: the docs' table
    print(markdown_table())
