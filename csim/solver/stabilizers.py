"""Constraint stabilizers: the right-hand side gamma* of the acceleration-level constraint.

Every formulation solves ``Phi_q qdd = gamma*``; a stabilizer is the single place where
gamma* is chosen. ``none`` keeps gamma* = gamma = -(Phi_q qd)_q qd, so Phi and dPhi/dt
are free to drift.
"""
from __future__ import annotations

import numpy as np


class Stabilizer:
    """Maps (gamma, Phi, dPhi/dt) to gamma*.

    Subclasses implement :meth:`gamma_star`; ``name`` is the registry key
    (``stabilization.method`` in a case file).
    """

    name = "abstract"

    def gamma_star(self, gamma: np.ndarray, phi: np.ndarray, phi_dot: np.ndarray) -> np.ndarray:
        """gamma* (r,) from gamma (r,), Phi (r,) and dPhi/dt = Phi_q qd (r,)."""
        raise NotImplementedError


class NoStabilization(Stabilizer):
    """gamma* = gamma: the acceleration-level constraint alone."""

    name = "none"

    def gamma_star(self, gamma, phi, phi_dot):
        return gamma


#: name -> class; each class is built from the validated ``stabilization`` section
STABILIZERS: dict[str, type[Stabilizer]] = {
    NoStabilization.name: NoStabilization,
}


def make_stabilizer(name: str, settings: dict | None = None) -> Stabilizer:
    """Build the stabilizer registered as ``name`` from its case-file ``settings``."""
    try:
        cls = STABILIZERS[name]
    except KeyError:
        raise KeyError(f"unknown stabilization method {name!r}; valid names: {', '.join(STABILIZERS)}") from None
    return cls(**(settings or {}))
