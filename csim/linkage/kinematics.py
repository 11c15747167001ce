"""Position, velocity and acceleration analysis for prescribed driving joint variables.

Given the driving variables u(t) (and their first two derivatives), the others v solve

    Phi(u, v) = 0                         positions, Newton-Raphson along the assembly branch
    Phi_v vd  = -Phi_u ud                 velocities
    Phi_v vdd = gamma - Phi_u udd         accelerations, gamma = -(d(Phi_q qd)/dq) qd

at every output time. It runs on what dynamics runs on: the mechanism's numeric model
(:func:`csim.pipeline.numeric_model`) and the Newton solver and branch following of
minimal coordinates (:mod:`csim.solver.newton`), with u the independent coordinates. The
result is a :class:`csim.result.Result` like a simulation's, with the quantities a
kinematic analysis does not have (multipliers, loads, work) set to NaN and the run kind in
its message. :func:`solve_positions` (Gauss-Newton with minimum-norm steps) assembles a
linkage's given configuration before any run, where the unknowns outnumber the equations.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from csim.io.units import mechanism_units
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


def _drive_at(drive: Callable, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, ud, udd) at t, each (d,); raises ValueError naming the values when one is not finite."""
    with np.errstate(all="ignore"):
        u, ud, udd = (np.atleast_1d(np.asarray(x, dtype=float)) for x in drive(t))
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(ud)) and np.all(np.isfinite(udd))):
        raise ValueError(f"{KINEMATIC_RUN}: mechanism.drive is not finite at t = {t:.6g} s (the driving variables, "
                         f"their rates and accelerations: {u.tolist()}, {ud.tolist()}, {udd.tolist()})")
    return u, ud, udd


def analyse_motion(model, par: np.ndarray, drive: Callable[[float], tuple[np.ndarray, np.ndarray, np.ndarray]],
                   driven: list[int], times: np.ndarray, q_guess: np.ndarray, labels: list[str],
                   tol: float = 1e-12, max_iter: int = 50, progress: Callable[[float], None] | None = None) -> dict:
    """Kinematic analysis at the output times, on the assembly branch of the start.

    The driving variables u are the independent coordinates of a coordinate partition and
    the others v the dependent ones, solved as ``stabilization.method: minimal`` solves
    them (:mod:`csim.solver.newton` over the core :mod:`csim.physics.branch`): at the first
    time by Newton-Raphson from ``q_guess``, then at each time along the assembly branch
    from the previous solution (its second-order prediction, continuity checked, the way
    cut in pieces where needed), so that the analysis never jumps to another closure.

        Phi(u, v) = 0,   Phi_v vd = -Phi_u ud,   Phi_v vdd = gamma(q, qd) - Phi_u udd

    Parameters
    ----------
    model : csim.model.numeric.NumericModel
        The mechanism's model, as dynamics uses it (``phi``, ``phi_q``, ``gamma``).
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
    tol, max_iter : Newton settings (tolerance on max |Phi|, corrections per solve).
    progress : callable t -> None, optional

    Returns
    -------
    dict with ``t`` (M,), ``q``, ``qd``, ``qdd`` (M, n), ``status``, ``message``, ``failure`` (its kind,
    :data:`csim.result.FAILURES`; "" for a success), ``nsteps``
    (M <= N: a failure stops the analysis at the last solved time).
    """
    from csim.solver.newton import (
        BranchPoint,
        DependentSolveError,
        dependent_velocities,
        follow_branch,
        solve_dependent,
    )

    n = model.n_coordinates
    ind = np.asarray(driven, dtype=int)
    dep = np.setdiff1d(np.arange(n), ind)
    N = times.size
    q_out, qd_out, qdd_out = np.zeros((N, n)), np.zeros((N, n)), np.zeros((N, n))
    status, message, failure = "success", f"{KINEMATIC_RUN}: prescribed drive; lambda, loads, work are NaN", ""
    point, done = None, 0
    for k, t in enumerate(times):
        try:
            u, ud, udd = _drive_at(drive, t)
            if point is None:  # the start: Newton from the guess, then the branch through its solution
                start = np.array(q_guess, dtype=float)
                start[ind] = u
                sol = solve_dependent(model, par, start, dep, tol, max_iter)
                point = BranchPoint.at(sol.q, sol.phi_q, ind, dep)
            else:
                sol, point = follow_branch(model, par, point, u, ind, dep, tol, max_iter)
        except ValueError as exc:  # the drive is not finite
            status, message, failure = "failed", str(exc), "drive"
            break
        except DependentSolveError as exc:
            status, message, failure = "failed", _assembly_message(exc, t, max_iter, labels), "assembly"
            break
        q, J = sol.q, sol.phi_q
        Jv, Ju = J[:, dep], J[:, ind]
        if np.linalg.cond(Jv) > 1e12:
            status, failure = "failed", "singular"
            message = (f"{KINEMATIC_RUN}: Phi_v is singular at t = {t:.6g} s: the driving variables cannot move the "
                       f"mechanism here (a singular position)")
            break
        # Phi_v vd = -Phi_u ud;  Phi_v vdd = gamma(q, qd) - Phi_u udd
        qd, qdd = np.zeros(n), np.zeros(n)
        qd[ind], qdd[ind] = ud, udd
        qd = dependent_velocities(J, qd, dep)
        qdd[dep] = np.linalg.solve(Jv, model.gamma(q, qd, par) - Ju @ udd)
        q_out[k], qd_out[k], qdd_out[k] = q, qd, qdd
        done = k + 1
        if progress is not None:
            progress(float(t))
    return dict(t=times[:done], q=q_out[:done], qd=qd_out[:done], qdd=qdd_out[:done], status=status,
                message=message, failure=failure, nsteps=done)


#: why a position solve failed (csim.solver.newton.DependentSolveError.reason), for messages
_WHY = {
    "singular": "Phi_v is singular on the way there: the driving variables cannot move the mechanism through this "
                "position (a singular position, or the assembly branch folds back)",
    "non_finite": "the constraint equations are not finite there",
    "branch": "Newton's solution left the assembly branch of the start",
}


def _assembly_message(exc, t: float, max_iter: int, labels: list[str]) -> str:
    """Why the positions could not be solved at t (from a DependentSolveError), for the result's message."""
    why = _WHY.get(exc.reason, f"Newton-Raphson did not converge in {max_iter} iterations")
    if exc.reason == "branch":
        why += f": {exc.detail}"
    phi = np.asarray(exc.phi, dtype=float)
    residuals = f"; residuals: {residual_report(labels, phi)}" if phi.size == len(labels) else ""
    return f"{KINEMATIC_RUN}: the mechanism cannot be assembled at t = {t:.6g} s ({why}){residuals}"


def run_kinematics(case, model, progress: Callable[[float], None] | None = None) -> Result:
    """Kinematic analysis of a link-coupling case with ``mechanism.drive``, as a Result.

    ``model`` supplies phi, phi_q, gamma, energies and observables: the case's numeric
    model, the one dynamics runs on (:func:`csim.pipeline.numeric_model`).

    Recorded: q, qd, qdd, Phi, Phi_q qd, kinetic and potential energy (when the links have
    mass), observables. NaN: lambda, loads, work, generalized forces (a kinematic analysis
    has no forces). The message starts with ``"kinematic analysis"``.
    """
    start_time = time.perf_counter()
    linkage = case.linkage
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
        status=out["status"], message=out["message"], failure=out["failure"],
        wall_time=time.perf_counter() - start_time,
        nsteps=out["nsteps"], run_kind="kinematic", **mechanism_units(case.mechanism, model, par),
    )
