"""
``brake_valve``: the driver's brake valve node, the head-end brake-pipe pressure source.

Publishes ``brake_pipe/pressure`` (``sensor_msgs/FluidPressure``, ABSOLUTE Pa = gauge +
``atmospheric_pressure``; ``header.stamp`` = node clock, so ``use_sim_time`` works) at
``publish_rate`` with reliable, keep-last 10 QoS. The handle follows the ``schedule``
parameter and ``ros2 param set brake_valve position <pos>`` moves it live (cancelling the rest
of the schedule). The ``position`` parameter always shows the current handle position: the
schedule updates it as it runs. The valve logic is :class:`BrakeValveModel` (no rclpy); its
parameters are :data:`~train_dynamics.physics.brake_valve.VALVE_PARAMETERS` and
:data:`~train_dynamics.physics.brake_valve.VALVE_NODE_PARAMETERS`, all live.

Run: ``ros2 run train_dynamics brake_valve --ros-args -p schedule:="['1.0:emergency']"``.
"""
from __future__ import annotations

import sys
from typing import Any

from rclpy.exceptions import ParameterException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import FluidPressure

from train_dynamics import topics
from train_dynamics.physics.brake_valve import (BrakeValveModel, check_live_change,
                                                parse_schedule, SETTING_NAMES,
                                                validate_position, validate_settings,
                                                VALVE_NODE_PARAMETERS, VALVE_PARAMETERS)
from train_dynamics.ros import parameters as ros_parameters
from train_dynamics.ros.executor import ExitOn, run_node, shutdown_safe

__all__ = ['BrakeValveNode', 'BrakeValveModel', 'main', 'OUTPUT_QOS', 'TOPIC']

TOPIC = topics.HEAD_PIPE_TOPIC
OUTPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                        reliability=ReliabilityPolicy.RELIABLE)
#: every parameter the node declares: the model's and its own
SPECS = {**VALVE_PARAMETERS, **VALVE_NODE_PARAMETERS}


class BrakeValveNode(Node):
    """
    Driver's brake valve: publishes the head brake-pipe pressure (absolute Pa).

    Single-threaded: every callback runs on the executor thread; no locks.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(topics.VALVE_NODE_NAME, **kwargs)
        self._internal_set = False      # the node itself sets `position` (schedule step)
        ros_parameters.declare_parameters(self, SPECS)
        params = ros_parameters.parameter_values(self, VALVE_PARAMETERS)
        # Raises ValueError (caught by main) for an invalid combination given at startup.
        self.model = BrakeValveModel.from_params(params)
        self._atm = float(self.get_parameter('atmospheric_pressure').value)
        self._rate = float(self.get_parameter('publish_rate').value)
        self._t0 = self.get_clock().now()
        self._last_position = self.model.position
        self._pub = self.create_publisher(FluidPressure, TOPIC, OUTPUT_QOS)
        self._timer = self.create_timer(1.0 / self._rate, shutdown_safe(self, self._on_timer))
        ros_parameters.watch_parameters(self, SPECS, self._check_parameters,
                                        self._apply_parameters,
                                        skip=lambda: self._internal_set)
        self._sync_position_parameter()
        sched = ', '.join(f'{e.time:g}s:{e.position}' for e in self.model.schedule) or 'none'
        self.get_logger().info(
            f'brake valve: handle {self.model.position}, schedule [{sched}], publishing '
            f'{self.resolve_topic_name(TOPIC)} at {self._rate:g} Hz')
        self._publish()

    # -- parameters ------------------------------------------------------------------------
    def _new_settings(self, changes: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
        """Return (the changed settings, all settings after the change), validated."""
        settings_changes = {k: v for k, v in changes.items() if k in SETTING_NAMES}
        return settings_changes, validate_settings({**self.model.settings, **settings_changes})

    def _check_parameters(self, changes: dict[str, Any]) -> None:
        """Set callback: raise ``ValueError`` unless the batch is acceptable as a whole."""
        settings_changes, settings = self._new_settings(changes)
        if 'position' in changes:
            validate_position(changes['position'], settings)
        elif settings_changes:
            # The handle position in use (and, unless replaced, every pending schedule
            # step) must stay valid under the new settings.
            check_live_change(self.model, settings_changes,
                              check_pending='schedule' not in changes)
        if 'schedule' in changes:
            parse_schedule(changes['schedule'], settings)

    def _apply_parameters(self, changes: dict[str, Any]) -> None:
        """Post-set callback: apply an accepted batch (current time first: acts from now)."""
        self._advance()
        settings_changes, settings = self._new_settings(changes)
        if settings_changes:
            self.model.settings = settings
        log = self.get_logger()
        if 'position' in changes:
            cancelled = len(self.model.pending)
            self.model.set_position(changes['position'])
            log.info(
                f'handle moved to {self.model.position} (target {self.model.target:.0f} Pa gauge)'
                + (f'; {cancelled} pending schedule step(s) cancelled' if cancelled else ''))
            self._last_position = self.model.position
        if 'schedule' in changes:
            self.model.set_schedule(changes['schedule'])
            log.info(f'new schedule from now: {list(changes["schedule"])}')
        if 'atmospheric_pressure' in changes:
            self._atm = float(changes['atmospheric_pressure'])
        if 'publish_rate' in changes and changes['publish_rate'] != self._rate:
            self._rate = float(changes['publish_rate'])
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / self._rate,
                                            shutdown_safe(self, self._on_timer))

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

    # -- time and output -------------------------------------------------------------------
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
        msg.header.frame_id = topics.VALVE_NODE_NAME
        msg.fluid_pressure = self.model.pressure + self._atm
        msg.variance = 0.0
        self._pub.publish(msg)

    def _on_timer(self) -> None:
        self._advance()
        if self.model.position != self._last_position:
            self.get_logger().info(
                f't = {self.model.t:.3f} s: handle {self._last_position} -> '
                f'{self.model.position} (target {self.model.target:.0f} Pa gauge)')
            self._last_position = self.model.position
            self._sync_position_parameter()
        self._publish()


def main(args: list[str] | None = None) -> int:
    """Run ``ros2 run train_dynamics brake_valve``; SIGINT/SIGTERM stop it cleanly."""
    return run_node('brake_valve', BrakeValveNode, args, node_name=topics.VALVE_NODE_NAME,
                    specs=SPECS, summary="The driver's brake valve: publishes the head-end "
                    'brake_pipe/pressure from a schedule of handle positions, changeable live.',
                    exits=(ExitOn((ValueError, ParameterException), 'invalid parameters', 2),),
                    executor_factory=SingleThreadedExecutor)


if __name__ == '__main__':
    sys.exit(main())
