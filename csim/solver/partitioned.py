"""Minimal coordinates by coordinate partitioning (Wehage and Haug).

The m coordinates are split into n = m - r independent ones u and r dependent ones v.
Only u, its rate and the work states are integrated, y = [u (n), ud (n), W (k)]. At every
evaluation the dependent coordinates follow from the constraints,

    Phi(u, v) = 0                   (Newton-Raphson on v, on the assembly branch)
    Phi_v vd = -Phi_u ud            (their rates)

and the accelerations of all coordinates from the equations of motion with the
acceleration-level constraint (the case's formulation, gamma* = gamma); u'' is the
independent part. The constraints therefore hold to the Newton tolerance at every instant,
with no drift to stabilize. When the dependent block Phi_v turns ill-conditioned (the
mechanism nears a configuration where v is no longer a function of u) the partition is
chosen again by pivoted QR and the integration restarts from the same state.

*The assembly branch.* A closed loop can be assembled in several ways for the same u, and
Newton converges to whichever its start leads it to. Every solve therefore starts from the
branch's prediction at the last accepted state (u_a, v_a), its Taylor polynomial in u

    v_pred = v_a + (dv/du)_a (u - u_a) + 1/2 Phi_v^-1 gamma(q_a, q'),   (dv/du)_a = -Phi_v^-1 Phi_u

(:meth:`csim.solver.newton.BranchPoint.predict`), and its solution must pass
:func:`csim.solver.newton.same_branch`: close to the prediction, with a slope dv/du close
to the one at (u_a, v_a). A stage far from the accepted state is reached by following the
branch in shorter pieces (:func:`csim.solver.newton.follow_branch`). Before, Newton started
from the last solution, whatever evaluation it came from: on Andrews' mechanism at
rtol = atol = 1e-8, a rejected trial step 1.3 rad of crank angle ahead left its solution
behind, the next stage started there and converged to the other closure of the loop H-E
(Omega from -0.05 to +3.09 rad between two stages), and the run went on from there and
reported success. Where the branch cannot be followed to a stage (it folds back, or ends),
the integration restarts from the last accepted state, in a better partition where there
is one; when the branch is lost from the same state after MAX_BRANCH_RESTARTS restarts, the
run fails, naming the change of branch.
"""
from __future__ import annotations

import numpy as np

from csim.errors import PartitionBreakdown, SimulationFailure
from csim.solver.formulations import choose_independent, dependent_block_inverse
from csim.solver.newton import (
    BranchLeftError,
    BranchPoint,
    DependentSolveError,
    follow_branch,
    solve_dependent,
)
from csim.solver.system import ConstrainedSystem

#: restarts from one accepted state, after the branch was lost, before the run fails
MAX_BRANCH_RESTARTS = 2


class BranchChange(PartitionBreakdown):
    """The dependent coordinates could not be kept on their assembly branch up to a stage.

    Raised inside a right-hand-side evaluation; the driver restarts from the last accepted
    state (:meth:`PartitionedSystem.repartition`).
    """


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
    branch_restarts : int
        How many times the integration restarted because the branch was lost at a stage.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.n = self.m - self.r
        self.independent = self.dependent = None
        self.repartitions = 0
        self.branch_restarts = 0
        self._q = None  # the last solved coordinates (m,)
        self._anchor = None  # BranchPoint at the last accepted state: where every solve starts from
        self._end = None  # BranchPoint of the last solve
        self._lost_at = None  # (accepted state, restarts from it) after the branch was lost

    @property
    def n_state(self) -> int:
        return 2 * self.n + self.k

    @property
    def work_slice(self) -> slice:
        return slice(2 * self.n, 2 * self.n + self.k)

    def _partition(self, q: np.ndarray) -> None:
        """Choose u and v at coordinates q on the manifold (:func:`choose_independent`); anchor the branch there."""
        u = choose_independent(self.model.phi_q(q, self.par))
        self.independent, self.dependent = u, np.setdiff1d(np.arange(self.m), u)
        self._anchor_at(q)

    def _anchor_at(self, q: np.ndarray) -> None:
        """Make q (on the manifold) the branch point later solves start from."""
        self._q = np.array(q, dtype=float)
        try:
            self._anchor = BranchPoint.at(self._q, self.model.phi_q(self._q, self.par), self.independent,
                                          self.dependent)
        except DependentSolveError:
            raise PartitionBreakdown(f"minimal: the dependent block Phi_v is singular at q = {self._q}") from None

    def _reduce(self, y_full: np.ndarray) -> np.ndarray:
        q, qd, W = self.split(y_full)
        u = self.independent
        return np.concatenate((q[u], qd[u], W))

    def start(self, y_full: np.ndarray) -> np.ndarray:
        """Partition at q0 and keep u0, ud0 (v0 and vd0 are solved: a perturbed start is projected).

        The assembly the run keeps is the one Newton reaches from the given v0.
        """
        q = np.array(self.split(y_full)[0], dtype=float)
        u = choose_independent(self.model.phi_q(q, self.par))
        self.independent, self.dependent = u, np.setdiff1d(np.arange(self.m), u)
        try:
            q = solve_dependent(self.model, self.par, q, self.dependent, self.stabilizer.tol,
                                self.stabilizer.max_iter).q
        except DependentSolveError as exc:
            self._newton_failure(exc, q[u])
        self._anchor_at(q)
        return self._reduce(y_full)

    def condition(self, q: np.ndarray) -> float:
        """How badly Phi_v determines v at q, ||Phi_q||_1 ||Phi_v^-1||_1 (inf if singular)."""
        return dependent_block_inverse(self.model.phi_q(q, self.par), self.dependent)[1]

    def _newton_failure(self, exc: DependentSolveError, u: np.ndarray):
        """Raise the failure of a dependent solve at the independent coordinates u, by its reason."""
        if exc.reason == "non_finite":
            raise SimulationFailure(f"blow-up: non-finite constraint residual at independent coordinates {u}") from None
        if exc.reason == "singular":
            raise PartitionBreakdown(f"minimal: the dependent block Phi_v is singular at q = {exc.q}") from None
        if isinstance(exc, BranchLeftError):
            names = self.model.definition.coordinate_names
            i = exc.coordinate
            raise BranchChange(
                f"minimal: the assembly branch changes between the last accepted state and the independent "
                f"coordinates {u}, even in the shortest pieces of the way: Newton's solution for the dependent "
                f"coordinates lands {exc.detail} ({names[i]}: {exc.predicted[i]:.6g} predicted, "
                f"{exc.q[i]:.6g} solved)") from None
        raise PartitionBreakdown(
            f"minimal: Newton-Raphson for the dependent coordinates did not reach max |Phi| <= "
            f"{self.stabilizer.tol:g} in {self.stabilizer.max_iter} iterations (max |Phi| = "
            f"{np.max(np.abs(exc.phi)):.3e}); the mechanism cannot be assembled at the independent "
            f"coordinates {u}") from None

    def to_full(self, y: np.ndarray) -> np.ndarray:
        """[q, qd, W] with v solved from Phi(u, v) = 0 on the branch, and vd from Phi_q qd = 0."""
        n, u, v = self.n, self.independent, self.dependent
        try:
            solution, self._end = follow_branch(self.model, self.par, self._anchor, np.asarray(y[:n], dtype=float),
                                                u, v, self.stabilizer.tol, self.stabilizer.max_iter)
        except DependentSolveError as exc:
            self._newton_failure(exc, y[:n])
        self._q = q = solution.q
        qd = np.empty(self.m)
        qd[u] = y[n:2 * n]
        qd[v] = self._end.tangent @ qd[u]  # vd = -Phi_v^-1 Phi_u ud, from Phi_q qd = 0
        return np.concatenate((q, qd, y[2 * n:]))

    def rhs(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """dy/dt = [ud, udd, dW/dt] (2 n + k,)."""
        q, qd, _ = self.split(self.to_full(y))
        loads = self.load_values(t, q, qd, mode)
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
        """Restart from the accepted state y after a breakdown at a later stage.

        In a better partition where there is one. Otherwise, after a :class:`BranchChange`,
        in the same partition (a fresh integrator start takes a different step), at most
        :data:`MAX_BRANCH_RESTARTS` times from the same state. Returns y in the partition to
        go on in; raises SimulationFailure when nothing can carry the integration on.
        """
        full = self.to_full(y)
        if self._choose_again():
            return self._reduce(full)
        if not isinstance(cause, BranchChange):
            raise SimulationFailure(f"{cause} (no better coordinate partition exists at the last accepted state)")
        same = self._lost_at is not None and np.array_equal(self._lost_at[0], y)
        restarts = self._lost_at[1] + 1 if same else 1
        if restarts > MAX_BRANCH_RESTARTS:
            raise SimulationFailure(f"{cause} (again after {MAX_BRANCH_RESTARTS} restarts from the last accepted "
                                    f"state, and no better coordinate partition exists there)")
        self._lost_at = (np.array(y, dtype=float), restarts)
        self.branch_restarts += 1
        return self._reduce(full)

    def after_step(self, t: float, y: np.ndarray) -> tuple[np.ndarray, str]:
        """Anchor the branch at the accepted state y; choose the partition again when Phi_v has turned ill-conditioned.

        The integration restarts only when a better-conditioned partition exists; while the
        current one is the best there is, it goes on.
        """
        full = self.to_full(y)
        self._anchor = self._end  # the accepted state, with its tangent
        if self.condition(self._q) <= self.stabilizer.max_condition or not self._choose_again():
            return y, "keep"
        return self._reduce(full), "restart"
