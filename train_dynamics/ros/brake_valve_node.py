"""``brake_valve``: the driver's brake valve node, the head-end brake-pipe pressure source.

Publishes ``brake_pipe/pressure`` (``sensor_msgs/FluidPressure``, ABSOLUTE Pa = gauge +
``atmospheric_pressure``; ``header.stamp`` = node clock, so ``use_sim_time`` works) at
``publish_rate`` with reliable, keep-last 10 QoS. The handle follows the ``schedule``
parameter and ``ros2 param set brake_valve position <pos>`` moves it live (cancelling the rest
of the schedule). The ``position`` parameter always shows the current handle position: the
schedule updates it as it runs. The valve logic is :class:`BrakeValveModel` (no rclpy).

Run: ``ros2 run train_dynamics brake_valve --ros-args -p schedule:="['1.0:emergency']"``.
"""
from __future__ import annotations

import sys
from typing import Any

import rclpy
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.exceptions import ParameterException, ParameterUninitializedException
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure

from train_dynamics.physics.brake_valve import (DEFAULTS, DESCRIPTIONS, RANGES, SETTING_NAMES,
                                              BrakeValveModel, check_live_change, parse_schedule,
                                              validate_position, validate_settings)

__all__ = ['BrakeValveNode', 'BrakeValveModel', 'main', 'OUTPUT_QOS', 'TOPIC']

TOPIC = 'brake_pipe/pressure'
OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE)

#: Node parameters beyond the model's: name -> (default, description, (min, max)).
NODE_PARAMETERS: dict[str, tuple[Any, str, tuple[float, float]]] = {
    'publish_rate': (50.0, 'Publishing rate of brake_pipe/pressure [Hz] (node clock).',
                     (0.1, 1000.0)),
    'atmospheric_pressure': (101325.0, 'Atmospheric pressure [Pa]: published absolute pressure '
                             '= gauge + atmospheric_pressure.', (50000.0, 150000.0)),
}


def _range_descriptor(name: str, description: str, lo: float, hi: float,
                      integer: bool = False) -> ParameterDescriptor:
    if integer:
        return ParameterDescriptor(name=name, description=description,
                                   integer_range=[IntegerRange(from_value=int(lo), to_value=int(hi),
                                                               step=1)])
    return ParameterDescriptor(name=name, description=description,
                               floating_point_range=[FloatingPointRange(from_value=float(lo),
                                                                        to_value=float(hi))])


class BrakeValveNode(Node):
    """Driver's brake valve: publishes the head brake-pipe pressure (absolute Pa)."""

    def __init__(self, **kwargs: Any) -> None:
        super().__init__('brake_valve', **kwargs)
        self._internal_set = False
        self._declare()
        params = {name: self.get_parameter(name).value
                  for name in (*SETTING_NAMES, 'position', 'schedule')}
        # Raises ValueError (caught by main) for an invalid combination given at startup.
        self.model = BrakeValveModel.from_params(params)
        self._atm = float(self.get_parameter('atmospheric_pressure').value)
        self._rate = float(self.get_parameter('publish_rate').value)
        self._t0 = self.get_clock().now()
        self._last_position = self.model.position
        self._pub = self.create_publisher(FluidPressure, TOPIC, OUTPUT_QOS)
        self._timer = self.create_timer(1.0 / self._rate, self._on_timer)
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._sync_position_parameter()
        sched = ', '.join(f'{e.time:g}s:{e.position}' for e in self.model.schedule) or 'none'
        self.get_logger().info(
            f'brake valve: handle {self.model.position}, schedule [{sched}], publishing '
            f'{self.resolve_topic_name(TOPIC)} at {self._rate:g} Hz')
        self._publish()

    # -- parameters ---------------------------------------------------------------------
    def _declare(self) -> None:
        self.declare_parameter('position', DEFAULTS['position'], ParameterDescriptor(
            name='position', description=DESCRIPTIONS['position']))
        self.declare_parameter('schedule', Parameter.Type.STRING_ARRAY, ParameterDescriptor(
            name='schedule', description=DESCRIPTIONS['schedule']))
        try:
            self.get_parameter('schedule')
        except ParameterUninitializedException:   # no override given: an empty schedule
            self.set_parameters([Parameter('schedule', Parameter.Type.STRING_ARRAY, [])])
        for name in SETTING_NAMES:
            lo, hi = RANGES[name]
            self.declare_parameter(name, DEFAULTS[name], _range_descriptor(
                name, DESCRIPTIONS[name], lo, hi, integer=(name == 'service_steps')))
        for name, (default, description, (lo, hi)) in NODE_PARAMETERS.items():
            self.declare_parameter(name, default, _range_descriptor(name, description, lo, hi))

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate a batch as a whole; apply it only if every value is acceptable."""
        if self._internal_set:    # the node reflecting a schedule step in `position`
            return SetParametersResult(successful=True)
        changes = {p.name: p.value for p in params}
        try:
            settings_changes = {k: v for k, v in changes.items() if k in SETTING_NAMES}
            settings = validate_settings({**self.model.settings, **settings_changes})
            if 'position' in changes:
                validate_position(changes['position'], settings)
            elif settings_changes:
                # The handle position in use (and, unless replaced, every pending schedule
                # step) must stay valid under the new settings.
                check_live_change(self.model, settings_changes,
                                  check_pending='schedule' not in changes)
            if 'schedule' in changes:
                parse_schedule(changes['schedule'], settings)
            for name in NODE_PARAMETERS:
                if name in changes:
                    value = changes[name]
                    lo, hi = NODE_PARAMETERS[name][2]
                    if not (isinstance(value, float) and lo <= value <= hi):
                        raise ValueError(f'{name}: must be a number in [{lo:g}, {hi:g}]')
        except ValueError as exc:
            reason = str(exc)
            self.get_logger().warning(f'rejected parameter change: {reason}')
            return SetParametersResult(successful=False, reason=reason)

        # Everything valid: apply (current time first, so changes act from now on).
        self._advance()
        if settings_changes:
            self.model.settings = settings
        if 'position' in changes:
            cancelled = len(self.model.pending)
            self.model.set_position(changes['position'])
            self.get_logger().info(
                f'handle moved to {self.model.position} (target {self.model.target:.0f} Pa gauge)'
                + (f'; {cancelled} pending schedule step(s) cancelled' if cancelled else ''))
            self._last_position = self.model.position
        if 'schedule' in changes:
            self.model.set_schedule(changes['schedule'])
            self.get_logger().info(f'new schedule from now: {list(changes["schedule"])}')
        if 'atmospheric_pressure' in changes:
            self._atm = float(changes['atmospheric_pressure'])
        if 'publish_rate' in changes and changes['publish_rate'] != self._rate:
            self._rate = float(changes['publish_rate'])
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / self._rate, self._on_timer)
        return SetParametersResult(successful=True)

    def _sync_position_parameter(self) -> None:
        """Make the `position` parameter show the handle (after a schedule step)."""
        if self.get_parameter('position').value == self.model.position:
            return
        self._internal_set = True
        try:
            self.set_parameters([Parameter('position', Parameter.Type.STRING,
                                           self.model.position)])
        finally:
            self._internal_set = False

    # -- time and output ----------------------------------------------------------------
    def _elapsed(self) -> float:
        return (self.get_clock().now() - self._t0).nanoseconds * 1e-9

    def _advance(self) -> None:
        t = self._elapsed()
        if t < self.model.t - 1e-3:
            # The clock went backwards (simulation reset / bag loop with use_sim_time):
            # start over from t = 0 with the current initial position and schedule.
            self.get_logger().info('clock jumped back: restarting the brake valve schedule')
            self._t0 = self.get_clock().now()
            self.model.reset()
            t = 0.0
        self.model.advance_to(t)

    def _publish(self) -> None:
        if not self.context.ok():
            return
        msg = FluidPressure()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = 'brake_valve'
        msg.fluid_pressure = self.model.pressure + self._atm
        msg.variance = 0.0
        self._pub.publish(msg)

    def _on_timer(self) -> None:
        self._advance()
        if self.model.position != self._last_position:
            self.get_logger().info(
                f't = {self.model.t:.3f} s: handle {self._last_position} -> {self.model.position} '
                f'(target {self.model.target:.0f} Pa gauge)')
            self._last_position = self.model.position
            self._sync_position_parameter()
        self._publish()


def main(args: list[str] | None = None) -> int:
    """Entry point of ``ros2 run train_dynamics brake_valve``; SIGINT/SIGTERM stop it cleanly."""
    rclpy.init(args=args)
    node = None
    try:
        node = BrakeValveNode()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (ValueError, ParameterException) as exc:
        if not rclpy.ok():      # a signal arrived while starting up
            return 0
        print(f'brake_valve: invalid parameters: {exc}', file=sys.stderr)
        return 2
    except Exception:
        # SIGINT/SIGTERM shut the context down from the signal handler; a callback that was
        # publishing at that instant (or spin starting) then fails with an RCLError. That is
        # a clean stop, not a crash. Anything else is re-raised.
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        try:
            rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 - a signal handler shut the context down first
            pass
    return 0


if __name__ == '__main__':
    sys.exit(main())
