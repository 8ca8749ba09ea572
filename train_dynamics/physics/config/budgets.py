"""
What a run costs: memory of the simulator, disk of its outputs; estimates checked before a run.

The configuration refuses a train whose simulator would need more than
:data:`MAX_SIMULATOR_MEMORY`; the offline command compares :func:`output_disk` with the free
space before it writes.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np
from train_dynamics import topics
from train_dynamics.physics.kernel import layout
from train_dynamics.physics.kernel import pneumatic as pneumatic_kernel
from train_dynamics.physics.pneumatic import PneumaticSpec

#: [bytes] largest simulator state a configuration may need (delay line + per-coach arrays)
MAX_SIMULATOR_MEMORY = 1 << 30
#: rows per vehicle of one output period's buffers: two tick buffers of the error-controlled
#: chain, one trace of the pneumatic brake
PERIOD_ROWS = 3
#: [bytes] the pneumatic brake pipe's grid per cell: its cell rows and face rows
PIPE_BYTES_PER_CELL = 8 * (pneumatic_kernel.N_CELL_ROWS + pneumatic_kernel.N_FACE_ROWS)


def simulator_bytes_per_coach() -> int:
    """
    Return an upper estimate [bytes] of the simulator's arrays per coach.

    The kernel's packed rows (state, coupler constants, workspace; from the layout) and 32
    more float rows for the per-vehicle vectors and the error-controlled stepping's tick
    buffers. Read when called: the layout takes its per-vehicle rows from the parameter table,
    so this module (imported with the table) must not use the layout while it is imported.
    """
    return 8 * (len(layout.COACH) + len(layout.COUPLER) + len(layout.WORK) + 32)


#: [bytes] the simulator's arrays whatever the train (cylinder tables, scalars)
SIMULATOR_FIXED_BYTES = 1 << 16
#: [s] the most work one output period of error-controlled stepping may be given
MAX_PERIOD_SECONDS = 0.25
#: [s] an upper estimate of the cost of one error-controlled step: a fixed part and one per
#: vehicle (measured ~5 us + 0.3 us per vehicle on one core of the development machine)
STEP_SECONDS = 1.0e-5
STEP_SECONDS_PER_VEHICLE = 5.0e-7
#: [bytes] MCAP record and index overhead per message (opcode, length, channel, sequence,
#: two times; message-index entry)
BAG_BYTES_PER_MESSAGE = 48
#: [bytes] a recorded head brake-pipe pressure (FluidPressure) per output instant
HEAD_INPUT_BYTES = 40 + BAG_BYTES_PER_MESSAGE
#: [bytes] a recorded traction command (Float64)
TRACTION_COMMAND_BYTES = 12 + BAG_BYTES_PER_MESSAGE
#: [bytes] a recorded /clock (rosgraph_msgs/Clock)
CLOCK_BYTES = 12 + BAG_BYTES_PER_MESSAGE


def max_period_steps(n_vehicles: int) -> int:
    """
    Return the largest ``integration_max_steps`` (error-controlled steps per output period).

    One output period is one kernel call; the offline run and ``sim_node`` take signals and
    serve their callbacks between two. The accepted steps of a period for ``n_vehicles`` are
    bounded so that they take at most :data:`MAX_PERIOD_SECONDS` at :data:`STEP_SECONDS` +
    :data:`STEP_SECONDS_PER_VEHICLE` per vehicle each (the driver's rejected steps are not
    counted here).
    """
    return max(1, int(MAX_PERIOD_SECONDS / (STEP_SECONDS + STEP_SECONDS_PER_VEHICLE
                                            * max(int(n_vehicles), 1))))


def delay_line_length(n_coaches: int, coach_length: float, speed: float, h: float) -> int:
    """Return the samples of the brake-pipe delay line: (N-1) L / c / h + 2 (train.py)."""
    return int(math.floor((n_coaches - 1) * coach_length / speed / h)) + 2


def simulator_memory(n_coaches: int, coach_length: float, speed: float, h: float,
                     period_steps: int = 1, cells: int = 0) -> int:
    """
    Return an upper estimate [bytes] of the simulator's arrays.

    ``coach_length``: the mean length [m] of the vehicles ahead of the last (the pipe the
    delay line spans); ``period_steps``: integration steps per output period (the
    error-controlled chain keeps two tick buffers of it, the pneumatic brake one trace, each a
    row per vehicle); ``cells``: the pneumatic brake pipe's cells (0: empirical brake).
    """
    return (8 * delay_line_length(n_coaches, coach_length, speed, h)
            + simulator_bytes_per_coach() * n_coaches
            + 8 * PERIOD_ROWS * (period_steps + 1) * n_coaches
            + PIPE_BYTES_PER_CELL * (cells + 1) + SIMULATOR_FIXED_BYTES)


def config_memory(cfg: Any) -> int:
    """
    Return :func:`simulator_memory` of a configuration: its vehicles' own lengths and cells.

    ``cfg``: a :class:`~train_dynamics.physics.config.SimConfig` (its consist is built; its
    number of vehicles was bounded when it was).
    """
    lengths = cfg.consist['length']
    n = len(lengths)
    ahead = float(np.mean(lengths[:-1])) if n > 1 else 0.0
    h = float(cfg.integration_step)
    period = max(1, int(round(1.0 / (float(cfg.publish_rate) * h))))
    # a vehicle has round(length / cell_length) cells, at least 1 (pneumatic.py): at most
    # length / cell_length + 1
    cells = (int(math.ceil(float(np.sum(lengths)) / PneumaticSpec.cell_length)) + n
             if cfg.brake_model == 'pneumatic' else 0)
    return simulator_memory(n, ahead, float(cfg.brake_propagation_speed), h, period, cells)


def _joint_state_bytes(joints: int, name_len: int) -> int:
    """Return the CDR size [bytes] of a JointState of ``joints`` names of ~``name_len``."""
    name = 4 + (name_len + 1 + 3) // 4 * 4
    return 32 + joints * name + 3 * (8 + 8 * joints)


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


def state_topics(cfg: Any) -> tuple[str, ...]:
    """
    Return the JointState outputs of a run of ``cfg``: those :class:`OutputEncoder` encodes.

    couplers, coaches, brake_cylinders; ``brake_reservoirs`` with the pneumatic brake;
    ``brake_ep/state`` with brake_system ep or ecp; ``distributed_power/state`` with remote
    locomotives.
    """
    return (topics.OUTPUT_TOPICS
            + ((topics.BRAKE_RESERVOIRS_TOPIC,) if has_reservoirs(cfg) else ())
            + ((topics.BRAKE_EP_STATE_TOPIC,) if has_ep_state(cfg) else ())
            + ((topics.RADIO_STATE_TOPIC,) if radio_remotes(cfg) else ()))


def sample_topics(cfg: Any) -> tuple[str, ...]:
    """
    Return the JointState topics a run of ``cfg`` records at every output instant.

    The outputs of :func:`state_topics`, ``vehicle_motion``, ``vehicle_forces`` for a train
    with external forces, ``wheelsets`` for a train with rotating wheelsets.
    """
    out = state_topics(cfg) + (topics.VEHICLE_MOTION_TOPIC,)
    if cfg.external_forces:
        out += (topics.VEHICLE_FORCES_TOPIC,)
    if getattr(cfg, 'has_wheelsets', False):
        out += (topics.WHEELSETS_TOPIC,)
    return out


def output_bytes_per_sample(n_coaches: int, joint_topics: tuple[str, ...] = topics.OUTPUT_TOPICS
                            ) -> int:
    """
    Return the bag bytes of one output instant: a JointState per topic of ``joint_topics``.

    Each carries the frame_id ``track`` (:data:`~train_dynamics.topics.TRACK_FRAME`, up to 8
    bytes more with its alignment).
    """
    digits = len(str(n_coaches))
    total = 8 * len(joint_topics)
    for topic in joint_topics:
        if topic == topics.COUPLERS_TOPIC:
            total += _joint_state_bytes(n_coaches - 1, 8 + digits)
        else:
            total += _joint_state_bytes(n_coaches, 6 + digits)
    return total + len(joint_topics) * BAG_BYTES_PER_MESSAGE


def output_disk(cfg: Any, duration: float, head_input: bool = True,
                traction_commands: int = 0, clock: bool = False) -> int:
    """
    Return an estimate [bytes] of the bag of ``duration`` [s] of ``cfg``.

    Every recorded topic: at each output instant the JointState topics of
    :func:`sample_topics`, the head brake-pipe pressure when ``head_input`` (the brake valve
    drives it), ``/clock`` when ``clock``; and ``traction_commands`` Float64 commands.
    Messages of an input bag are the caller's to add (their sizes are known).
    """
    samples = math.floor(duration * float(cfg.publish_rate) + 1e-9) + 1
    per_sample = output_bytes_per_sample(cfg.n_coaches, sample_topics(cfg))
    if head_input:
        per_sample += HEAD_INPUT_BYTES
    if clock:
        per_sample += CLOCK_BYTES
    return int(samples * per_sample + traction_commands * TRACTION_COMMAND_BYTES)


def fmt_bytes(n: float) -> str:
    """Return ``n`` bytes in words: '3.8 MB', '64 TB'."""
    for unit in ('B', 'kB', 'MB', 'GB', 'TB', 'PB'):
        if abs(n) < 1000.0 or unit == 'PB':
            return f'{n:.3g} {unit}'
        n /= 1000.0
    raise AssertionError
