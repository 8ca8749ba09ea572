"""
Brake-input and traction-command messages: the rejection rules of the node and the offline replay.

One rule per input kind, so that the node and the offline command refuse the same values for
the same reason (counted per reason).
"""
from __future__ import annotations

import math

from train_dynamics import topics

#: why a brake-input pressure is not used (``sim_node`` counts them per reason)
INPUT_VALUE_REASONS = ('non_finite', 'negative', 'too_high')


def input_rejection(absolute: float) -> tuple[str, str] | None:
    """
    Return (reason, detail) if a brake-input ABSOLUTE pressure [Pa] is rejected, else None.

    The one rule for ``sim_node`` and the offline replay: ``non_finite`` (NaN, +-inf),
    ``negative`` (< 0), ``too_high`` (> :data:`train_dynamics.topics.MAX_ABSOLUTE_PRESSURE`).
    """
    p = float(absolute)
    if not math.isfinite(p):
        return 'non_finite', f'pressure {p}'
    if p < 0.0:
        return 'negative', f'absolute pressure {p:g} Pa < 0'
    if p > topics.MAX_ABSOLUTE_PRESSURE:
        return 'too_high', (f'absolute pressure {p:g} Pa > '
                            f'{topics.MAX_ABSOLUTE_PRESSURE:g} Pa')
    return None


#: why an EP / ECP command is not used (counted per reason like the other inputs)
EP_VALUE_REASONS = ('non_finite', 'out_of_range')


def ep_rejection(command: float) -> tuple[str, str] | None:
    """
    Return (reason, detail) if an EP / ECP command is rejected, else None.

    ``brake_ep/command`` is a fraction of full service: ``non_finite``, ``out_of_range``
    (outside [0, 1]).
    """
    c = float(command)
    if not math.isfinite(c):
        return 'non_finite', f'command {c}'
    if not 0.0 <= c <= 1.0:
        return 'out_of_range', f'EP command {c:g} outside [0, 1]'
    return None


#: why a traction command is not used (``sim_node`` counts them per reason)
TRACTION_VALUE_REASONS = ('non_finite', 'out_of_range')


def traction_rejection(command: float) -> tuple[str, str] | None:
    """
    Return (reason, detail) if a traction command is rejected, else None.

    The one rule for ``sim_node`` and the offline replay of ``coach_<i>/traction/command``
    (a fraction of the available force, > 0 traction, < 0 dynamic brake): ``non_finite``
    (NaN, +-inf), ``out_of_range`` (outside [-1, 1]).
    """
    c = float(command)
    if not math.isfinite(c):
        return 'non_finite', f'command {c}'
    if not -1.0 <= c <= 1.0:
        return 'out_of_range', f'command {c:g} outside [-1, 1]'
    return None


#: why a slide-protection valve command is not used (counted per reason like the others)
WSP_VALUE_REASONS = ('out_of_range',)


def wsp_rejection(state: int) -> tuple[str, str] | None:
    """
    Return (reason, detail) if a ``coach_<i>/wsp/valve`` state is rejected, else None.

    ``std_msgs/Int8``: 0 normal, 1 hold, 2 vent; anything else is ``out_of_range``.
    """
    if int(state) not in (0, 1, 2):
        return 'out_of_range', f'valve state {int(state)} not 0 (normal), 1 (hold) or 2 (vent)'
    return None
