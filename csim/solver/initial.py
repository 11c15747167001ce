"""Consistent initial conditions: Phi(q0) = 0 and Phi_q(q0) qd0 = 0.

Given the independent coordinates u and velocities ud, Newton-Raphson solves Phi(u, v) = 0
for the dependent coordinates v, and a linear solve gives the dependent velocities,
Phi_v vd = -Phi_u ud (:mod:`csim.solver.newton`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.errors import SimulationFailure
from csim.model.numeric import NumericModel
from csim.physics.jit import plain
from csim.solver.newton import DependentSolveError, dependent_velocities, solve_dependent

#: the dependent block Phi_v counts as singular beyond this 2-norm condition number
MAX_CONDITION = 1e12


@dataclass
class InitialState:
    """Consistent initial state.

    Attributes
    ----------
    q, qd : ndarray (m,)
    iterations : int
        Newton iterations used.
    residual : float
        max |Phi(q)| at the solution.
    """

    q: np.ndarray
    qd: np.ndarray
    iterations: int
    residual: float


def consistent_initial_state(model: NumericModel, par: np.ndarray, independent: dict[str, float],
                             velocities: dict[str, float], guess: dict[str, float],
                             tol: float = 1e-12, max_iter: int = 50) -> InitialState:
    """Solve for the dependent coordinates and velocities.

    Parameters
    ----------
    model : NumericModel
    par : ndarray (n_par,)
    independent : dict name -> value
        Values of the independent coordinates [rad or m]; there must be m - r of them.
    velocities : dict name -> value
        Their velocities; missing ones are 0.
    guess : dict name -> value
        Newton start values of dependent coordinates (missing ones start at 0).
    tol : float
        Convergence when max |Phi| <= tol [unit of Phi].
    max_iter : int

    Raises
    ------
    SimulationFailure
        Newton did not converge (the message lists each residual), or the Jacobian block
        of the dependent coordinates is singular.
    """
    names = model.definition.coordinate_names
    m = len(names)
    u = np.array([names.index(k) for k in independent], dtype=int)
    v = np.array([i for i in range(m) if i not in set(u)], dtype=int)
    q = np.zeros(m)
    for i, name in enumerate(names):
        q[i] = independent.get(name, guess.get(name, 0.0))
    dep_names = ", ".join(names[i] for i in v)

    def singular(q_):
        return SimulationFailure(
            f"initial conditions: the constraint Jacobian with respect to the dependent "
            f"coordinates ({dep_names}) is singular at q = {_fmt(names, q_)}; the given "
            f"independent coordinates cannot drive the mechanism here, or the guess is poor", "assembly")

    try:
        with plain():  # a few iterations: plain Python beats loading compiled code (csim.physics.jit)
            solution = solve_dependent(model, par, q, v, tol, max_iter, max_condition=MAX_CONDITION)
    except DependentSolveError as exc:
        if exc.reason == "singular":
            raise singular(exc.q) from None
        if exc.reason == "non_finite":
            raise SimulationFailure("initial conditions: Newton-Raphson diverged (non-finite coordinates)",
                                    "assembly") from None
        per_eq = ", ".join(f"Phi[{i}] = {val:.3e}" for i, val in enumerate(exc.phi))
        raise SimulationFailure(
            f"initial conditions: Newton-Raphson did not converge in {max_iter} iterations "
            f"(residuals {per_eq}; last q = {_fmt(names, exc.q)}); the mechanism may not "
            f"assemble at the given independent coordinates, or initial.guess is poor", "assembly") from None
    q, phi_q = solution.q, solution.phi_q
    if v.size and np.linalg.cond(phi_q[:, v]) > MAX_CONDITION:  # a tree has no dependent coordinates
        raise singular(q)
    qd = np.zeros(m)
    for name, value in velocities.items():
        qd[names.index(name)] = value
    with plain():
        qd = dependent_velocities(phi_q, qd, v)  # Phi_v vd = -Phi_u ud
    return InitialState(q=q, qd=qd, iterations=solution.iterations, residual=solution.residual)


def _fmt(names, q):
    return "[" + ", ".join(f"{n}={x:.6g}" for n, x in zip(names, q)) + "]"
