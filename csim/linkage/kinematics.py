"""Position, velocity and acceleration analysis for prescribed driving joint variables.

Given the driving variables u(t) (and their first two derivatives), the others v solve

    Phi(u, v) = 0                         positions, Newton-Raphson (Gauss-Newton with the
                                          minimum-norm step when Phi_v is not square)
    Phi_v vd  = -Phi_u ud                 velocities
    Phi_v vdd = gamma - Phi_u udd         accelerations, gamma = -(d(Phi_q qd)/dq) qd

at every output time, each Newton start being the previous solution extrapolated with its
velocity and acceleration. The result is a :class:`csim.result.Result` like a simulation's,
with the quantities a kinematic analysis does not have (multipliers, loads, work) set to
NaN and the run kind in its message.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from csim.result import Result

#: First words of the message of a kinematic run's result (the run kind).
KINEMATIC_RUN = "kinematic analysis"


@dataclass
class Assembly:
    """Outcome of a position solve.

    Attributes
    ----------
    q : ndarray (n,)
    residual : ndarray (r,), Phi at q
    iterations : int
    converged : bool
    """

    q: np.ndarray
    residual: np.ndarray
    iterations: int
    converged: bool


def solve_positions(phi: Callable, phi_q: Callable, q_start: np.ndarray, free: np.ndarray,
                    tol: float = 1e-12, max_iter: int = 50) -> Assembly:
    """Newton-Raphson (Gauss-Newton, minimum-norm steps) on Phi(q) = 0 over ``q[free]``.

    Parameters
    ----------
    phi : callable q -> (r,)
    phi_q : callable q -> (r, n)
    q_start : ndarray (n,)
        Start; the entries outside ``free`` stay fixed.
    free : ndarray of int
        Indices of the unknowns.
    tol : float
        Converged when max |Phi| <= tol [unit of Phi].
    max_iter : int

    Returns
    -------
    Assembly (``converged`` False when the iteration limit was reached or it diverged).
    """
    q = np.array(q_start, dtype=float)
    res = np.asarray(phi(q), dtype=float)
    for iteration in range(max_iter + 1):
        if res.size == 0 or np.max(np.abs(res)) <= tol:
            return Assembly(q, res, iteration, True)
        if iteration == max_iter:
            break
        J = np.asarray(phi_q(q), dtype=float)[:, free]
        if not np.all(np.isfinite(J)):
            break
        try:
            step = np.linalg.lstsq(J, -res, rcond=None)[0]
        except np.linalg.LinAlgError:
            break
        q[free] += step
        res = np.asarray(phi(q), dtype=float)
        if not np.all(np.isfinite(q)) or not np.all(np.isfinite(res)):
            break
    return Assembly(q, res, max_iter, False)


def residual_report(labels: list[str], residual: np.ndarray) -> str:
    """'label = value' for every equation, for failure messages."""
    return "; ".join(f"{lab} = {val:.3e}" for lab, val in zip(labels, residual))


def analyse_motion(model, par: np.ndarray, drive: Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]],
                   driven: list[int], times: np.ndarray, q_guess: np.ndarray, labels: list[str],
                   tol: float = 1e-12, max_iter: int = 50, progress: Callable[[float], None] | None = None) -> dict:
    """Kinematic analysis at the output times.

    Parameters
    ----------
    model : csim.model.numeric.NumericModel
        Its ``phi``, ``phi_q`` and ``gamma`` (the independent cut-joint equations).
    par : ndarray (n_par,)
    drive : callable t -> (u, ud, udd), each (d,)
        Driving variables [rad or m], their rates and second rates.
    driven : list of int
        Indices of the driving variables in q.
    times : ndarray (N,) [s]
    q_guess : ndarray (n,)
        Newton start at the first time (its driven entries are replaced by u(t0)).
    labels : list of str
        One per equation, for messages.
    tol, max_iter : Newton settings.
    progress : callable t -> None, optional

    Returns
    -------
    dict with ``t`` (M,), ``q``, ``qd``, ``qdd`` (M, n), ``status``, ``message``, ``nsteps``
    (M <= N: a failure stops the analysis at the last solved time).
    """
    n = model.n_coordinates
    driven = np.asarray(driven, dtype=int)
    free = np.array([i for i in range(n) if i not in set(driven.tolist())], dtype=int)
    N = times.size
    q_out, qd_out, qdd_out = np.zeros((N, n)), np.zeros((N, n)), np.zeros((N, n))
    status, message = "success", f"{KINEMATIC_RUN}: prescribed drive; lambda, loads, work are NaN"
    start = np.array(q_guess, dtype=float)
    done = 0
    for k, t in enumerate(times):
        with np.errstate(all="ignore"):
            u, ud, udd = (np.atleast_1d(np.asarray(x, dtype=float)) for x in drive(t))
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(ud)) and np.all(np.isfinite(udd))):
            status = "failed"
            message = (f"{KINEMATIC_RUN}: mechanism.drive is not finite at t = {t:.6g} s (the driving variables, "
                       f"their rates and accelerations: {u.tolist()}, {ud.tolist()}, {udd.tolist()})")
            break
        if k > 0:
            h = t - times[k - 1]
            start = q_out[k - 1] + h * qd_out[k - 1] + 0.5 * h * h * qdd_out[k - 1]
        start[driven] = u
        sol = solve_positions(lambda q: model.phi(q, par), lambda q: model.phi_q(q, par), start, free, tol, max_iter)
        if not sol.converged:
            status = "failed"
            message = (f"{KINEMATIC_RUN}: the mechanism cannot be assembled at t = {t:.6g} s (Newton-Raphson did "
                       f"not converge in {max_iter} iterations); residuals: {residual_report(labels, sol.residual)}")
            break
        q = sol.q
        J = model.phi_q(q, par)
        Jv, Ju = J[:, free], J[:, driven]
        if Jv.shape[0] != Jv.shape[1] or np.linalg.cond(Jv) > 1e12:
            status = "failed"
            message = (f"{KINEMATIC_RUN}: Phi_v is singular at t = {t:.6g} s: the driving variables cannot move the "
                       f"mechanism here (a singular position)")
            break
        qd = np.zeros(n)
        qd[driven] = ud
        qd[free] = np.linalg.solve(Jv, -Ju @ ud)
        qdd = np.zeros(n)
        qdd[driven] = udd
        qdd[free] = np.linalg.solve(Jv, model.gamma(q, qd, par) - Ju @ udd)
        q_out[k], qd_out[k], qdd_out[k] = q, qd, qdd
        done = k + 1
        if progress is not None:
            progress(float(t))
    return dict(t=times[:done], q=q_out[:done], qd=qd_out[:done], qdd=qdd_out[:done], status=status,
                message=message, nsteps=done)


class KinematicModel:
    """The terms a kinematic analysis needs, compiled straight from a MechanismDefinition.

    Same call signatures as :class:`csim.model.numeric.NumericModel` (``phi(q, par)`` (r,),
    ``phi_q(q, par)`` (r, m), ``gamma(q, qd, par)`` (r,), energies [J], observables), but
    without the mass matrix and without simplification: gamma = -(d(Phi_q qd)/dq) qd is
    lambdified with common-subexpression elimination, so that spatial loops (whose
    equations have hundreds of terms) compile in seconds.
    """

    def __init__(self, definition):
        import sympy as sp

        self.definition = definition
        q, qd = list(definition.coordinates), list(definition.velocities)
        par = definition.parameter_symbols
        phi = sp.Matrix(definition.constraints) if definition.constraints else sp.zeros(0, 1)
        phi_q = phi.jacobian(q) if definition.constraints else sp.zeros(0, len(q))
        gamma = -(phi_q * sp.Matrix(qd)).jacobian(q) * sp.Matrix(qd) if definition.constraints else sp.zeros(0, 1)
        obs = sp.Matrix([o.expression for o in definition.observables]) if definition.observables else sp.zeros(0, 1)
        obs_q = obs.jacobian(q) if definition.observables else sp.zeros(0, len(q))
        self._phi = sp.lambdify([q, par], phi, "numpy", cse=True)
        self._phi_q = sp.lambdify([q, par], phi_q, "numpy", cse=True)
        self._gamma = sp.lambdify([q, qd, par], gamma, "numpy", cse=True)
        self._T = sp.lambdify([q, qd, par], definition.kinetic_energy, "numpy", cse=True)
        self._V = sp.lambdify([q, par], definition.potential_energy, "numpy", cse=True)
        self._obs = sp.lambdify([q, par], obs, "numpy", cse=True)
        self._obs_q = sp.lambdify([q, par], obs_q, "numpy", cse=True)
        self.n_coordinates, self.n_constraints, self.n_loads = len(q), phi.shape[0], len(definition.loads)
        self._o = obs.shape[0]

    def parameter_vector(self, values: dict[str, float] | None = None) -> np.ndarray:
        values = values or {}
        return np.array([float(values.get(p.name, p.default)) for p in self.definition.parameters])

    def phi(self, q, par):
        return np.asarray(self._phi(list(q), list(par)), dtype=float).reshape(self.n_constraints)

    def phi_q(self, q, par):
        return np.asarray(self._phi_q(list(q), list(par)), dtype=float).reshape(self.n_constraints,
                                                                                 self.n_coordinates)

    def gamma(self, q, qd, par):
        return np.asarray(self._gamma(list(q), list(qd), list(par)), dtype=float).reshape(self.n_constraints)

    def kinetic_energy(self, q, qd, par):
        return float(self._T(list(q), list(qd), list(par)))

    def potential_energy(self, q, par):
        return float(self._V(list(q), list(par)))

    def observables(self, q, par):
        return np.asarray(self._obs(list(q), list(par)), dtype=float).reshape(self._o)

    def observable_jacobian(self, q, par):
        return np.asarray(self._obs_q(list(q), list(par)), dtype=float).reshape(self._o, self.n_coordinates)


def run_kinematics(case, model=None, progress: Callable[[float], None] | None = None) -> Result:
    """Kinematic analysis of a link-coupling case with ``mechanism.drive``, as a Result.

    ``model`` supplies phi, phi_q, gamma, energies and observables (default: a
    :class:`KinematicModel` of the case's mechanism).

    Recorded: q, qd, qdd, Phi, Phi_q qd, kinetic and potential energy (when the links have
    mass), observables. NaN: lambda, loads, work, generalized forces (a kinematic analysis
    has no forces). The message starts with ``"kinematic analysis"``.
    """
    start_time = time.perf_counter()
    linkage = case.linkage
    model = model if model is not None else KinematicModel(case.mechanism)
    par = model.parameter_vector(case.parameters)
    t_end, dt = case.simulation.t_end, case.output.dt
    count = int(np.floor(t_end / dt + 1e-9)) + 1
    times = np.linspace(0.0, (count - 1) * dt, count)
    if times[-1] < t_end - 1e-12:
        times = np.append(times, t_end)
    names = case.mechanism.coordinate_names
    ini = case.initial
    q_guess = np.array([linkage.start.get(n, 0.0) for n in names])
    for name, value in ini.guess.items():
        q_guess[names.index(name)] = value
    out = analyse_motion(model, par, linkage.drive_function(case.parameters), linkage.driven_indices,
                         times, q_guess, linkage.equation_labels, tol=ini.tol, max_iter=ini.max_iter,
                         progress=progress)
    t, q, qd, qdd = out["t"], out["q"], out["qd"], out["qdd"]
    M, r, k, o = t.size, model.n_constraints, model.n_loads, len(case.mechanism.observables)
    phi, phi_dot = np.zeros((M, r)), np.zeros((M, r))
    kinetic, potential = np.zeros(M), np.zeros(M)
    observables, rates = np.zeros((M, o)), np.zeros((M, o))
    for i in range(M):
        phi[i] = model.phi(q[i], par)
        phi_dot[i] = model.phi_q(q[i], par) @ qd[i]
        kinetic[i] = model.kinetic_energy(q[i], qd[i], par)
        potential[i] = model.potential_energy(q[i], par)
        if o:
            observables[i] = model.observables(q[i], par)
            rates[i] = model.observable_jacobian(q[i], par) @ qd[i]
    nan = np.nan
    return Result(
        mechanism=case.mechanism.name,
        coordinate_names=names,
        load_names=[ld.name for ld in case.mechanism.loads],
        observable_names=[ob.name for ob in case.mechanism.observables],
        case_yaml=case.to_yaml(),
        t=t, q=q, qd=qd, qdd=qdd, lam=np.full((M, r), nan), phi=phi, phi_dot=phi_dot,
        kinetic=kinetic, potential=potential, work=np.full((M, k), nan), loads=np.full((M, k), nan),
        generalized_forces=np.full((M, len(names)), nan), observables=observables, observable_rates=rates,
        status=out["status"], message=out["message"], wall_time=time.perf_counter() - start_time,
        nsteps=out["nsteps"], run_kind="kinematic",
    )
