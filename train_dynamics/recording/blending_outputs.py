"""
The brake control unit's outputs (``blending: builtin``), for the node and the offline bag.

Two ``sensor_msgs/JointState`` topics (:mod:`train_dynamics.topics`), ``frame_id`` ``track``:

- ``brake_blending``, ``coach_1..N``: position = achieved ED force [N, >= 0 braking; 0 for
  trailers], velocity = friction brake force [N, >= 0], effort = magnetic track brake force
  [N, >= 0];
- ``brake_demand/state``, ``demand``, ``achieved``: position = deceleration [m/s^2]
  (``demand``: after the jerk limit; ``achieved``: the brake forces ED + friction + track
  over the inertial mass sum m (1 + rotating_mass_factor), resistance and gradients not
  counted), velocity = brake force [N] (demanded; achieved), effort = ED force of the train
  [N] (commanded; achieved).

CDR-encoded here once per output (:func:`train_dynamics.recording.cdr.encode_joint_state`);
the node publishes and records the same bytes the offline command writes.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from train_dynamics import topics
from train_dynamics.physics.blending import ed_forces
from train_dynamics.recording.cdr import encode_joint_state

#: the topics written for a run with blending builtin, in order
BLENDING_OUTPUT_TOPICS = (topics.BRAKE_BLENDING_TOPIC, topics.BRAKE_DEMAND_STATE_TOPIC)


def blending_outputs(t_ns: int, sim: Any) -> list[tuple[str, bytes]]:
    """
    Return (topic, CDR bytes) of the brake control unit's outputs at ``t_ns``.

    ``blending: builtin``: both topics; ``external``: ``brake_blending`` (the controller
    under test is the unit: no demand known here, no track brakes); ``none``: [].
    """
    bcu = getattr(sim, 'bcu', None)
    external = bcu is None and sim.cfg.blending == 'external'
    if bcu is None and not external:
        return []
    ed = ed_forces(sim) if external else bcu.ed_force()
    friction = sim.brake_force
    track = np.zeros(sim.n) if external else bcu.track.force
    names = [f'coach_{i}' for i in range(1, sim.n + 1)]
    per_car = encode_joint_state(t_ns, names, ed, friction, track, topics.TRACK_FRAME)
    if external:
        return [(topics.BRAKE_BLENDING_TOPIC, per_car)]
    achieved = float(ed.sum() + friction.sum() + track.sum())
    mass = float(sim.inertia.sum())
    state = encode_joint_state(
        t_ns, ['demand', 'achieved'],
        np.array([bcu.demanded_deceleration, achieved / mass]),
        np.array([bcu.force_demand, achieved]),
        np.array([float(np.sum(bcu.ed_command)), float(ed.sum())]), topics.TRACK_FRAME)
    return [(topics.BRAKE_BLENDING_TOPIC, per_car), (topics.BRAKE_DEMAND_STATE_TOPIC, state)]
