"""Consistent initial conditions: Phi(q0) = 0 and Phi_q(q0) qd0 = 0.

Given the independent coordinates u and velocities ud, Newton-Raphson solves Phi(u, v) = 0
for the dependent coordinates v,

    Phi_v(q_i) (v_{i+1} - v_i) = -Phi(q_i),

and a linear solve gives the dependent velocities, Phi_v vd = -Phi_u ud.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.errors import SimulationFailure
from csim.model.numeric import NumericModel


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

    def phi_v_at(q_):
        phi_v = model.phi_q(q_, par)[:, v]
        if np.linalg.cond(phi_v) > 1e12:
            raise SimulationFailure(
                f"initial conditions: the constraint Jacobian with respect to the dependent "
                f"coordinates ({dep_names}) is singular at q = {_fmt(names, q_)}; the given "
                f"independent coordinates cannot drive the mechanism here, or the guess is poor"
            )
        return phi_v

    residual = np.inf
    for iteration in range(max_iter + 1):
        phi = model.phi(q, par)
        residual = float(np.max(np.abs(phi))) if phi.size else 0.0
        if residual <= tol:
            break
        if iteration == max_iter:
            per_eq = ", ".join(f"Phi[{i}] = {val:.3e}" for i, val in enumerate(phi))
            raise SimulationFailure(
                f"initial conditions: Newton-Raphson did not converge in {max_iter} iterations "
                f"(residuals {per_eq}; last q = {_fmt(names, q)}); the mechanism may not "
                f"assemble at the given independent coordinates, or initial.guess is poor"
            )
        # Newton step on the dependent coordinates
        q[v] -= np.linalg.solve(phi_v_at(q), phi)
        if not np.all(np.isfinite(q)):
            raise SimulationFailure("initial conditions: Newton-Raphson diverged (non-finite coordinates)")
    qd = np.zeros(m)
    for name, value in velocities.items():
        qd[names.index(name)] = value
    # Phi_v vd = -Phi_u ud
    phi_q = model.phi_q(q, par)
    qd[v] = np.linalg.solve(phi_v_at(q), -phi_q[:, u] @ qd[u])
    return InitialState(q=q, qd=qd, iterations=iteration, residual=residual)


def _fmt(names, q):
    return "[" + ", ".join(f"{n}={x:.6g}" for n, x in zip(names, q)) + "]"
