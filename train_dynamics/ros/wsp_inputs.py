"""
The slide-protection inputs of ``sim_node``: ``coach_<i>/wsp/valve`` (``wsp: external``).

With ``bogie_wheelsets`` one valve state per bogie instead: ``coach_<i>/bogie_<j>/wsp/valve``
(j = 1 front, 2 rear; :mod:`train_dynamics.physics.kernel.bogie`), the same handling per
bogie (staleness, lock-step: one state per bogie answering the output).

``std_msgs/Int8``: 0 normal, 1 hold, 2 vent, the hold and vent valves on vehicle i's brake
cylinder (:mod:`train_dynamics.physics.kernel.wheelset`), subscribed best-effort keep-last 10
for every vehicle while ``wsp`` is ``external``. A state takes effect at the next integration
step (zero-order hold) and is recorded as received. Rejected and counted with the brake
inputs' reasons: ``out_of_range`` (not 0, 1 or 2), ``malformed``.

Staleness (``input_timeout`` > 0): a vehicle whose valve state has not been refreshed for
``input_timeout`` wall seconds after a first one falls back to 0 (normal: the brake as the
driver commands it; a valve left venting by a dead controller would leave the vehicle
without brake), whatever ``on_input_timeout`` says; the next state restores it. The same
handling as the traction commands (:class:`~train_dynamics.ros.traction_inputs.TractionInputs`,
whose hooks this class sets), lock-step included (``wsp`` in ``lockstep_inputs``: a state
answers the latest output published before it arrived; each period waits for one state
per vehicle answering its output).
"""
from __future__ import annotations

from typing import Any

from rclpy.serialization import deserialize_message
from std_msgs.msg import Int8

from train_dynamics import topics
from train_dynamics.physics.config import wsp_rejection
from train_dynamics.physics.train import TrainSimulator
from train_dynamics.ros.traction_inputs import TractionInputs


def wsp_valve(data: bytes) -> int:
    """Return the state of a raw Int8 valve command; raise ValueError(reason, detail)."""
    try:
        value = int(deserialize_message(data, Int8).data)
    except Exception as exc:  # noqa: BLE001 - anything rclpy raises on a bad buffer
        raise ValueError('malformed', f'cannot deserialise: {exc}') from None
    why = wsp_rejection(value)
    if why is not None:
        raise ValueError(*why)
    return value


class WspInputs(TractionInputs):
    """Subscribe to, check and hold every vehicle's slide-protection valve state."""

    MSG = Int8
    MSG_TYPE = topics.INT8
    LABEL = 'wsp valve'
    FAILSAFE = 0
    ALWAYS_FAILSAFE = True
    decode = staticmethod(wsp_valve)
    #: ``bogie_wheelsets``: one valve state per bogie, index 2 i + j - 1 for bogie j of
    #: vehicle i (0-based), topic ``coach_<i>/bogie_<j>/wsp/valve``
    bogies = False

    def start(self, vehicles: list[int], bogies: bool = False) -> None:
        """Subscribe to the valves of ``vehicles`` (0-based), of each bogie with ``bogies``."""
        self.bogies = bool(bogies)
        super().start([2 * i + j for i in vehicles for j in (0, 1)] if bogies else vehicles)

    def topic(self, k: int) -> str:
        """Return the topic of valve channel ``k`` (1-based: a vehicle, or a bogie)."""
        if not self.bogies:
            return topics.wsp_valve_topic(k)
        return topics.bogie_wsp_valve_topic((k + 1) // 2, 2 - k % 2)

    def put(self, sim: TrainSimulator, value: Any, index: int) -> None:
        """Hand valve state ``value`` of channel ``index`` (0-based) to the simulator."""
        if self.bogies:
            sim.set_wsp_valve(int(value), index // 2, index % 2 + 1)
        else:
            sim.set_wsp_valve(int(value), index)
