"""Checks after every accepted step: stop a run that has diverged, saying why.

Shared by the Python driver and the compiled loop; codes from :mod:`csim.physics.status`.
"""
from __future__ import annotations

import math

from csim.physics.jit import kernel
from csim.physics.status import MAX_PHI, NONFINITE_STATE, OK, STEP_COLLAPSE


@kernel
def all_finite(x):
    """Whether every entry of x is finite (a loop: numba does not compile all() over a generator)."""
    for i in range(x.size):  # noqa: SIM110
        if not math.isfinite(x[i]):
            return False
    return True


@kernel
def check_step(y, max_phi_now, h, t, t_bound, adaptive, max_phi, min_step, info):
    """Status of an accepted step ending at (t, y): OK, or why the run has diverged.

    Checks, in order: a non-finite state; max |Phi| (``max_phi_now``) above ``max_phi``
    (the joints torn apart); an adaptive step ``h`` shorter than ``min_step`` that was
    not cut short by the end of the interval ``t_bound`` (step-size collapse). The details
    go to info (2,) as :mod:`csim.physics.status` lists them.
    """
    if not all_finite(y):
        info[0] = t
        return NONFINITE_STATE
    if not max_phi_now <= max_phi:
        info[0] = max_phi_now
        info[1] = t
        return MAX_PHI
    if adaptive and t != t_bound and h < min_step:
        info[0] = h
        info[1] = t
        return STEP_COLLAPSE
    return OK
