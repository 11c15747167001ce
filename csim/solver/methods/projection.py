"""``projection``: coordinate projection onto Phi = 0, Phi_q qd = 0 after every accepted step.

gamma* = gamma during the step. After it, positions go by Gauss-Newton with the metric W
(the identity, or M),

    q <- q - W^-1 Phi_q^T (Phi_q W^-1 Phi_q^T)^-1 Phi(q),

until max |Phi| <= ``projection_tol`` (or the correction is down to the round-off of q),
then velocities onto Phi_q qd + Phi_t = 0 with one such correction (Phi_t: zero but for the
rows of drives, :mod:`csim.solver.driven`). The mass metric changes the
state least in kinetic-energy norm. The core functions are in :mod:`csim.physics.projection`.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from csim.physics import projection as core
from csim.physics.status import OK
from csim.solver.failures import failure
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
        #: the method whose own projection this is, with its metric fixed ("": the user's ``projection``)
        self.metric_fixed_by = ""

    def parameters(self):
        return [self.tol], [int(self.metric == "mass"), self.max_iter]

    def project(self, model, par, q, qd, t=0.0, phi_t=None):
        """Projected (q, qd) (:func:`csim.physics.projection.project`): onto Phi = 0 and
        Phi_q qd + Phi_t = 0, Phi_t (r,) the constraints' rates at fixed q (``phi_t``: zero when
        None; a drive row's is -f'(t)). Raises SimulationFailure, saying at time ``t`` [s], when
        Gauss-Newton does not converge, the Jacobian has lost rank or the mass metric is singular."""
        from csim.solver.newton import PythonModel

        m, r = q.size, model.n_constraints
        q, qd = np.array(q, dtype=float), np.array(qd, dtype=float)
        code, max_phi = core.project(PythonModel(model, par, phi_t), q, qd, self.tol, self.metric == "mass",
                                     self.max_iter, m, r, np.empty(m * m), np.empty(m * m), np.zeros(m * m),
                                     np.zeros(max(m, r), np.int64), np.empty(m), np.empty(r), np.empty(r * m),
                                     np.empty(m * r), np.empty(r * r), np.empty(r), np.empty(m), np.empty(r))
        if code != OK:
            raise failure(code, max_phi, t, None, self)
        return q, qd
