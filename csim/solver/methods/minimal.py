"""``minimal``: minimal coordinates by coordinate partitioning (Wehage and Haug).

The independent coordinates u and their rates are integrated; at every evaluation the
dependent coordinates v are solved from Phi(u, v) = 0 by Newton-Raphson and their rates
from Phi_v vd = -Phi_u ud, so the constraints hold to the Newton tolerance by
construction (:class:`csim.solver.partitioned.PartitionedSystem`). The Newton solve, the
branch check and the choice of the partition are core functions (:mod:`csim.physics.branch`)
that the compiled kernels run too.
"""
from __future__ import annotations

import dataclasses

from csim.solver.methods.base import Method, option


@dataclasses.dataclass(frozen=True)
class MinimalOptions:
    minimal_tol: float = option(1e-13, "Newton tolerance on max |Phi| for the dependent coordinates", "unit of Phi",
                                gt=0.0)
    minimal_max_iter: int = option(20, "Newton iteration limit per evaluation", ge=1)
    minimal_max_condition: float = option(20.0, "choose the partition again when cond(Phi_v) exceeds this", gt=1.0)


class Minimal(Method):
    """Minimal coordinates by coordinate partitioning (Wehage and Haug).

    The partition is chosen by trying every dependent block and chosen again (the
    integration restarts) when ||Phi_q||_1 ||Phi_v^-1||_1 exceeds ``minimal_max_condition``.

    Parameters
    ----------
    minimal_tol : float
        Newton tolerance on max |Phi| [unit of Phi].
    minimal_max_iter : int
        Newton iteration limit per evaluation.
    minimal_max_condition : float
        Look for a better partition when ||Phi_q||_1 ||Phi_v^-1||_1 exceeds this (the
        factor by which errors in u are amplified in v, about). The default 20 is above
        the quick-return mechanism's worst value with the crank independent (11.9), so the
        crank stays independent there, and switches a Cartesian pendulum's independent
        coordinate when |y| falls below about L / 20.
    """

    name = "minimal"
    rank = 50
    Options = MinimalOptions
    compiled = True

    def __init__(self, minimal_tol=1e-13, minimal_max_iter=20, minimal_max_condition=20.0):
        super().__init__(minimal_tol=minimal_tol, minimal_max_iter=minimal_max_iter,
                         minimal_max_condition=minimal_max_condition)
        self.tol = float(minimal_tol)
        self.max_iter = int(minimal_max_iter)
        self.max_condition = float(minimal_max_condition)

    def parameters(self):
        """fpar = [tol, max_condition], ipar = [max_iter] (the kernels' csim.fast.kernels.system._partition_call)."""
        return [self.tol, self.max_condition], [self.max_iter]

    @classmethod
    def system_class(cls):
        from csim.solver.partitioned import PartitionedSystem

        return PartitionedSystem
