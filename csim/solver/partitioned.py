"""Minimal coordinates by coordinate partitioning (Wehage and Haug).

The m coordinates are split into n = m - r independent ones u and r dependent ones v.
Only u, its rate and the work states are integrated, y = [u (n), ud (n), W (k)]. At every
evaluation the dependent coordinates follow from the constraints,

    Phi(u, v) = 0                   (Newton-Raphson on v, started from the last solution)
    Phi_v vd = -Phi_u ud            (their rates)

and the accelerations of all coordinates from the equations of motion with the
acceleration-level constraint (the case's formulation, gamma* = gamma); u'' is the
independent part. The constraints therefore hold to the Newton tolerance at every instant,
with no drift to stabilize. When the dependent block Phi_v turns ill-conditioned (the
mechanism nears a configuration where v is no longer a function of u) the partition is
chosen again by pivoted QR and the integration restarts from the same state.
"""
from __future__ import annotations

import numpy as np

from csim.errors import PartitionBreakdown, SimulationFailure
from csim.solver.formulations import choose_independent, dependent_block_inverse
from csim.solver.newton import DependentSolveError, dependent_velocities, solve_dependent
from csim.solver.system import ConstrainedSystem


class PartitionedSystem(ConstrainedSystem):
    """The equations of motion in the independent coordinates only.

    Parameters are those of :class:`ConstrainedSystem`; the stabilizer is a
    :class:`csim.solver.stabilizers.Minimal` and carries the Newton settings and the
    re-partition threshold.

    Attributes
    ----------
    independent, dependent : ndarray of int (n,), (r,)
        The current partition.
    repartitions : int
        How many times the partition was chosen again during the run.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.n = self.m - self.r
        self.independent = self.dependent = None
        self.repartitions = 0
        self._q = None  # the last full coordinates: the Newton start of the next solve

    @property
    def n_state(self) -> int:
        return 2 * self.n + self.k

    @property
    def work_slice(self) -> slice:
        return slice(2 * self.n, 2 * self.n + self.k)

    def _partition(self, q: np.ndarray) -> None:
        """Choose u and v at coordinates q (:func:`choose_independent`)."""
        u = choose_independent(self.model.phi_q(q, self.par))
        self.independent, self.dependent = u, np.setdiff1d(np.arange(self.m), u)
        self._q = np.array(q, dtype=float)

    def _reduce(self, y_full: np.ndarray) -> np.ndarray:
        q, qd, W = self.split(y_full)
        u = self.independent
        return np.concatenate((q[u], qd[u], W))

    def start(self, y_full: np.ndarray) -> np.ndarray:
        """Partition at q0 and keep u0, ud0 (v0 and vd0 are solved: a perturbed start is projected)."""
        self._partition(self.split(y_full)[0])
        return self._reduce(y_full)

    def condition(self, q: np.ndarray) -> float:
        """How badly Phi_v determines v at q, ||Phi_q||_1 ||Phi_v^-1||_1 (inf if singular)."""
        return dependent_block_inverse(self.model.phi_q(q, self.par), self.dependent)[1]

    def to_full(self, y: np.ndarray) -> np.ndarray:
        """[q, qd, W] with v solved from Phi(u, v) = 0 and vd from Phi_q qd = 0."""
        n, u, v = self.n, self.independent, self.dependent
        q = self._q.copy()
        q[u] = y[:n]
        try:
            solution = solve_dependent(self.model, self.par, q, v, self.stabilizer.tol, self.stabilizer.max_iter)
        except DependentSolveError as exc:
            if exc.reason == "non_finite":
                raise SimulationFailure(f"blow-up: non-finite constraint residual at independent coordinates "
                                        f"{y[:n]}") from None
            if exc.reason == "singular":
                raise PartitionBreakdown(f"minimal: the dependent block Phi_v is singular at q = {exc.q}") from None
            raise PartitionBreakdown(
                f"minimal: Newton-Raphson for the dependent coordinates did not reach max |Phi| <= "
                f"{self.stabilizer.tol:g} in {self.stabilizer.max_iter} iterations (max |Phi| = "
                f"{np.max(np.abs(exc.phi)):.3e}); the mechanism cannot be assembled at the independent "
                f"coordinates {y[:n]}") from None
        self._q = q = solution.q
        qd = np.zeros(self.m)
        qd[u] = y[n:2 * n]
        try:
            qd = dependent_velocities(solution.phi_q, qd, v)  # Phi_v vd = -Phi_u ud
        except np.linalg.LinAlgError:
            raise PartitionBreakdown(f"minimal: the dependent block Phi_v is singular at q = {q}") from None
        return np.concatenate((q, qd, y[2 * n:]))

    def rhs(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """dy/dt = [ud, udd, dW/dt] (2 n + k,)."""
        q, qd, _ = self.split(self.to_full(y))
        loads = self.loads.values(mode)
        qdd, _, _, _, _, B = self._solve(q, qd, loads)
        return np.concatenate((qd[self.independent], qdd[self.independent], loads * (B.T @ qd)))

    def _choose_again(self) -> bool:
        """Choose the best partition at the last solved coordinates; True if it changed."""
        old = self.independent
        self._partition(self._q)
        if np.array_equal(old, self.independent):
            return False
        self.repartitions += 1
        return True

    def repartition(self, y: np.ndarray, cause: Exception) -> np.ndarray:
        """Choose the partition again at the accepted state y after a breakdown at a later stage.

        Returns y in the new partition; raises SimulationFailure when the best partition at y
        is the current one (then no partition can carry the integration on).
        """
        full = self.to_full(y)
        if not self._choose_again():
            raise SimulationFailure(f"{cause} (no better coordinate partition exists at the last accepted state)")
        return self._reduce(full)

    def after_step(self, t: float, y: np.ndarray) -> tuple[np.ndarray, str]:
        """Choose the partition again when Phi_v has turned ill-conditioned (restart).

        The integration restarts only when a better-conditioned partition exists; while the
        current one is the best there is, it goes on.
        """
        full = self.to_full(y)
        if self.condition(self._q) <= self.stabilizer.max_condition or not self._choose_again():
            return y, "keep"
        return self._reduce(full), "restart"
