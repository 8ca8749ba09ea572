"""
The integration method of a configuration: ``integrator`` and the two tolerances, resolved once.

One parameter names the method (``integrator``: ``fixed``, ``multirate`` or ``adaptive``); the
tolerances keep their meaning (``multirate_tolerance`` for ``multirate``,
``integration_tolerance`` for ``adaptive``). Older files name the method by a tolerance alone,
and still work, read with the default ``integrator`` (``multirate``):

=================  =======================  =====================  ===========================
integrator         integration_tolerance    multirate_tolerance    method (tolerance used)
=================  =======================  =====================  ===========================
fixed              0                        (not used)             fixed step
fixed              > 0                      any                    refused: a contradiction
multirate          0                        > 0                    multirate (its tolerance)
multirate          0                        0                      fixed step (older files)
multirate          > 0                      any                    adaptive (older files)
adaptive           0                        (not used)             adaptive at 1e-3
adaptive           > 0                      (not used)             adaptive (that tolerance)
=================  =======================  =====================  ===========================

The methods: docs/integrators.md. Never imports rclpy.
"""
from __future__ import annotations

from typing import NamedTuple

from train_dynamics.physics.config.spec import ConfigError

#: the values of ``integrator``
INTEGRATORS = ('fixed', 'multirate', 'adaptive')
#: the default method: multirate (docs/integrators.md, "Multirate fixed step (the default)")
DEFAULT_INTEGRATOR = 'multirate'
#: error tolerance of ``integrator: adaptive`` when ``integration_tolerance`` is 0 (unset) [-]:
#: the tolerance of the shipped config/paper_3coach_adaptive.yaml, every sample of the paper's
#: scenario within 0.5 % of the reference (docs/integrators.md, "What the tolerance means")
ADAPTIVE_TOLERANCE = 1.0e-3


class Integration(NamedTuple):
    """The resolved method and the tolerances the kernel uses (0 = off)."""

    method: str                 # 'fixed', 'multirate' or 'adaptive'
    tolerance: float            # error control's local coupler-force error / force level [-]
    multirate_tolerance: float  # multirate's local coupler-force error / force level [-]


def resolve(integrator: str, integration_tolerance: float,
            multirate_tolerance: float) -> Integration:
    """
    Return the method of ``integrator`` and the tolerances (the module's table).

    Under error control the multirate tolerance is passed on unchanged (error control does not
    read it: every step is controlled already). Raises :class:`ConfigError` (one line) on a
    contradiction.
    """
    tol, mr = float(integration_tolerance), float(multirate_tolerance)
    if integrator == 'fixed':
        if tol > 0.0:
            raise ConfigError(f'integrator fixed contradicts integration_tolerance {tol:g} (the '
                              'error control of integrator adaptive): set integrator adaptive, '
                              'or integration_tolerance 0')
        return Integration('fixed', 0.0, 0.0)
    if integrator == 'adaptive':
        return Integration('adaptive', tol if tol > 0.0 else ADAPTIVE_TOLERANCE, mr)
    if integrator != 'multirate':
        raise ConfigError(f'integrator: one of {", ".join(INTEGRATORS)}, got {integrator!r}')
    if tol > 0.0:
        return Integration('adaptive', tol, mr)
    if mr > 0.0:
        return Integration('multirate', 0.0, mr)
    return Integration('fixed', 0.0, 0.0)
