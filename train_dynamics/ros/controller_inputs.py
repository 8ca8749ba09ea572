"""
The controller inputs of ``sim_node``: one channel per kind of the input table.

Every kind of :data:`train_dynamics.input_kinds.INPUT_KINDS` (the topics, message types,
rules, setters, fail-safes and lock-step families of the inputs, written once) is served by a
channel: the brake pressures of the run's ``brake_input`` by the
:class:`~train_dynamics.ros.brake_channel.BrakeChannel`, every other kind by a
:class:`~train_dynamics.ros.command_channel.CommandChannel` of its row. A kind whose
vehicles are absent from the run's train has no subscription.

:class:`ControllerInputs` holds the channels of one node and what they share: the rejection
counts per reason (:data:`REJECT_REASONS`, in ``/diagnostics``, with a throttled warning
naming the topic), the staleness policy (``input_timeout``, ``on_input_timeout``), the graph
scan (every :data:`GRAPH_SCAN_PERIOD` s: topics of other brake modes, of coaches that do not
exist and of vehicles that take no such command are subscribed then, only to count and
reject their messages: keeping 2N idle subscriptions would slow rclpy's executor for long
trains), the lock-step (:class:`~train_dynamics.ros.lockstep_inputs.LockstepInputs`) and
what ``/diagnostics`` reports of them together (:attr:`ControllerInputs.stale`,
:attr:`~ControllerInputs.emergency`, :attr:`~ControllerInputs.stale_names`,
:meth:`~ControllerInputs.max_age`).

Reasons: ``non_finite``, ``negative``, ``too_high`` (the brake pressures' rule), ``wrong_mode``
(a topic of another ``brake_input``), ``unknown_coach`` (``coach_<i>`` with i outside 1..N),
``malformed`` (not deserialisable), ``out_of_range`` (the commands' rules), and a row's
``idle_reason`` (``not_locomotive``: a traction command for a vehicle without traction or
dynamic brake). Publishers of another message type on a brake-input topic (never received:
DDS does not match them) are found by the graph scan and reported as ``wrong_type``.
"""
from __future__ import annotations

import time
from typing import Any, Callable

from rclpy.node import Node

from train_dynamics import topics
from train_dynamics.input_kinds import BRAKE_KINDS, COMMAND_KINDS, InputKind, TWINS
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.ros.brake_channel import (BrakeChannel, INPUT_QOS, MAX_EXTRA_SUBSCRIPTIONS,
                                              Record)
from train_dynamics.ros.command_channel import CommandChannel
from train_dynamics.ros.lockstep_inputs import LockstepInputs
from train_dynamics.ros.publishers import message_class
from train_dynamics.ros.throttle import Throttle

__all__ = ['ControllerInputs', 'GRAPH_SCAN_PERIOD', 'INPUT_QOS', 'MAX_ABSOLUTE_PRESSURE',
           'REJECT_REASONS']

MAX_ABSOLUTE_PRESSURE = topics.MAX_ABSOLUTE_PRESSURE
#: Reasons an input message is rejected (keys of the counts in /diagnostics).
REJECT_REASONS = tuple(dict.fromkeys(
    [r for k in BRAKE_KINDS for r in k.reasons] + ['wrong_mode', 'unknown_coach', 'malformed']
    + [r for k in COMMAND_KINDS for r in k.reasons]
    + [k.idle_reason for k in COMMAND_KINDS if k.idle_reason]))
GRAPH_SCAN_PERIOD = 2.0  # [s wall] search for input topics of other modes / unknown coaches


class ControllerInputs(LockstepInputs):
    """
    Subscribe to, check and hold every controller input; apply them to a run.

    ``channels``: kind name -> :class:`CommandChannel` (every command kind of the table);
    ``brake``: the brake pressures. Lock discipline: see the channels; the rejection counts
    and the graph scan's subscriptions are the executor thread's, the policy the simulation
    lock's.
    """

    def __init__(self, node: Node) -> None:
        self._node = node
        self._log = node.get_logger()
        self._throttle = Throttle()
        # executor thread only
        self.rejected = dict.fromkeys(REJECT_REASONS, 0)
        self.last_rejected = ''
        self._idle: dict[str, Any] = {}       # graph scan: topics of vehicles that take none
        # simulation lock
        self.timeout = 0.0                    # [s wall] input_timeout, 0 = never stale
        self.on_timeout = 'hold'
        self.wait_for_input = 0.0             # [s wall]
        self._wait_since: float | None = None
        self._wait_ready: float | None = None
        #: called (executor thread) after each accepted message: wakes a waiting simulation
        self.on_input: Callable[[], None] | None = None
        self.brake = BrakeChannel(node, self._reject, self._notify, self._duplicate_answer,
                                  self.duplicate)
        self.channels: dict[str, CommandChannel] = {   # a twin is served by its kind's
            k.name: CommandChannel(k, node, INPUT_QOS, self._reject, self._notify, TWINS[k.name])
            for k in COMMAND_KINDS if not k.twin}

    def _notify(self) -> None:
        """Tell the simulation thread that an input was accepted (executor thread)."""
        if self.on_input is not None:
            self.on_input()

    def _reject(self, resolved: str, reason: str, detail: str) -> None:
        """Count a refused message per reason; warn (throttled per topic and reason)."""
        self.rejected[reason] += 1
        self.last_rejected = f'{resolved}: {reason}'
        suppressed = self._throttle((resolved, reason), time.monotonic())
        if suppressed is not None:
            more = f' ({suppressed} more since the last warning)' if suppressed else ''
            self._log.warning(f'rejected input on {resolved}: {detail} ({reason}){more}')

    # -- what /diagnostics reports: every channel together ----------------------------------
    @property
    def stale(self) -> bool:
        """Return True while a brake input or a supervised command is stale."""
        return self.brake.stale or any(ch.stale_names for ch in self.channels.values())

    @property
    def emergency(self) -> bool:
        """Return True while a fail-safe holds (emergency brake, or a command's)."""
        return self.brake.emergency or any(ch.emergency for ch in self.channels.values())

    @property
    def stale_names(self) -> list[str]:
        """Return the stale brake inputs, then the stale command topics."""
        names = list(self.brake.stale_names) if self.brake.stale else []
        for ch in self.channels.values():
            names += ch.stale_names
        return names

    @property
    def accepted(self) -> int:
        """Return the accepted messages of every channel."""
        return self.brake.accepted + sum(ch.accepted for ch in self.channels.values())

    @property
    def late(self) -> int:
        """Return the brake inputs applied after their stamp (``input_timing`` stamp)."""
        return self.brake.late

    @property
    def by_stamp(self) -> bool:
        """``input_timing`` stamp: brake inputs act at their header stamps."""
        return self.brake.by_stamp

    @by_stamp.setter
    def by_stamp(self, value: bool) -> None:
        self.brake.by_stamp = bool(value)

    @property
    def wrong_type(self) -> dict[str, list[str]]:
        """Return brake-input topic -> the types of its publishers that are not its own."""
        return self.brake.wrong_type

    @property
    def multiple_publishers(self) -> dict[str, int]:
        """Return the active brake-input topics with more than one publisher."""
        return self.brake.multiple_publishers

    def max_age(self, now: float) -> float:
        """Return the age [s wall] of the oldest input (brake inputs, supervised commands)."""
        return max([self.brake.max_age(now)]
                   + [ch.max_age(now) for ch in self.channels.values()])

    # -- a run (executor thread, simulation lock held) -------------------------------------
    def start(self, cfg: Any, n: int, recording: bool) -> None:
        """Take inputs for a new run of ``cfg`` with ``n`` vehicles, from its initial inputs."""
        self.set_policy(cfg.input_timeout, cfg.on_input_timeout)
        self._wait_since = None
        for name in list(self._idle):
            self._node.destroy_subscription(self._idle.pop(name))
        self.brake.start(cfg, n, recording)
        for ch in self.channels.values():
            ch.start(cfg)

    def set_policy(self, timeout: float, on_timeout: str) -> None:
        """Report inputs older than ``timeout`` [s wall]; ``on_timeout``: hold/emergency."""
        self.timeout = float(timeout)
        self.on_timeout = on_timeout

    def scan_graph(self) -> None:
        """
        Subscribe to input topics no input of the run takes, to count and reject them.

        Brake-input topics of other modes and of coaches that do not exist; command topics
        of a kind with an ``idle_reason`` for vehicles that do not take it. (Graph-scan
        timer, executor thread.)
        """
        node = self._node
        ns = node.get_namespace().rstrip('/') + '/'
        try:
            found = node.get_topic_names_and_types()
        except Exception:  # noqa: BLE001 - shutting down
            return

        def room() -> bool:
            return (self.brake.extra_subscriptions + len(self._idle)
                    < MAX_EXTRA_SUBSCRIPTIONS)

        n = self.brake.buffer.n
        for name, types in found:
            if name in self._idle or not name.startswith(ns):
                continue
            for kind in COMMAND_KINDS:
                if not kind.idle_reason or kind.msgtype not in types:
                    continue
                m = kind.pattern.fullmatch(name[len(ns):])
                if m is None or self.channels[kind.name].subscribed(name):
                    continue
                if not room():
                    return
                self._subscribe_idle(name, kind, int(m.group(1)), n)
        self.brake.scan(found, ns, room)

    def _subscribe_idle(self, resolved: str, kind: InputKind, vehicle: int, n: int) -> None:
        """Count and reject the messages of a topic no vehicle of ours takes."""
        if 1 <= vehicle <= n:
            why = (kind.idle_reason, f'vehicle {vehicle} takes no {kind.label}')
        else:
            why = ('unknown_coach', f'coach index outside 1..{n}')

        def reject(data: bytes) -> None:
            self._reject(resolved, *why)

        self._idle[resolved] = self._node.create_subscription(
            message_class(kind.msgtype), resolved, reject, INPUT_QOS, raw=True)

    # -- the simulation thread (simulation lock held) --------------------------------------
    def discard_records(self) -> None:
        """Drop the accepted inputs not yet recorded (the run has ended)."""
        self.brake.discard_records()

    def apply(self, now: float, sim: TrainSimulator, record: Record) -> None:
        """Put the inputs received since the last call (or the fail-safes) into ``sim``."""
        emergency = self.on_timeout == 'emergency'
        for ch in self.channels.values():     # the table's order, not the arrival order
            ch.apply(now, sim, record, self.timeout, emergency)
        self.brake.apply(now, sim, record, self.timeout, emergency)

    def schedule_due(self, sim: TrainSimulator, until: float, record: Record) -> None:
        """``input_timing`` stamp: hand ``sim`` the brake inputs stamped up to ``until``."""
        self.brake.schedule_due(sim, until, record)
