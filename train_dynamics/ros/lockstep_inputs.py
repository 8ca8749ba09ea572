"""
The lock-step side of ``sim_node``'s inputs: which inputs answered an output, and what is refused.

:class:`LockstepInputs` is a part of :class:`train_dynamics.ros.controller_inputs.ControllerInputs`
(a mixin over its channels) that :class:`train_dynamics.ros.run_control.RunControl` asks
before it releases a lock-step period. ``lockstep_inputs`` declares the families a period
waits for (:data:`LOCKSTEP_INPUTS`; each kind of the input table names its family,
:data:`train_dynamics.input_kinds.INPUT_KINDS`); ``lockstep_answer`` says what answers:

- ``echo``: a brake input whose ``header.stamp`` equals the output's stamp;
- ``clock``: a brake input stamped at or after the period's time (the node publishes
  ``/clock``; a controller on ``use_sim_time`` answers from its own timer).

A ``std_msgs/Float64`` or ``Int8`` command (traction, EP, WSP valve, the brake control
unit's ``brake_demand``, ``brake_emergency``, ``ed_brake/trip``, the ED forces) has no stamp:
it answers the latest output published before it arrived, in both; a stamped command kind
(its row's ``stamped``) the output of its header stamp.

What the lock-step refuses, so that a run is the same on every run or ends saying why:

- a second answer to one output on one input (a controller answering twice; in ``clock``: a
  second message stamped in the same period) is not used: the first wins; counted
  (:attr:`LockstepInputs.duplicates`, ``/diagnostics`` ``lockstep_duplicate_answers``, the
  run's summary) with a throttled warning;
- a second publisher on a declared input, and a best-effort publisher (declared inputs are
  subscribed reliable: a lost command would stall the loop), are found before the first period
  and before each release while that is cheap (:data:`CHEAP_TOPICS` topics at most;
  :meth:`LockstepInputs.publisher_problems`): the run control ends the run with an error;
- a declared family the train does not have is a configuration error
  (:func:`lockstep_input_error`).

Outside lock-step, ``wait_for_input`` holds t = 0 until the brake-input topics have
publishers, for at most that many wall seconds (:meth:`LockstepInputs.hold_for_input`).
"""
from __future__ import annotations

import time
from typing import Any

import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from train_dynamics.input_kinds import family_active, FAMILY_NEEDS, INPUT_KINDS
from train_dynamics.ros.node_parameters import SIM_NODE_PARAMETERS

#: ``lockstep_inputs``: the controller inputs a lock-step period can wait for
LOCKSTEP_INPUTS = SIM_NODE_PARAMETERS['lockstep_inputs'].choices
BRAKE = LOCKSTEP_INPUTS[0]     # the brake pressures' family
#: declared lock-step inputs: reliable (a lost command would stall the loop until its timeout)
LOCKSTEP_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
#: publishers are counted before every period's release up to this many declared topics
#: (one graph query each); beyond, at the start and by the graph scan (every 2 s)
CHEAP_TOPICS = 8
START_SETTLE = 0.3       # [s wall] wait_for_input: pause after the inputs are connected


def lockstep_input_error(cfg: Any, families: tuple[str, ...]) -> str | None:
    """
    Return why ``families`` (``lockstep_inputs``) cannot be waited for on ``cfg``'s train.

    None when every declared family has an input topic on this train (``brake`` always has).
    """
    missing = [f for f in families if not family_active(f, cfg)]
    if not missing:
        return None
    return (f'lockstep_inputs {", ".join(missing)}: the train has no such input '
            f'({"; ".join(FAMILY_NEEDS[f] for f in missing)}); a lock-step period would not '
            'wait for it')


class LockstepInputs:
    """
    Lock-step queries and refusals over :class:`ControllerInputs`' channels (see the module).

    The declared families and the answer rule are set by :meth:`configure_lockstep`
    (executor thread, simulation lock held); the duplicate check runs in the subscription
    callbacks (executor thread, input lock held); the queries on the simulation thread.
    """

    _ls_families: tuple[str, ...] = ()    # declared families (empty: not in lock-step)
    _ls_clock = False                     # lockstep_answer clock
    _ls_period_ns = -1                    # stamp of the latest output published

    # -- configuration (executor thread, simulation lock held) -----------------------------
    def configure_lockstep(self, families: tuple[str, ...], clock: bool) -> None:
        """Declare the families a period waits for (empty: free running) and the answer rule."""
        self._ls_families = tuple(families)
        self._ls_clock = bool(clock)
        for family, part in self._command_families():
            part.dedupe = family in families
            part.on_duplicate = self.duplicate
            part.set_qos(LOCKSTEP_QOS if family in families else self.brake.free_qos)
        self.brake.set_qos(LOCKSTEP_QOS if BRAKE in families else self.brake.free_qos)

    @property
    def duplicates(self) -> int:
        """Return the answers not used because their input had answered the output already."""
        return self.brake.duplicates + sum(part.duplicates
                                           for _, part in self._command_families())

    def _command_families(self) -> tuple[tuple[str, Any], ...]:
        """Return (family, channel) of every command channel, in the table's order."""
        return tuple((kind.family, self.channels[kind.name]) for kind in INPUT_KINDS
                     if kind.name in self.channels)

    # -- subscription callbacks (executor thread, input lock held) -------------------------
    def _duplicate_answer(self, last_ns: int, stamp_ns: int) -> bool:
        """
        Return True if a brake input stamped ``stamp_ns`` answers what its input answered.

        ``last_ns``: the stamp of the input's last accepted message. Echo: the same stamp
        again; clock: a second message stamped in the present period.
        """
        if BRAKE not in self._ls_families:
            return False
        if stamp_ns == last_ns:
            return True
        period = self._ls_period_ns
        return self._ls_clock and period >= 0 and stamp_ns >= period and last_ns >= period

    def duplicate(self, resolved: str) -> None:
        """Count and warn (throttled) about an answer that is not used (executor thread)."""
        if self._throttle(('duplicate', resolved), time.monotonic()) is not None:
            self._log.warning(
                f'lockstep: a second answer on {resolved} to one output is not used (the '
                f'first answers; {self.duplicates} such so far): answer each output once')

    # -- the simulation thread (simulation lock held) ---------------------------------------
    def output_published(self, t_ns: int) -> None:
        """Take note of an output stamped ``t_ns`` about to go out: Float64 commands answer it."""
        self._ls_period_ns = t_ns
        for _, part in self._command_families():
            part.output_published(t_ns)

    def unanswered(self, t_ns: int, families: tuple[str, ...] = (BRAKE,)) -> list[str]:
        """
        Return the input topics of ``families`` whose applied input does not answer ``t_ns``.

        ``brake``: every active brake input holds a value stamped ``t_ns`` (``clock``: at or
        after it); ``traction``, ``ep``, ``wsp``, ``blending``: the applied command (valve
        state, demand) arrived
        after the output stamped ``t_ns`` was published. Empty: every declared input answered.
        """
        out: list[str] = []
        if BRAKE in families:
            stamps = self.brake.applied_stamp
            missing = np.nonzero(stamps < t_ns if self._ls_clock else stamps != t_ns)[0]
            out += [self.brake.buffer.topics[k] for k in missing[:10]]
        for family, part in self._command_families():
            if family in families:
                out += part.unanswered(t_ns, self._ls_clock)
        return out

    def answered(self, t_ns: int, families: tuple[str, ...] = (BRAKE,)) -> bool:
        """Lock-step: return True if every input of ``families`` answers the output ``t_ns``."""
        if families == (BRAKE,):        # the common case, without building lists
            stamps = self.brake.applied_stamp
            return bool(np.all(stamps >= t_ns if self._ls_clock else stamps == t_ns))
        return not self.unanswered(t_ns, families)

    def connected(self, families: tuple[str, ...] = (BRAKE,)) -> bool:
        """Return True if every active input topic of ``families`` has a publisher."""
        return not self.unconnected(families, limit=1)

    def unconnected(self, families: tuple[str, ...], limit: int = 10) -> list[str]:
        """Return (up to ``limit``) input topics of ``families`` without a publisher."""
        out = []
        for sub in self._lockstep_subscriptions(families):
            if sub.get_publisher_count() == 0:
                out.append(sub.topic_name)
                if len(out) >= limit:
                    break
        return out

    def lockstep_topics(self, families: tuple[str, ...]) -> int:
        """Return the number of input topics of ``families`` (the cost of a publisher count)."""
        return len(self._lockstep_subscriptions(families))

    def publisher_problems(self, families: tuple[str, ...], qos: bool = False,
                           scanned: bool = False) -> list[str]:
        """
        Return what makes the lock-step on ``families`` undeterministic ([]: nothing).

        A second publisher on an input topic (their answers mix); with ``qos`` also a
        best-effort publisher (it cannot reach the reliable subscription). ``scanned``: only
        what the last graph scan found on the brake inputs (no graph query: many topics).
        """
        if scanned:
            return ([f'{count} publishers on {name}'
                     for name, count in sorted(self.multiple_publishers.items())]
                    if BRAKE in families else [])
        out = []
        for sub in self._lockstep_subscriptions(families):
            if not qos:
                count = sub.get_publisher_count()     # matched ones: cheap
                if count > 1:
                    out.append(f'{count} publishers on {sub.topic_name}')
                continue
            infos = self._node.get_publishers_info_by_topic(sub.topic_name)   # the graph's
            if len(infos) > 1:
                out.append(f'{len(infos)} publishers on {sub.topic_name}')
            weak = sum(1 for info in infos
                       if info.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT)
            if weak:
                out.append(f'{weak} best-effort publisher(s) on {sub.topic_name} (a lock-step '
                           'input is subscribed reliable: a lost command would stall the '
                           'loop; publish reliable)')
        return out

    def missing_inputs(self, families: tuple[str, ...]) -> list[str]:
        """Return the families of ``families`` this run has no input topic of."""
        active: dict[str, bool] = {}
        for f, part in self._command_families():
            active[f] = active.get(f, False) or part.active
        return [f for f in families if f in active and not active[f]]

    def _lockstep_subscriptions(self, families: tuple[str, ...]) -> list[Any]:
        subs: list[Any] = []
        if BRAKE in families:
            subs += list(self.brake.active)
        for family, part in self._command_families():
            if family in families:
                subs += part.subscriptions()
        return subs

    def lockstep_topic_names(self, families: tuple[str, ...]) -> list[str]:
        """Return the resolved input topics of ``families``."""
        return [sub.topic_name for sub in self._lockstep_subscriptions(families)]

    def hold_for_input(self, now: float) -> bool:
        """``wait_for_input``: return True while the start waits for brake-input publishers."""
        limit = self.wait_for_input
        if limit <= 0.0:
            return False
        if self._wait_since is None:
            self._wait_since = now
            self._wait_ready = None
            self._log.info(f'waiting up to {limit:g} s for publishers on the '
                           f'{len(self.brake.active)} brake-input topic(s) of '
                           f'{self.brake.buffer.mode} '
                           'before starting the clock')
        if self.connected():
            if self._wait_ready is None:
                self._wait_ready = now
            if now - self._wait_ready < START_SETTLE:
                return True          # let the other direction (e.g. their /clock) match too
            self._log.info(f'brake input connected after {now - self._wait_since:.2f} s; '
                           'starting')
            return False
        self._wait_ready = None
        if now - self._wait_since >= limit:
            self._log.warning(f'no publisher on every brake-input topic after {limit:g} s; '
                              'starting anyway')
            return False
        return True
