"""``ggl``: the stabilized index-2 formulation of Gear, Gupta and Leimkuhler.

    q' = v - Phi_q^T mu,   M v' = p - Phi_q^T lambda,   0 = Phi(q),   0 = Phi_q v

Both the position and the velocity constraints are equations of the DAE, solved at every
stage of the implicit Radau IIA integrator (:class:`csim.solver.ggl_system.GGLSystem`): no drift
and no post-step correction. mu vanishes on the exact solution.
"""
from __future__ import annotations

import dataclasses

from csim.solver.methods.base import Method, option
from csim.solver.methods.projection import ProjectionOptions


@dataclasses.dataclass(frozen=True)
class GGLOptions:
    ggl_tol: float = option(1e-12, "largest residual of Phi and Phi_q qd accepted at a step's end", "unit of Phi",
                            gt=0.0)


class GGL(Method):
    """The stabilized index-2 formulation of Gear, Gupta and Leimkuhler.

    Parameters
    ----------
    ggl_tol : float
        Largest residual of Phi and Phi_q v accepted at the end of a step [unit of Phi,
        and per second].
    """

    name = "ggl"
    rank = 40
    Options = GGLOptions
    integrators = ("Radau",)  # the DAE integrators of csim.solver.integrators
    compiled = True  # the compiled Radau runs the DAE (csim.fast.kernels.radau)

    def __init__(self, ggl_tol=1e-12):
        super().__init__(ggl_tol=ggl_tol)
        self.tol = float(ggl_tol)

    def parameters(self):
        """([projection tolerance, ggl_tol], [mass metric (1), projection iteration limit]): the compiled kernels'
        projection of the consistent states and the samples reads fpar[0] and ipar (with the settings of
        GGLSystem's own projection, the defaults of ``projection``), their Radau fpar[1]."""
        projection = ProjectionOptions()
        return [projection.projection_tol, self.tol], [1, projection.projection_max_iter]

    @classmethod
    def system_class(cls):
        from csim.solver.ggl_system import GGLSystem

        return GGLSystem
