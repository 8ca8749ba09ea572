"""
Output sinks of the offline run loop (:func:`train_dynamics.simulation.runner.run_simulation`).

- :class:`BagSink` writes the output topics of each sample, and the brake inputs used, to a
  :class:`train_dynamics.recording.bags.BagRecorder` (``train-dynamics simulate``);
- :class:`ArraySink` keeps y, ydot, F (and x, v, Fb) of each sample in memory as a
  :class:`train_dynamics.recording.history.History` (``train-dynamics compare``).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.input_kinds import KINDS
from train_dynamics.physics.kernel import couplers
from train_dynamics.recording.bags import BagRecorder
from train_dynamics.recording.cdr import encode_float64
from train_dynamics.recording.history import History, JointSeries
from train_dynamics.recording.messages import stamp
from train_dynamics.recording.outputs import OutputEncoder, OutputRows, time_ns
from train_dynamics.simulation.runner import CommandEvent, Sample


class BagSink:
    """
    Write the output topics of each sample (and the inputs used) to a BagRecorder.

    The outputs are the bytes of :class:`train_dynamics.recording.outputs.OutputEncoder` (the
    node's), the head-pipe pressure of a brake-valve run ABSOLUTE [Pa], written in blocks of
    samples (:class:`train_dynamics.recording.outputs.OutputRows`); input messages of an input
    bag are re-stamped with their simulation time.
    """

    def __init__(self, rec: BagRecorder, cfg: Any) -> None:
        self.rec = rec
        self.atm = float(cfg.atmospheric_pressure)
        self.encoder = OutputEncoder.for_config(cfg)
        for topic, msgtype in zip(self.encoder.topics, self.encoder.msgtypes):
            rec.add_topic(topic, msgtype)
        self._rows: OutputRows | None = None

    def sample(self, s: Sample) -> None:
        """Write the outputs at an output step (and the head-pipe pressure of a valve run)."""
        head = None if s.head_gauge is None else s.head_gauge + self.atm
        rows = self._rows
        if rows is None or rows.head_pipe != (head is not None):
            rows = self._rows = OutputRows(self.encoder, head is not None)
        rows.write(self.rec, time_ns(s.t), s.sim, head)

    def input(self, e: CommandEvent) -> None:  # noqa: A003 - runner's hook
        """Write an input message as applied, stamped with its time from the run's start."""
        kind = KINDS[e.kind]
        if kind.stamped:                        # its header stamp: the time it acted
            msg = e.msg
            msg.header.stamp = stamp(e.t_ns, ns=True)
            self.rec.write_msg(e.topic, e.t_ns, msg)
        elif kind.msgtype == topics.FLOAT64:    # std_msgs/Float64 (a schedule's: no message)
            self.rec.add_topic(e.topic, topics.FLOAT64)
            self.rec.write(e.topic, e.t_ns, encode_float64(e.value))
        else:                                   # as read (std_msgs/Int8 ...)
            self.rec.write_msg(e.topic, e.t_ns, e.msg)


class ArraySink:
    """Collect x, v and Fb of each sample; :meth:`history` adds y, ydot and F."""

    def __init__(self) -> None:
        self.t: list[float] = []
        self.x: list[np.ndarray] = []
        self.v: list[np.ndarray] = []
        self.fb: list[np.ndarray] = []

    def sample(self, s: Sample) -> None:
        """Keep the coach states of one sample."""
        self.t.append(s.t)
        self.x.append(s.sim.x)
        self.v.append(s.sim.v)
        self.fb.append(s.sim.brake_force)

    def history(self, sim: Any, label: str = '') -> History:
        """
        Return the samples as a :class:`History`.

        y = x_i - x_{i+1} [m], ydot [m/s], F [N] from the simulator's force law (paper eqs.
        2-7) with ``sim``'s coupler constants.
        """
        t = np.asarray(self.t)
        x, v = np.asarray(self.x), np.asarray(self.v)
        y, yd = x[:, :-1] - x[:, 1:], v[:, :-1] - v[:, 1:]
        m = y.shape[1]

        def tile(a):
            return np.tile(a, len(t))

        force = couplers.coupler_force(y.ravel(), yd.ravel(), tile(sim.ke), tile(sim.kf),
                                       tile(sim.kec), tile(sim.kfc), sim.model, sim.u
                                       ).reshape(len(t), m)
        n = x.shape[1]
        cp = JointSeries(t, topics.coupler_names(n), y, yd, force)
        co = JointSeries(t, topics.coach_names(n), x, v, np.asarray(self.fb))
        return History(couplers=cp, coaches=co, label=label)
