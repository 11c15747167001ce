"""``projection``: coordinate projection onto Phi = 0, Phi_q qd = 0 after every accepted step.

gamma* = gamma during the step. After it, positions go by Gauss-Newton with the metric W
(the identity, or M),

    q <- q - W^-1 Phi_q^T (Phi_q W^-1 Phi_q^T)^-1 Phi(q),

until max |Phi| <= ``projection_tol`` (or the correction is down to the round-off of q),
then velocities onto Phi_q qd = 0 with one such correction. The mass metric changes the
state least in kinetic-energy norm. The core functions are in :mod:`csim.physics.projection`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from csim.errors import SimulationFailure
from csim.physics import projection as core
from csim.physics.kkt import constraint_rates
from csim.physics.linalg import as_core
from csim.physics.status import PROJ_NO_CONVERGENCE, PROJ_SINGULAR, failure_message
from csim.solver.methods.base import Method, option

METRICS = ("minimum_norm", "mass")


@dataclasses.dataclass(frozen=True)
class ProjectionOptions:
    projection_metric: str = option("mass", "metric of the Gauss-Newton projection", choices=("mass", "minimum_norm"))
    projection_tol: float = option(1e-13, "target max |Phi|", "unit of Phi", gt=0.0)
    projection_max_iter: int = option(10, "Gauss-Newton iteration limit", ge=1)


class Projection(Method):
    """Coordinate projection after every accepted step (gamma* = gamma during the step).

    Parameters
    ----------
    projection_metric : {"minimum_norm", "mass"}
    projection_tol : float
        Convergence of the position iteration on max |Phi| [unit of Phi].
    projection_max_iter : int
    """

    name = "projection"
    rank = 30
    Options = ProjectionOptions
    METRICS = METRICS
    compiled = True
    projects = True

    def __init__(self, projection_metric="mass", projection_tol=1e-13, projection_max_iter=10):
        if projection_metric not in METRICS:
            raise ValueError(f"projection_metric must be one of {', '.join(METRICS)}")
        super().__init__(projection_metric=projection_metric, projection_tol=projection_tol,
                         projection_max_iter=projection_max_iter)
        self.metric = projection_metric
        self.tol = float(projection_tol)
        self.max_iter = int(projection_max_iter)

    def parameters(self):
        return [self.tol], [int(self.metric == "mass"), self.max_iter]

    def project(self, model, par, q, qd):
        """Projected (q, qd); raises SimulationFailure when Gauss-Newton does not converge."""
        m, r = q.size, model.n_constraints
        mass_metric = self.metric == "mass"
        # the core functions' scratch; matrices flat and row-major
        Winv, WJt, S, z, dq = np.zeros(m * m), np.empty(m * r), np.empty(r * r), np.empty(r), np.empty(m)
        piv = np.zeros(max(m, r), np.int64)
        if mass_metric and not core.invert(as_core(model.mass(q, par)), np.empty(m * m), piv, np.empty(m), Winv, m):
            raise np.linalg.LinAlgError("Singular matrix")  # the driver says when
        q = np.array(q, dtype=float)
        for _ in range(self.max_iter + 1):
            phi = model.phi(q, par)
            if core.max_abs(phi) <= self.tol:
                break
            if not core.correction(as_core(model.phi_q(q, par)), Winv, mass_metric, phi, WJt, S, z, piv, dq, r, m):
                raise SimulationFailure(_failure(PROJ_SINGULAR, self))
            q -= dq
            if core.at_round_off(dq, q):  # |Phi| cannot go lower: its round-off grows with |q|
                break
        else:
            raise SimulationFailure(_failure(PROJ_NO_CONVERGENCE, self, core.max_abs(phi)))
        phi_q = as_core(model.phi_q(q, par))
        phi_dot = np.empty(r)
        constraint_rates(phi_q, qd, phi_dot, r, m)
        if not core.correction(phi_q, Winv, mass_metric, phi_dot, WJt, S, z, piv, dq, r, m):
            raise SimulationFailure(_failure(PROJ_SINGULAR, self))
        return q, qd - dq


def _failure(code: int, method: Projection, a: float = 0.0) -> str:
    return failure_message(code, a, 0.0, None, method)
