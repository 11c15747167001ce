"""Driven dynamics: prescribed joint motion as rheonomic constraints, and the drive forces.

A driven joint variable q_j = f_j(t) (``mechanism.drive`` with ``mechanism.drive_mode:
dynamic``) adds the constraint

    Phi_d(q, t) = q_j - f_j(t) = 0

to the mechanism's own Phi(q) = 0. Its derivatives, from sympy in
:meth:`csim.linkage.plan.LightLinkage.drive_function`, enter the acceleration equation:
Phi_d,q = e_j^T (a constant row), Phi_d,t = -f_j', Phi_d,qt = 0, Phi_d,tt = -f_j'', so

    d/dt Phi_d = qd_j - f_j'(t),      Phi_d,q qdd = gamma_d = f_j''(t)

(gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt). With as many drives as degrees of
freedom, the KKT system has a square, regular Phi_q: the motion is the prescribed one and
the multipliers are the forces that keep it. With fewer drives (a governor's shaft turned
at a set speed while its arms swing freely) the other joints move under the forces, and
the drive multipliers are still the forces that hold the driven joints to their motion. The
constraint force of a drive is -Phi_d,q^T lambda_d = -e_j lambda_d, a generalized force along q_j alone: the drive's
torque (R joint) or force (P joint) is

    tau_j = -lambda_d      [N m or N],

the torque the motor applies on the joint (positive in the sense of q_j), and its power is
tau_j qd_j. The work of each drive is integrated with the motion as an extra quadrature
state, so the energy balance T + V - T0 - V0 - W_loads - W_drives stays a check.

The drive rows are stabilized like the mechanism's constraints: ``baumgarte`` and
``sliding_mode`` take the stacked rows [Phi; Phi_d] with their rates
[Phi_q qd; qd_j - f_j'(t)] (for Baumgarte the drive error e = q_j - f_j(t) then obeys
e'' + 2 d w e' + w^2 e = 0 exactly), and ``projection`` projects onto both after every
step: the positions by the method's Gauss-Newton iteration on [Phi(q); q_j - f_j(t)] = 0,
the velocities to the one solution of J qd = [0; f_j'(t)], J = [Phi_q; e_j^T], where there
is one drive per degree of freedom (J square), else to the nearest solution in the
projection's metric (``projection_metric``: the mass matrix, or the identity). Not offered
(:func:`driven_problems`, exit 2): ``ggl``, ``minimal`` and ``augmented_lagrangian`` (they
integrate a system of their own), the elimination, per-constraint gain lists (the drive
rows need gains too). The compiled kernels run the same rows, built symbolically into the
mechanism's model (:func:`csim.model.derive.with_drive_rows`), for every method above, and the
same projection (:func:`csim.physics.projection.project`, whose velocity target is
Phi_q qd + Phi_t = 0). Both project the recorded samples at their own time too.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from csim.errors import SimulationFailure
from csim.physics.kkt import constraint_rates, generalized_forces
from csim.physics.linalg import as_core
from csim.solver.system import ConstrainedSystem, Evaluation

#: stabilization methods that run with drives as rheonomic constraints
DRIVEN_METHODS = ("none", "baumgarte", "sliding_mode", "projection")

#: the gains of the methods above (one number each: they act on the drive rows too)
GAIN_KEYS = ("d", "w", "Lambda", "K", "k")


def driven_problems(case) -> list[str]:
    """Why a validated case (:class:`csim.case.Case`) with ``mechanism.drive_mode: dynamic`` cannot run ([]: it can)."""
    problems = []
    method = case.stabilization.method
    if method not in DRIVEN_METHODS:
        problems.append(f"stabilization.method: got {method!r} with mechanism.drive_mode 'dynamic'; {method} "
                        f"integrates a system of its own, which does not take the drives as constraints that "
                        f"depend on time; expected one of {', '.join(DRIVEN_METHODS)}")
    for key in GAIN_KEYS:
        if method in DRIVEN_METHODS and isinstance(getattr(case.stabilization, key, None), list | tuple):
            problems.append(f"stabilization.{key}: got a list (one per constraint) with mechanism.drive_mode "
                            f"'dynamic'; the drives are constraints that {method} stabilizes too; expected one "
                            f"number")
    if case.formulation.method != "kkt":
        problems.append(f"formulation.method: got {case.formulation.method!r} with mechanism.drive_mode "
                        f"'dynamic'; the drives are rows the elimination does not take (with one drive per "
                        f"degree of freedom no coordinate is left independent); expected 'kkt'")
    return problems


class DrivenSystem(ConstrainedSystem):
    """The constrained ODE with drives as rheonomic constraints (see the module docstring).

    State y (2 m + k + d,) = [q, qd, W (k loads), W_d (d drives)], integrated and recorded
    whole (:func:`csim.pipeline.initial_state` starts W_d at 0).

    Parameters
    ----------
    model, par, loads, formulation, stabilizer
        As :class:`ConstrainedSystem`.
    driven : sequence of int
        Indices of the driven coordinates (d,).
    drive : callable t -> (f, f', f'')
        The prescribed values, each (d,) [rad or m, per s, per s^2].
    expressions : list of str, optional
        Each f_j as sympy's ``srepr`` of an expression of ``t`` and the model's parameters:
        what the compiled kernels build the drive rows from (:func:`csim.model.derive.with_drive_rows`).
    """

    def __init__(self, model, par, loads, formulation, stabilizer, driven, drive: Callable,
                 expressions: list[str] | None = None):
        super().__init__(model, par, loads, formulation, stabilizer)
        self.driven = np.asarray(driven, dtype=int)
        self.drive = drive
        self.expressions = expressions
        self.d = self.driven.size
        self._rows = np.eye(self.m)[self.driven]  # Phi_d,q (d, m)

    @property
    def n_state(self) -> int:
        return 2 * self.m + self.k + self.d

    @property
    def work_slice(self) -> slice:
        return slice(2 * self.m, self.n_state)

    def _solve_driven(self, t, q, qd, u):
        """qdd (m,), lambda (r,), lambda_d (d,), Phi (r,), Phi_q qd (r,), Q (m,), B (m, k) at time t."""
        model, par, r = self.model, self.par, self.r
        M = model.mass(q, par)
        phi_q = model.phi_q(q, par)
        B = model.load_matrix(q, par)
        p = np.empty(self.m)  # p = B u - C qd - h
        generalized_forces(as_core(B), u, as_core(model.velocity_terms(q, qd, par)), as_core(model.gravity(q, par)), p,
                           self.m, self.k)
        phi = model.phi(q, par)
        phi_dot = np.empty(r)
        constraint_rates(as_core(phi_q), as_core(qd), phi_dot, r, self.m)
        f, fd, fdd = self.drive(t)
        # the stacked rows [Phi; q_j - f_j(t)], their rates [Phi_q qd; qd_j - f_j'(t)] and
        # gamma = [gamma; f_j''(t)], stabilized together
        gamma_star = self.stabilizer.gamma_star(np.concatenate((model.gamma(q, qd, par), fdd)),
                                                np.concatenate((phi, q[self.driven] - f)),
                                                np.concatenate((phi_dot, qd[self.driven] - fd)))
        J = np.vstack((phi_q.reshape(r, self.m), self._rows))
        qdd, lam = self.formulation.solve(M, J, p, gamma_star)
        return qdd, lam[:r], lam[r:], phi, phi_dot, B @ u, B

    def project(self, t: float, y: np.ndarray) -> np.ndarray:
        """y with (q, qd) projected (``projection``) onto Phi = 0 and the drives at time t.

        Positions by the method's Gauss-Newton iteration on [Phi(q); q_j - f_j(t)] = 0, then
        velocities onto J qd = [0; f_j'(t)], J = [Phi_q; e_j^T], with one correction
        (:func:`csim.physics.projection.project`, Phi_t = [0; -f_j'(t)]): with one drive per degree
        of freedom J is square and that is J^-1 [0; f'(t)]; with fewer, the velocities nearest the
        integrated ones in the projection's metric.
        """
        q, qd, _ = self.split(y)
        view = _DriveRows(self.model, self.driven, self.drive(t))
        q, qd = self.stabilizer.project(view, self.par, q, qd, t=t, phi_t=view.phi_t)
        return np.concatenate((q, qd, y[2 * self.m:]))

    def rhs(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """dy/dt (n_state,): [qd, qdd, u (B^T qd), tau qd_driven]."""
        q, qd, _ = self.split(y)
        u = self.load_values(t, q, qd, mode)
        qdd, _, lam_d, _, _, _, B = self._solve_driven(t, q, qd, u)
        return np.concatenate((qd, qdd, u * self._load_rates(B, qd), -lam_d * qd[self.driven]))

    def evaluate(self, t: float, y: np.ndarray, mode: np.ndarray) -> Evaluation:
        """The recorded quantities (the mechanism's constraints only; the drives: :meth:`drive_forces`)."""
        q, qd, _ = self.split(y)
        u = self.load_values(t, q, qd, mode)
        qdd, lam, _, phi, phi_dot, Q, _ = self._solve_driven(t, q, qd, u)
        phi, phi_dot, lam = self.recorded(q, qd, lam, phi, phi_dot)  # (an overconstrained linkage: its full set)
        return Evaluation(qdd=qdd, lam=lam, phi=phi, phi_dot=phi_dot, u=u, Q=Q,
                          kinetic=self.model.kinetic_energy(q, qd, self.par),
                          potential=self.model.potential_energy(q, self.par))

    def drive_forces(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """tau (d,) = -lambda_d: the torque [N m] or force [N] each drive applies along its variable."""
        q, qd, _ = self.split(y)
        return -self._solve_driven(t, q, qd, self.load_values(t, q, qd, mode))[2]


class _DriveRows:
    """The model seen with the drive rows at one instant appended to its constraints, for a
    method's projection (it reads ``n_constraints``, ``mass``, ``phi``, ``phi_q`` and ``phi_t``).

    Parameters
    ----------
    model : NumericModel
    driven : ndarray (d,) of int
    values : (f, f', f'') at that instant, each (d,)
    """

    def __init__(self, model, driven: np.ndarray, values):
        self.model, self.driven = model, driven
        self.target = values[0]
        self.n_constraints = model.n_constraints + driven.size
        #: Phi_t (r + d,): the rows' rates at fixed q, [0; -f'(t)]
        self.phi_t = np.concatenate((np.zeros(model.n_constraints), -np.asarray(values[1], dtype=float)))
        self._rows = np.eye(model.n_coordinates)[driven]

    def mass(self, q, par):
        return self.model.mass(q, par)

    def phi(self, q, par):
        return np.concatenate((self.model.phi(q, par), q[self.driven] - self.target))

    def phi_q(self, q, par):
        r, m = self.model.n_constraints, self._rows.shape[1]
        return np.vstack((np.asarray(self.model.phi_q(q, par)).reshape(r, m), self._rows))


def record_drives(result, system: DrivenSystem, t: np.ndarray, y: np.ndarray, mode: np.ndarray,
                  names: list[str], units: list[str]) -> None:
    """Set a driven run's drive forces and work on ``result`` (and keep its load work only).

    Parameters
    ----------
    result : csim.result.Result
        As assembled from the trajectory (its ``work`` holds the drives' work as extra columns;
        its ``drive_forces``, where the compiled evaluation of the samples gave them, are kept,
        and only their NaN rows evaluated here).
    system : DrivenSystem
    t : ndarray (N,); y : ndarray (N, n_state); mode : ndarray (N, n_switches)
        The trajectory's samples.
    names, units : list of str
        The driven coordinates and the unit of each drive's force (N m or N).
    """
    N, k = t.size, system.k
    given = result.drive_forces
    tau = np.array(given, dtype=float) if given is not None and given.shape == (N, system.d) else \
        np.full((N, system.d), np.nan)
    for i in np.flatnonzero(np.isnan(tau).any(axis=1)):
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                tau[i] = system.drive_forces(t[i], y[i], mode[i])
        except SimulationFailure:  # a sample that cannot be evaluated (the last state of a blow-up) stays NaN
            continue
    work = np.asarray(result.work)
    result.work, result.drive_work = work[:, :k], work[:, k:k + system.d]
    result.drive_forces, result.drive_names, result.drive_units = tau, list(names), list(units)
