"""
What a run costs: memory of the simulator, disk of its outputs; estimates checked before a run.

The configuration refuses a train whose simulator would need more than
:data:`MAX_SIMULATOR_MEMORY`; the offline command compares :func:`output_disk` with the free
space before it writes.
"""
from __future__ import annotations

import math
from typing import Any

from train_dynamics.physics.kernel import layout

#: [bytes] largest simulator state a configuration may need (delay line + per-coach arrays)
MAX_SIMULATOR_MEMORY = 1 << 30


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
#: [bytes] MCAP record and index overhead per message (opcode, length, channel, sequence,
#: two times; message-index entry)
BAG_BYTES_PER_MESSAGE = 48
#: [bytes] a recorded head brake-pipe pressure (FluidPressure) per output instant
HEAD_INPUT_BYTES = 40 + BAG_BYTES_PER_MESSAGE


def delay_line_length(n_coaches: int, coach_length: float, speed: float, h: float) -> int:
    """Return the samples of the brake-pipe delay line: (N-1) L / c / h + 2 (train.py)."""
    return int(math.floor((n_coaches - 1) * coach_length / speed / h)) + 2


def simulator_memory(n_coaches: int, coach_length: float, speed: float, h: float) -> int:
    """Return an upper estimate [bytes] of the simulator's arrays."""
    return (8 * delay_line_length(n_coaches, coach_length, speed, h)
            + simulator_bytes_per_coach() * n_coaches + SIMULATOR_FIXED_BYTES)


def _joint_state_bytes(joints: int, name_len: int) -> int:
    """Return the CDR size [bytes] of a JointState of ``joints`` names of ~``name_len``."""
    name = 4 + (name_len + 1 + 3) // 4 * 4
    return 32 + joints * name + 3 * (8 + 8 * joints)


def output_bytes_per_sample(n_coaches: int) -> int:
    """
    Return the bag bytes of one output instant.

    couplers, coaches, brake_cylinders and vehicle_motion (its frame_id ``track``: 8 bytes).
    """
    digits = len(str(n_coaches))
    msgs = (_joint_state_bytes(n_coaches - 1, 8 + digits)
            + 3 * _joint_state_bytes(n_coaches, 6 + digits) + 8)
    return msgs + 4 * BAG_BYTES_PER_MESSAGE


def output_disk(cfg: Any, duration: float) -> int:
    """Return an estimate [bytes] of the bag of the outputs of ``duration`` [s] of ``cfg``."""
    samples = math.floor(duration * float(cfg.publish_rate) + 1e-9) + 1
    return int(samples * (output_bytes_per_sample(cfg.n_coaches) + HEAD_INPUT_BYTES))


def fmt_bytes(n: float) -> str:
    """Return ``n`` bytes in words: '3.8 MB', '64 TB'."""
    for unit in ('B', 'kB', 'MB', 'GB', 'TB', 'PB'):
        if abs(n) < 1000.0 or unit == 'PB':
            return f'{n:.3g} {unit}'
        n /= 1000.0
    raise AssertionError
