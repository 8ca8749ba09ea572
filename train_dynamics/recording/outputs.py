"""
The output messages of a simulator state, encoded once for publishing and recording.

``sim_node`` publishes these bytes and records the very same bytes; the offline command
writes them to its bag. Every one has ``header.stamp`` = simulation time and ``header.frame_id``
``track`` (:data:`train_dynamics.topics.TRACK_FRAME`: along the track, forward > 0). What each
output topic carries, and when a run has it, is the table
:data:`train_dynamics.recording.output_specs.OUTPUTS`; here it is encoded: per message
(:class:`OutputEncoder`, the node) or in place in the rows of a bag block
(:class:`OutputRows`, the offline command), both through each row's byte layout, so the two
give the same bytes.
"""
from __future__ import annotations

import json
import struct
from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.recording.cdr import fluid_pressure_layout, STAMP_OFFSET
from train_dynamics.recording.output_specs import active, OutputRun, OutputSpec

__all__ = ['OutputEncoder', 'OutputRows', 'output_topics', 'parameters_json', 'run_metadata',
           'time_ns']


def time_ns(t: float) -> int:
    """Return simulation time ``t`` [s] as the integer nanoseconds of stamps and bag times."""
    return int(round(t * 1e9))


def output_topics(cfg: Any) -> tuple[str, ...]:
    """Return the output topics of a run of ``cfg``, in publishing order."""
    return tuple(spec.topic for spec in active(cfg))


class OutputEncoder:
    """
    CDR bytes of the output topics of a run of ``cfg`` (names and layouts encoded once).

    :attr:`specs`: the rows of :data:`~train_dynamics.recording.output_specs.OUTPUTS` the run
    has; :attr:`topics`, :attr:`msgtypes`: theirs; :attr:`run`: what the outputs keep between
    two (:class:`~train_dynamics.recording.output_specs.OutputRun`). Every stamped message has
    the frame ``topics.TRACK_FRAME``.
    """

    def __init__(self, cfg: Any) -> None:
        self.specs: tuple[OutputSpec, ...] = active(cfg)
        self.topics = tuple(spec.topic for spec in self.specs)
        self.msgtypes = tuple(spec.msgtype for spec in self.specs)
        self.layouts = tuple(spec.layout(cfg) for spec in self.specs)
        self.run = OutputRun(cfg)

    @classmethod
    def for_config(cls, cfg: Any) -> 'OutputEncoder':
        """Return the encoder of a run of ``cfg`` (as ``OutputEncoder(cfg)``)."""
        return cls(cfg)

    def fields(self, t_ns: int, sim: Any) -> tuple[tuple[Any, ...], ...]:
        """
        Return the field values of each of :attr:`topics` for ``sim``'s state at ``t_ns``.

        None: an empty array. Call it once per output (some rows keep state between two).
        """
        run = self.run
        return tuple(spec.read(sim, t_ns, run) for spec in self.specs)

    def encode(self, t_ns: int, sim: Any) -> tuple[bytes, ...]:
        """Return the CDR bytes of each of :attr:`topics` for ``sim``'s state at ``t_ns``."""
        sec, nanosec = divmod(int(t_ns), 1_000_000_000)
        out = []
        for layout, values in zip(self.layouts, self.fields(t_ns, sim)):
            data = bytearray(layout.template)
            struct.pack_into('<iI', data, STAMP_OFFSET, sec, nanosec)
            view = np.frombuffer(data, np.uint8)
            for at, n, value in zip(layout.fields, layout.lengths, values):
                if n:
                    view[at:at + 8 * n] = np.asarray(value, dtype='<f8').reshape(n).view(
                        np.uint8)
            out.append(bytes(data))
        return tuple(out)


class OutputRows:
    """
    The output topics of each sample as rows of a :class:`RecordBlock` (the offline bag).

    The messages of :class:`OutputEncoder` (its topics, then the head-pipe FluidPressure
    ABSOLUTE [Pa] when ``head_pipe``), byte for byte, but encoded in place: the values of a
    sample are copied once into the block's rows and a whole block goes to the bag at once
    (:meth:`BagRecorder.attach`).
    """

    def __init__(self, encoder: OutputEncoder, head_pipe: bool,
                 capacity: int | None = None) -> None:
        self.encoder = encoder
        self.capacity = capacity                     # rows per block (None: about 1 MiB)
        self.head_pipe = bool(head_pipe)
        self.topics = encoder.topics + ((topics.HEAD_PIPE_TOPIC,) if head_pipe else ())
        self.block: Any = None                       # the RecordBlock, made at the first row
        self._views: list[list[Any]] = []

    def _fields(self, t_ns: int, sim: Any, head: float | None) -> tuple[Any, ...]:
        out = self.encoder.fields(t_ns, sim)
        if self.head_pipe:
            out += ((head, 0.0),)
        return out

    def _build(self) -> Any:
        """Make the block of the run's layouts (and the head pipe's)."""
        from train_dynamics.recording.mcap_rows import RecordBlock  # here: the node needs no bags
        layouts = list(self.encoder.layouts)
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
            self.block = self._build()
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
