"""
What a run costs in memory: the simulator's arrays, estimated before a run.

The configuration refuses a train whose simulator would need more than
:data:`MAX_SIMULATOR_MEMORY`. (The disk of its outputs is estimated beside the outputs:
:func:`train_dynamics.recording.output_specs.output_disk`.)
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

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


def fmt_bytes(n: float) -> str:
    """Return ``n`` bytes in words: '3.8 MB', '64 TB'."""
    for unit in ('B', 'kB', 'MB', 'GB', 'TB', 'PB'):
        if abs(n) < 1000.0 or unit == 'PB':
            return f'{n:.3g} {unit}'
        n /= 1000.0
    raise AssertionError
