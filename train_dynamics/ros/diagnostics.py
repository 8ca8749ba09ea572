"""
``/diagnostics`` of ``sim_node`` (~1 Hz wall): what the two statuses say, built from reports.

- ``train_dynamics: simulation``: real-time factor and the achieved one, sim time, steps, lag,
  integrator health, pending parameter changes, recording;
- ``train_dynamics: run metrics``: the running maxima of the run metrics
  (:class:`train_dynamics.physics.metrics.RunMetrics`: largest tension and compression with
  coupler and time, deceleration, jerk, blocking, impacts), WARN with the worst crossing
  (coupler or vehicle, value, time) once ``coupler_force_limit`` or ``jerk_limit`` is crossed;
- ``train_dynamics: brake input``: input age, staleness, emergency (the fail-safe), accepted
  and rejected counts per reason, of the brake inputs and the locomotives' traction commands
  (``coach_<i>/traction/command``) together, publishers of a wrong message type on an input
  topic (``wrong_type``: their number; ``wrong_type_topics``: which, with their types; WARN),
  active input topics with more than one publisher (``multiple_publishers``; WARN: their values
  mix), inputs applied after their stamp (``late_inputs``, ``input_timing`` stamp).
- ``train_dynamics: brake system`` (``brake_system`` ep or ecp, or remote locomotives):
  the EP / ECP train line (WARN when lost: EP brakes through the pipe, ECP makes a penalty
  application), the command at the head and at the vehicles, the vehicles' cylinder valves
  filling / lapped / venting; the distributed-power radio link (WARN when lost: the remotes
  idle and lap their brake valves), the age of its last message, messages sent, lost and
  received.

The status names start with the node's full name without the leading slash
(:func:`status_name`): ``train_dynamics: simulation`` for the node in the root namespace,
``train1/train_dynamics: simulation`` under ``/train1``, so two trains' statuses stay apart.

The node fills a :class:`SimulationReport` and an :class:`InputReport` under the simulation
lock; building the message needs no lock.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue

from train_dynamics.topics import NODE_NAME

SIMULATION = f'{NODE_NAME}: simulation'
BRAKE_INPUT = f'{NODE_NAME}: brake input'
RUN_METRICS = f'{NODE_NAME}: run metrics'
_LEVELS = {'OK': DiagnosticStatus.OK, 'WARN': DiagnosticStatus.WARN}


@dataclass
class SimulationReport:
    """The state of the simulation for one diagnostics message."""

    t: float                    # [s] simulation time
    steps: int
    n: int                      # coaches
    fault: str | None
    finished: bool
    behind: float               # [s wall] behind schedule
    real_time_factor: float
    achieved: float             # achieved real-time factor
    lag_dropped: float          # [s wall]
    lag_events: int
    model_type: str
    scale_factor: float         # [s/m]
    h: float                    # [s] integration step
    rate: float                 # [Hz] publish_rate
    duration: float             # [s]
    behind_warn: float          # [s wall] behind by more: WARN
    pending: str = ''
    recording: str = ''         # bag path, '' when not recording
    recorded: int = 0
    backlog: int = 0
    backlog_bytes: int = 0
    record_error: str | None = None
    #: the simulator's integration_stats (error-controlled stepping), None: not given
    integration: dict | None = None
    #: the run control's values (sync_mode, paused, lock-step waits), in this order
    control: dict[str, str] = field(default_factory=dict)
    #: lock-step: why the simulation waits ('' when it does not)
    waiting: str = ''
    #: parameter files with no section for the node (WARN), '' when none
    parameter_file_warning: str = ''
    #: the simulation thread's scheduling ('SCHED_FIFO <priority>' or 'normal')
    scheduling: str = ''
    #: the node's CPU wake-up latency request ('0 us', 'none', 'not granted (...)')
    cpu_wake_latency: str = ''


def integration_values(stats: dict | None) -> dict[str, str]:
    """
    Return the diagnostics values of the integration.

    ``stats``: :attr:`TrainSimulator.integration_stats`. The standstill counters
    (hold_solves, hold_capped) in both stepping modes; the error control's counters only
    when it runs. Empty when None.
    """
    if not stats:
        return {}
    hold = {'hold_solves': str(stats['hold_solves']), 'hold_capped': str(stats['hold_capped'])}
    if not stats.get('adaptive'):
        return hold
    h_min = stats['h_min']
    return hold | {
        'chain_steps': str(stats['steps']), 'step_rejections': str(stats['rejected']),
        'smallest_step_s': f'{h_min:.3e}' if h_min != float('inf') else '',
        'steps_last_output_period': str(stats['steps_last_period']),
        'steps_max_output_period': str(stats['steps_max_period']),
        'fallback_periods': str(stats['fallback_periods']),
    }


@dataclass
class InputReport:
    """The state of the brake inputs and traction commands for one diagnostics message."""

    mode: str
    timeout: float              # [s wall] input_timeout
    on_timeout: str
    max_age: float              # [s wall] age of the oldest input (brake or traction)
    stale: bool                 # a brake input or a traction command is stale
    emergency: bool             # a fail-safe holds: emergency brake or traction command 0
    stale_names: str            # the stale topics
    accepted: int
    rejected: dict[str, int]
    last_rejected: str
    wrong_type: dict[str, list[str]] = field(default_factory=dict)   # topic -> publisher types
    multiple_publishers: dict[str, int] = field(default_factory=dict)  # topic -> publishers
    late: int = 0               # input_timing stamp: applied a step or more after their stamp


@dataclass
class BrakeSystemReport:
    """The state of the EP / ECP train line and the distributed-power radio link."""

    system: str                 # brake_system: pneumatic, ep or ecp
    train_line: bool            # EP / ECP train line healthy
    head_command: float         # EP / ECP command at the head [fraction of full service]
    vehicle_command: float      # command the vehicles' valves follow now (0: line lost)
    filling: int                # vehicles whose cylinder valve fills
    lapped: int
    venting: int
    remotes: str = ''           # remote locomotives (coach_<i>, ...), '' when none
    radio_ok: bool = True
    radio_age: float = 0.0      # [s] since the remotes' last message
    radio_sent: int = 0
    radio_lost: int = 0
    radio_received: int = 0


def brake_system_status(r: BrakeSystemReport, hardware_id: str) -> DiagnosticStatus:
    """Build the ``train_dynamics: brake system`` status."""
    problems = []
    if r.system != 'pneumatic' and not r.train_line:
        problems.append('EP train line lost: braking through the pipe' if r.system == 'ep'
                        else 'ECP train line lost: penalty (full) application')
    if r.remotes and not r.radio_ok:
        problems.append(f'distributed-power radio lost ({r.radio_age:.1f} s without a '
                        'message): remotes idle, brake valves lapped')
    level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
    kv = {'brake_system': r.system, 'train_line': 'ok' if r.train_line else 'lost',
          'command_head': f'{r.head_command:g}', 'command_vehicles': f'{r.vehicle_command:g}',
          'valves_filling': str(r.filling), 'valves_lapped': str(r.lapped),
          'valves_venting': str(r.venting), 'remotes': r.remotes}
    if r.remotes:
        kv.update({'radio_link': 'up' if r.radio_ok else 'lost',
                   'radio_age_s': f'{r.radio_age:.3f}', 'radio_sent': str(r.radio_sent),
                   'radio_lost': str(r.radio_lost), 'radio_received': str(r.radio_received)})
    return DiagnosticStatus(level=level, name=status_name(hardware_id, 'brake system'),
                            message='; '.join(problems) or 'ok', hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in kv.items()])


def status_name(hardware_id: str, what: str) -> str:
    """Return the status name of ``what`` for the node ``hardware_id`` (its full name)."""
    return f'{hardware_id.lstrip("/") or NODE_NAME}: {what}'


def _level_message(r: SimulationReport) -> tuple[bytes, str]:
    rtf, achieved = r.real_time_factor, r.achieved
    if r.fault is not None:
        return DiagnosticStatus.ERROR, f'numerical fault: {r.fault}; stopped, call reset'
    if r.record_error:
        return DiagnosticStatus.ERROR, f'recording failed: {r.record_error}'
    if r.finished:
        return DiagnosticStatus.OK, 'finished (duration reached)'
    if r.waiting:
        return DiagnosticStatus.WARN, r.waiting
    if r.parameter_file_warning:
        return DiagnosticStatus.WARN, r.parameter_file_warning
    if rtf > 0 and r.behind > r.behind_warn:
        return DiagnosticStatus.WARN, (f'behind real time by {r.behind:.3f} s (rtf {rtf:g}, '
                                       f'achieved {achieved:.3g})')
    if rtf > 0:
        return DiagnosticStatus.OK, f'running, real_time_factor {rtf:g}, achieved {achieved:.3g}'
    return DiagnosticStatus.OK, f'running as fast as possible, achieved rtf {achieved:.3g}'


def simulation_status(r: SimulationReport, hardware_id: str) -> DiagnosticStatus:
    """Build the ``train_dynamics: simulation`` status."""
    level, message = _level_message(r)
    kv = {
        'sim_time': f'{r.t:.6f}', 'steps': str(r.steps),
        'real_time_factor': f'{r.real_time_factor:g}',
        'achieved_real_time_factor': f'{r.achieved:.6g}', 'behind_s': f'{r.behind:.6f}',
        'lag_dropped_s': f'{r.lag_dropped:.6f}', 'lag_drop_events': str(r.lag_events),
        'integrator': 'fault' if r.fault else 'ok', 'fault': r.fault or '',
        'num_coaches': str(r.n), 'model_type': str(r.model_type),
        'scale_factor': f'{float(r.scale_factor):g}', 'integration_step': f'{r.h:g}',
        'publish_rate': f'{r.rate:g}', 'duration': f'{r.duration:g}',
        'finished': str(r.finished).lower(), 'pending_changes': r.pending,
        'recording': r.recording, 'recorded_messages': str(r.recorded),
        'record_backlog': str(r.backlog), 'record_backlog_bytes': str(r.backlog_bytes),
        'scheduling': r.scheduling, 'cpu_wake_latency': r.cpu_wake_latency,
    }
    kv.update(integration_values(r.integration))
    kv.update(r.control)
    kv['parameter_file_warning'] = r.parameter_file_warning
    return DiagnosticStatus(level=level, name=status_name(hardware_id, 'simulation'),
                            message=message,
                            hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in kv.items()])


def input_status(r: InputReport, hardware_id: str) -> DiagnosticStatus:
    """Build the ``train_dynamics: brake input`` status."""
    rejected = sum(r.rejected.values())
    if r.emergency:
        level = DiagnosticStatus.ERROR
        message = (f'stale (> {r.timeout:g} s): emergency fail-safe applied (brake / traction '
                   f'command 0) ({r.stale_names})')
    elif r.stale:
        level = DiagnosticStatus.WARN
        message = f'stale (> {r.timeout:g} s): holding the last values ({r.stale_names})'
    elif r.wrong_type:
        level = DiagnosticStatus.WARN
        message = (f'{_wrong_type_count(r)} publisher(s) of the wrong type on input topics: '
                   f'{_wrong_type_list(r)}')
    elif rejected:
        level = DiagnosticStatus.WARN
        message = f'{rejected} input message(s) rejected (last: {r.last_rejected})'
    elif r.multiple_publishers:
        level = DiagnosticStatus.WARN
        message = ('more than one publisher on an active input (their values mix): '
                   + _publishers_list(r))
    else:
        level, message = DiagnosticStatus.OK, 'ok'
    kv = {'brake_input': r.mode, 'input_timeout': f'{r.timeout:g}',
          'on_input_timeout': str(r.on_timeout), 'input_age_s': f'{r.max_age:.3f}',
          'stale': str(r.stale).lower(), 'stale_inputs': r.stale_names,
          'emergency_applied': str(r.emergency).lower(),
          'accepted': str(r.accepted), 'rejected_total': str(rejected)}
    kv.update({f'rejected_{reason}': str(c) for reason, c in r.rejected.items()})
    kv['last_rejected'] = r.last_rejected
    kv['wrong_type'] = str(_wrong_type_count(r))
    kv['wrong_type_topics'] = _wrong_type_list(r)
    kv['multiple_publishers'] = _publishers_list(r)
    kv['late_inputs'] = str(r.late)
    return DiagnosticStatus(level=level, name=status_name(hardware_id, 'brake input'),
                            message=message,
                            hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in kv.items()])


def _publishers_list(r: InputReport) -> str:
    """Return 'topic (k publishers), ...' of the active inputs with more than one."""
    return ', '.join(f'{topic} ({k} publishers)'
                     for topic, k in sorted(r.multiple_publishers.items()))


def _wrong_type_count(r: InputReport) -> int:
    return sum(len(types) for types in r.wrong_type.values())


def _wrong_type_list(r: InputReport) -> str:
    """Return 'topic (type, ...), ...' of the input topics with wrong-type publishers."""
    return ', '.join(f'{topic} ({", ".join(sorted(set(types)))})'
                     for topic, types in sorted(r.wrong_type.items()))


def metrics_status(metrics: tuple[str, str, list[tuple[str, str]]],
                   hardware_id: str) -> DiagnosticStatus:
    """Build the run-metrics status from ``RunMetrics.diagnostic()`` (level, message, values)."""
    level, message, values = metrics
    return DiagnosticStatus(level=_LEVELS[level], name=status_name(hardware_id, 'run metrics'),
                            message=message,
                            hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in values])


def diagnostic_array(sim: SimulationReport, inputs: InputReport, hardware_id: str,
                     stamp: Time, metrics: tuple | None = None,
                     brake_system: BrakeSystemReport | None = None) -> DiagnosticArray:
    """Build the DiagnosticArray: simulation, brake input, run metrics, brake system."""
    statuses = [simulation_status(sim, hardware_id), input_status(inputs, hardware_id)]
    if metrics is not None:
        statuses.append(metrics_status(metrics, hardware_id))
    if brake_system is not None:
        statuses.append(brake_system_status(brake_system, hardware_id))
    msg = DiagnosticArray(status=statuses)
    msg.header.stamp = stamp
    return msg
