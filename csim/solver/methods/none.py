"""``none``: the acceleration-level constraint alone, gamma* = gamma.

Phi'' = 0 along exact solutions, so integration errors in Phi and Phi' are never pulled
back: Phi drifts, linearly or worse.
"""
from __future__ import annotations

from csim.solver.methods.base import Method


class NoStabilization(Method):
    """gamma* = gamma: the acceleration-level constraint alone."""

    name = "none"
    rank = 0
    compiled = True
