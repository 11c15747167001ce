"""Formulations that turn the DAE into an ODE: accelerations and multipliers from a state.

Both solve, at one state, the equations of motion with the acceleration-level constraint

    M qdd + Phi_q^T lambda = p,      Phi_q qdd = gamma*

and differ in how: ``kkt`` solves the (m + r) augmented system; ``elimination`` (the
paper's eqs. 8-10) premultiplies by the null-space matrix R and solves an m x m system.
"""
from __future__ import annotations

import numpy as np

from csim.physics.elimination import E_CHOSEN, E_REPARTITIONS, eliminate, new_elimination
from csim.physics.kkt import kkt_solve
from csim.physics.linalg import as_core
from csim.physics.status import OK, SINGULAR_KKT
from csim.solver.failures import failure


class Formulation:
    """Solves for (qdd, lambda); ``name`` is the registry key (``formulation.method``)."""

    name = "abstract"

    def solve(self, M, phi_q, p, gamma_star):
        """Accelerations and multipliers.

        Parameters
        ----------
        M : ndarray (m, m)
            Mass matrix.
        phi_q : ndarray (r, m)
            Constraint Jacobian.
        p : ndarray (m,)
            Q - C qd - h.
        gamma_star : ndarray (r,)
            Right-hand side of the acceleration-level constraint (from the stabilizer).

        Returns
        -------
        qdd : ndarray (m,)
        lam : ndarray (r,)

        Raises
        ------
        SimulationFailure
            If the system is singular.
        """
        raise NotImplementedError


class KKT(Formulation):
    """Lagrange multipliers: [[M, Phi_q^T], [Phi_q, 0]] [qdd; lambda] = [p; gamma*]."""

    name = "kkt"

    def solve(self, M, phi_q, p, gamma_star):
        m, r = M.shape[0], phi_q.shape[0]
        x = np.empty(m + r)
        if not kkt_solve(as_core(M), as_core(phi_q), as_core(p), as_core(gamma_star), np.empty((m + r) ** 2), x,
                         np.empty(m + r, np.int64), m, r):
            raise failure(SINGULAR_KKT, 0.0, 0.0, None)
        return x[:m], x[m:]


class Elimination(Formulation):
    """Elimination of the multipliers with R = [E; -Phi_v^-1 Phi_u] (paper's eqs. 8-10).

        [R^T M ] qdd = [R^T p ]
        [Phi_q ]       [gamma*]

    The multipliers are recovered from the dependent rows, Phi_v^T lambda = (p - M qdd)_v.
    The solve is :func:`csim.physics.elimination.eliminate`, the compiled kernels' too; this
    object holds its partition between solves.

    Parameters
    ----------
    independent : sequence of int or None
        Indices of the independent coordinates u. ``None`` chooses them from Phi_q at the
        first evaluation (the best-conditioned block, every one tried where that is cheap, else
        pivoted QR: :func:`csim.physics.partition.choose_partition`) and chooses them again
        whenever the condition of Phi_v exceeds ``max_condition``. The Python path evaluates its
        samples with the partition the integration ended on, the compiled kernels choose it
        afresh at the first sample: their multipliers differ by round-off.
    max_condition : float
        Largest acceptable condition of Phi_v, ||Phi_q||_1 ||Phi_v^-1||_1.
    """

    name = "elimination"

    def __init__(self, independent=None, max_condition: float = 1e8):
        self.fixed = independent is not None
        #: formulation.independent, ascending (the order of u does not change qdd)
        self.given = np.sort(np.asarray([] if independent is None else independent, dtype=np.int64))
        self.max_condition = float(max_condition)
        self._state = None  # the EliminationState, laid out at the first solve (its sizes are the Jacobian's)

    @property
    def independent(self) -> np.ndarray | None:
        """The independent coordinates of the last solve (``formulation.independent``, or None, before it)."""
        if self._state is None or not self._state.count[E_CHOSEN]:
            return self.given if self.fixed else None
        return self._state.ind.copy()

    @property
    def repartitions(self) -> int:
        """How many times the partition was chosen again."""
        return 0 if self._state is None else int(self._state.count[E_REPARTITIONS])

    def solve(self, M, phi_q, p, gamma_star):
        m, r = M.shape[0], phi_q.shape[0]
        if self._state is None:
            self._state = new_elimination(m, r)
        x = np.empty(m + r)
        code = eliminate(as_core(M), as_core(phi_q), as_core(p), as_core(gamma_star), self._state, self.fixed,
                         self.given, self.max_condition, np.empty(m * m), x, np.empty(m, np.int64), m, r)
        if code != OK:
            raise failure(code, 0.0, 0.0, None)
        return x[:m], x[m:]


#: name -> class
FORMULATIONS: dict[str, type[Formulation]] = {KKT.name: KKT, Elimination.name: Elimination}


def make_formulation(name: str, **settings) -> Formulation:
    """Build the formulation registered as ``name``."""
    try:
        cls = FORMULATIONS[name]
    except KeyError:
        raise KeyError(f"unknown formulation {name!r}; valid names: {', '.join(FORMULATIONS)}") from None
    return cls(**settings)
