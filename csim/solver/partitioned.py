"""Minimal coordinates by coordinate partitioning (Wehage and Haug).

The m coordinates are split into n = m - r independent ones u and r dependent ones v.
Only u, its rate and the work states are integrated, y = [u (n), ud (n), W (k)]. At every
evaluation the dependent coordinates follow from the constraints,

    Phi(u, v) = 0                   (Newton-Raphson on v, on the assembly branch)
    Phi_v vd = -Phi_u ud            (their rates)

and the accelerations from the equations of motion on the tangent space,

    (R^T M R) u'' = R^T (p - M c),   R = [E; dv/du],   c = [0; Phi_v^-1 gamma]

(:func:`csim.physics.partition.reduced_accelerations`: an n x n solve with the dv/du and
Phi_v's LU factors the solve on the branch leaves, where the KKT system is (m + r) x (m + r);
the case's formulation gives the recorded samples' multipliers). The constraints therefore hold to the
Newton tolerance at every instant, with no drift to stabilize. When the dependent block Phi_v turns ill-conditioned (the
mechanism nears a configuration where v is no longer a function of u) the partition is
chosen again (:func:`csim.physics.partition.choose_partition`: the best-conditioned block, by
trying every one where that is cheap, else by pivoted QR) and the integration restarts from
the same state.

The numerics, written once for both backends, are :mod:`csim.physics.branch` (the solves on
the branch, the partition's choice and repartitioning, with the rules they follow) and
:mod:`csim.physics.partition`; this class drives them from Python, over the numeric model,
and raises the driver's exceptions from their status codes.
"""
from __future__ import annotations

import numpy as np

from csim.errors import PartitionBreakdown, SimulationFailure
from csim.physics import branch as core
from csim.physics.linalg import as_core
from csim.physics.partition import (
    C_BRANCH_RESTARTS,
    C_REPARTITIONS,
    MAX_BRANCH_RESTARTS,
    block_inverse,
    new_partition,
    reduced_accelerations,
)
from csim.physics.status import BRANCH_LEFT, OK, TANGENT_MASS_SINGULAR
from csim.solver.failures import failure
from csim.solver.newton import PythonModel
from csim.solver.system import ConstrainedSystem

__all__ = ["MAX_BRANCH_RESTARTS", "BranchChange", "PartitionedSystem"]


class BranchChange(PartitionBreakdown):
    """The dependent coordinates could not be kept on their assembly branch up to a stage.

    Raised inside a right-hand-side evaluation; the driver restarts from the last accepted
    state (:meth:`PartitionedSystem.repartition`).
    """


class PartitionedSystem(ConstrainedSystem):
    """The equations of motion in the independent coordinates only.

    Parameters are those of :class:`ConstrainedSystem`; the stabilizer is a
    :class:`csim.solver.methods.minimal.Minimal` and carries the Newton settings and the
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
        self.P = new_partition(self.m, self.r, self.k)  # the core's state: partition, anchor, scratch
        self.calls = PythonModel(self.model, self.par)

    @property
    def independent(self) -> np.ndarray:
        return self.P.ind.copy()

    @property
    def dependent(self) -> np.ndarray:
        return self.P.dep.copy()

    @property
    def repartitions(self) -> int:
        return int(self.P.count[C_REPARTITIONS])

    @property
    def branch_restarts(self) -> int:
        return int(self.P.count[C_BRANCH_RESTARTS])

    @property
    def n_state(self) -> int:
        return 2 * self.n + self.k

    @property
    def work_slice(self) -> slice:
        return slice(2 * self.n, 2 * self.n + self.k)

    def _settings(self) -> tuple:
        """(r, m, k, tol, max_iter): the sizes and Newton settings every core call takes."""
        return self.r, self.m, self.k, self.stabilizer.tol, self.stabilizer.max_iter

    def _check(self, code: int) -> None:
        """Raise the driver's exception for a core status code (nothing for OK)."""
        if code == OK:
            return
        exc = self._failure(code)
        if code == BRANCH_LEFT:
            raise BranchChange(str(exc), exc.kind)
        if core.is_breakdown(code):
            raise PartitionBreakdown(str(exc), exc.kind)
        raise exc

    def _failure(self, code: int) -> SimulationFailure:
        """The SimulationFailure of core status ``code``, with the partition's details."""
        return failure(code, 0.0, 0.0, None, self.stabilizer, detail=self.P.detail.copy(),
                       coordinates=self.model.definition.coordinate_names)

    def start(self, y_full: np.ndarray) -> np.ndarray:
        """Partition at q0 and keep u0, ud0 (v0 and vd0 are solved: a perturbed start is projected)."""
        y = np.empty(self.n_state)
        self._check(core.start(self.calls, self.P, np.array(y_full, dtype=float), y, *self._settings()))
        return y

    def condition(self, q: np.ndarray) -> float:
        """How badly Phi_v determines v at q, ||Phi_q||_1 ||Phi_v^-1||_1 (inf if singular)."""
        r, m = self.r, self.m
        J = np.ascontiguousarray(self.model.phi_q(q, self.par), dtype=float).ravel()
        return block_inverse(J, self.P.dep, r, m, np.empty(r * r), np.empty(r, np.int64), np.empty(r),
                             np.empty(r * r))

    def to_full(self, y: np.ndarray) -> np.ndarray:
        """[q, qd, W] with v solved from Phi(u, v) = 0 on the branch, and vd from Phi_q qd = 0."""
        yf = np.empty(2 * self.m + self.k)
        self._check(core.to_full(self.calls, self.P, np.ascontiguousarray(y, dtype=float), yf, *self._settings()))
        return yf

    def rhs(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """dy/dt = [ud, udd, dW/dt] (2 n + k,): udd from the equations of motion on the tangent space at the full
        state (core: ``reduced_accelerations``, an n x n solve; the formulation serves the recorded samples)."""
        q, qd, _ = self.split(self.to_full(y))
        loads = self.load_values(t, q, qd, mode)
        M, _, p, _, _, gamma_star, _, B = self._terms(q, qd, loads)
        qdd = np.empty(self.m)
        if not reduced_accelerations(self.P, as_core(M), as_core(p), as_core(gamma_star), qdd, self.r, self.m):
            raise failure(TANGENT_MASS_SINGULAR, 0.0, 0.0, None)
        f = np.empty(self.n_state)
        core.reduce(self.P, np.concatenate((qd, qdd, loads * self._load_rates(B, qd))), f, self.r, self.m, self.k)
        return f

    def repartition(self, y: np.ndarray, cause: Exception) -> np.ndarray:
        """Restart from the accepted state y after a breakdown at a later stage (core: ``repartition``).

        Returns y in the partition to go on in; raises SimulationFailure when nothing can
        carry the integration on.
        """
        y = np.array(y, dtype=float)
        code = core.repartition(self.calls, self.P, y, *self._settings())
        if code != OK:
            raise self._failure(code)
        return y

    def after_step(self, t: float, y: np.ndarray) -> tuple[np.ndarray, str]:
        """Anchor the branch at the accepted state y; choose the partition again when Phi_v has turned ill-conditioned.

        The integration restarts only when a better-conditioned partition exists
        (:func:`csim.physics.branch.after_step`).
        """
        y = np.array(y, dtype=float)
        code, restart = core.after_step(self.calls, self.P, y, *self._settings(), self.stabilizer.max_condition)
        self._check(code)
        return y, "restart" if restart else "keep"
