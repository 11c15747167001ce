"""The run pipeline: case -> model -> system -> initial state -> integration -> result.

Library functions the CLI and the tests both call.
"""
from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from csim.case import Case
from csim.errors import SimulationFailure
from csim.fast import KERNEL_BACKENDS, integrate_compiled, prepare_compiled, resolve_backend
from csim.io.outputs import EVALUATED
from csim.io.units import mechanism_units
from csim.model.cache import definition_key
from csim.model.numeric import NumericModel, build_numeric_model
from csim.result import Result
from csim.solver.formulations import make_formulation
from csim.solver.initial import consistent_initial_state
from csim.solver.methods import stabilizer_from
from csim.solver.settings import Trajectory
from csim.solver.system import ConstrainedSystem

_MODELS: dict[str, NumericModel] = {}


def numeric_model(case: Case) -> NumericModel:
    """The (process-wide cached) numeric model of the case's mechanism."""
    # keyed by the symbolic content too: link-coupling cases share names but not models
    key = f"{case.mechanism.name}-{definition_key(case.mechanism)}"
    if key not in _MODELS:
        _MODELS[key] = build_numeric_model(case.mechanism)
    return _MODELS[key]


def build_system(case: Case) -> ConstrainedSystem:
    """The ODE system of a case: model, parameters, loads, formulation and stabilizer.

    An overconstrained linkage's model chooses its independent rows among all its equations
    as it moves (:class:`csim.solver.redundant.RedundantModel`), for every method that works
    with the constraint equations as rows (all but ``minimal``, which chooses its partition
    itself, and ``augmented_lagrangian``, which takes the full set as it is).
    """
    model = numeric_model(case)
    if reselects_rows(case):
        from csim.solver.redundant import RedundantModel

        par = model.parameter_vector(case.parameters)
        model = RedundantModel(model, constraint_watch(case, model, par), par)
    form = case.formulation
    settings = {}
    if form.method == "elimination":
        names = case.mechanism.coordinate_names
        settings = dict(
            independent=None if form.independent is None else [names.index(n) for n in form.independent],
            max_condition=form.max_condition,
        )
    stabilizer = stabilizer_from(case.stabilization)
    if case.driven:  # drives as rheonomic constraints (csim.solver.driven)
        from csim.solver.driven import DrivenSystem

        return DrivenSystem(model, model.parameter_vector(case.parameters), case.load_set(),
                            make_formulation(form.method, **settings), stabilizer,
                            case.linkage.driven_indices, case.linkage.drive_function(case.parameters),
                            case.linkage.drive_expressions(case.parameters, case.mechanism.parameter_names))
    system = stabilizer.system_class()(
        model=model,
        par=model.parameter_vector(case.parameters),
        loads=case.load_set(),
        formulation=make_formulation(form.method, **settings),
        stabilizer=stabilizer,
    )
    if hasattr(system, "use_constraints"):  # integrates every non-trivial equation, the removed ones too
        system.use_constraints(constraint_watch(case, system.model, system.par))
    return system


def initial_state(case: Case, system: ConstrainedSystem) -> np.ndarray:
    """Initial state vector y0 = [q0, qd0, W0 = 0] (raises SimulationFailure).

    Consistent, plus the case's ``initial.q_offset`` and ``initial.qd_offset`` (zero unless a
    perturbed start is asked for).
    """
    ini = case.initial
    state = consistent_initial_state(system.model, system.par, ini.q, ini.qd, ini.guess, tol=ini.tol,
                                     max_iter=ini.max_iter)
    names = case.mechanism.coordinate_names
    q0, qd0 = state.q.copy(), state.qd.copy()
    for name, dq in ini.q_offset.items():
        q0[names.index(name)] += dq
    for name, dqd in ini.qd_offset.items():
        qd0[names.index(name)] += dqd
    # W = 0: the work of the loads, and of the drives of driven dynamics (csim.solver.driven)
    return np.concatenate((q0, qd0, np.zeros(system.k + getattr(system, "d", 0))))


def run_case(case: Case, progress: Callable[[float], None] | None = None) -> Result:
    """Simulate a validated case. Failures come back as a result with status "failed".

    A link-coupling case with prescribed drives is a kinematic analysis instead
    (:func:`csim.linkage.kinematics.run_kinematics`).
    """
    if case.kinematic:
        from csim.linkage.kinematics import run_kinematics

        return run_kinematics(case, numeric_model(case), progress=progress)
    system = build_system(case)  # the model: derived, or loaded from the cache (not timed)
    settings = case.integration_settings()
    start = time.perf_counter()
    try:
        y0 = initial_state(case, system)
    except SimulationFailure as exc:
        empty = Trajectory(t=np.zeros(0), y=np.zeros((0, system.n_state)),
                           mode=np.zeros((0, system.loads.n_switches), bool), status="failed", message=str(exc),
                           failure="assembly")  # the initial state cannot be assembled: bad input (csim run exits 2)
        return assemble_result(case, system, empty, time.perf_counter() - start)
    backend, why, load_time = resolve_backend(case), "", 0.0
    if backend == "compiled":
        loading = time.perf_counter()
        backend, why = _load_compiled(case, system, y0, settings)
        load_time = time.perf_counter() - loading
        if backend == "failed":
            empty = Trajectory(t=np.zeros(0), y=np.zeros((0, system.n_state)),
                               mode=np.zeros((0, system.loads.n_switches), bool), status="failed", message=why,
                               failure="backend")
            return assemble_result(case, system, empty, 0.0, backend="compiled")
        start = time.perf_counter()  # loading (on a cold cache: compiling) the kernels is not the run's time
    if backend in KERNEL_BACKENDS:  # numba kernels entered once per run, or their source run by Python (csim.fast)
        trajectory = integrate_compiled(system, y0, settings, progress=progress, interpreted=backend == "interpreted")
        if progress is not None:
            progress(trajectory.t[-1] if trajectory.t.size else 0.0)
    else:
        from csim.solver.simulate import integrate  # scipy's integrators: imported only for this path

        trajectory = integrate(system, y0, settings, progress=progress)
    if why:
        trajectory.message += f" (on the Python path: {why})"
    result = assemble_result(case, system, trajectory, time.perf_counter() - start, backend=backend)
    if case.linkage is not None:  # drive forces, cut-joint reactions
        from csim.linkage.recording import linkage_outputs

        linkage_outputs(case, system, trajectory, result)
    record_integrity(case, system, result)
    result.kernel_load_time = load_time
    if backend != case.simulation.backend:  # why auto (or compiled) ran on another backend (run summary)
        from csim.fast.support import why_not_compiled

        result.backend_reason = why or why_not_compiled(case, backend)
    return result


def reselects_rows(case: Case) -> bool:
    """Whether a run of ``case`` chooses its independent constraint rows as it moves (see :func:`build_system`)."""
    return (case.linkage is not None and case.linkage.redundant and not case.kinematic
            and case.stabilization.method not in ("minimal", "augmented_lagrangian"))


def constraint_watch(case: Case, model: NumericModel, par: np.ndarray):
    """Every non-trivial constraint equation of the case's mechanism (:class:`ConstraintWatch`)
    at the parameter values ``par``: a linkage's removed ones too; a registered mechanism's are
    the model's own."""
    from csim.solver.integrity import ConstraintWatch

    if case.linkage is not None:  # at the run's parameter values (csim.linkage.plan.LightLinkage)
        return case.linkage.constraint_watch(case.mechanism.parameters, par)
    r = model.n_constraints
    return ConstraintWatch(phi=lambda q: model.phi(q, par), phi_q=lambda q: model.phi_q(q, par),
                           labels=[f"Phi_{i + 1}" for i in range(r)], kept=np.arange(r),
                           removed=np.zeros(0, dtype=int), rank=r)


def record_integrity(case: Case, system: ConstrainedSystem, result: Result) -> None:
    """Check the samples of a run for removed equations that came apart, singular crossings
    and branch changes (:mod:`csim.solver.integrity`); record them in ``result``, and fail a
    run whose motion is wrong although it reached its end."""
    from csim.solver.integrity import check_integrity

    if result.t.size == 0 or system.r == 0:
        return
    finite = np.all(np.isfinite(result.q), axis=1) & np.all(np.isfinite(result.qd), axis=1)
    n = int(np.argmin(finite)) if not finite.all() else finite.size  # the samples before a blow-up
    # the full set the run integrated (an overconstrained linkage's), else built here
    watch = getattr(system, "watch", None) or getattr(system.model, "watch", None) or \
        constraint_watch(case, system.model, system.par)
    if case.driven:  # the drive rows are constraints too: a dead centre is a singular crossing
        names = case.mechanism.coordinate_names
        watch = watch.with_drives(system.driven, [names[j] for j in system.driven], len(names))
    with np.errstate(all="ignore"):
        found = check_integrity(watch, result.t[:n], result.q[:n], result.qd[:n],
                                result.qdd[:n], case.mechanism.coordinate_names,
                                kept_fixed=not (reselects_rows(case)
                                                or case.stabilization.method == "augmented_lagrangian"))
    result.removed_names = found.removed_names
    result.removed_units = [watch.units[i] for i in watch.removed] if watch.units else []
    result.removed_phi = np.full((result.t.size, len(found.removed_names)), np.nan)
    result.removed_phi[:n] = found.removed_phi
    result.singular_times = found.singular_times
    result.warnings = found.warnings
    if found.failure is not None and result.status == "success":
        result.status, result.failure = "failed", found.failure[0]
        result.message = found.failure[1]
    elif found.failure is not None:  # failed later, for a reason of its own: say what went wrong first
        result.message += f"; before that, {found.failure[1]}"
    if result.failure == "drift" and result.phi.shape[1] and np.isfinite(result.phi[:n]).any():
        labels = watch.labels if result.phi.shape[1] == len(watch.labels) else [watch.labels[i] for i in watch.kept]
        worst = np.nanmax(np.abs(result.phi[:n]), axis=0)
        j = int(np.nanargmax(worst)) if worst.size else 0
        # name the equation that came apart, where the samples show it drifting (a step that
        # failed the check may lie past the last sample, whose residuals are then round-off)
        if len(labels) == worst.size and worst[j] >= 0.1 * case.simulation.max_phi:
            result.message += f"; the largest residual is {labels[j]}'s ({worst[j]:.3g})"


def _load_compiled(case: Case, system: ConstrainedSystem, y0: np.ndarray, settings) -> tuple[str, str]:
    """Load the compiled kernels: ``("compiled", "")``, or where they cannot be loaded (numba
    missing or broken, no writable cache) ``("python", why)`` under ``backend: auto`` and
    ``("failed", message)`` under ``backend: compiled``."""
    try:
        prepare_compiled(system, y0, settings)
        return "compiled", ""
    except Exception as exc:  # numba's errors have no common base class
        why = f"{type(exc).__name__}: {' '.join(str(exc).split())[:300]}"
        if case.simulation.backend == "compiled":
            return "failed", f"simulation.backend 'compiled': the compiled kernels could not be loaded ({why})"
        return "python", f"the compiled kernels could not be loaded, {why}"


def assemble_result(case: Case, system: ConstrainedSystem, traj: Trajectory, wall_time: float,
                    backend: str = "python") -> Result:
    """Evaluate every recorded quantity at the output times of a trajectory (``backend``: what integrated it)."""
    m = system.m
    arrays, failure, drive_forces = _sample_values(system, traj, backend, len(case.mechanism.observables))
    status, message, kind = traj.status, traj.message, traj.failure
    if failure is not None and status == "success":  # e.g. the last state of a failed run is singular
        status, message, kind = "failed", str(failure), failure.kind
    y = traj.y
    return Result(
        mechanism=case.mechanism.name,
        coordinate_names=case.mechanism.coordinate_names,
        load_names=[ld.name for ld in case.mechanism.loads],
        observable_names=[ob.name for ob in case.mechanism.observables],
        case_yaml=case.to_yaml(),
        t=traj.t, q=y[:, :m], qd=y[:, m:2 * m], work=y[:, 2 * m:],
        status=status, message=message, failure=kind, wall_time=wall_time,
        nfev=traj.nfev, njev=traj.njev, nlu=traj.nlu, nsteps=traj.nsteps,
        event_times=np.asarray(traj.event_times, dtype=float), event_labels=list(traj.event_labels),
        backend=backend,
        drive_forces=drive_forces,
        **arrays,
        **mechanism_units(case.mechanism, system.model, system.par),
    )


def _sample_values(system: ConstrainedSystem, traj: Trajectory, backend: str,
                   o: int) -> tuple[dict[str, np.ndarray], SimulationFailure | None, np.ndarray | None]:
    """Every recorded quantity at every sample, the first failure (None: every sample evaluated),
    and a compiled driven run's drive forces (N, d) (None: :func:`csim.solver.driven.record_drives`
    evaluates them).

    A compiled run's samples are evaluated in one compiled call, by the right-hand side that
    integrated them; a sample where that fails (and every sample of a Python run) by
    :meth:`ConstrainedSystem.evaluate`. A sample that cannot be evaluated (the last state of
    a blow-up) is NaN, but for its observables (geometry only).
    """
    N = traj.t.size
    columns = {"coordinate": (system.m,), "constraint": (system.r_recorded,), "load": (system.k,), "": ()}
    # the outputs one evaluation gives (csim.io.outputs), and the observables (geometry only)
    arrays = {name: np.full((N, *columns[out.columns]), np.nan) for name, out in EVALUATED.items()}
    arrays.update(observables=np.full((N, o), np.nan), observable_rates=np.full((N, o), np.nan))
    drive_forces = None
    if backend in KERNEL_BACKENDS and N:
        from csim.fast.runner import evaluate_compiled

        values = evaluate_compiled(system, traj.t, traj.y, traj.mode, interpreted=backend == "interpreted")
        for name, a in arrays.items():
            a[:] = values[name]
        todo = np.flatnonzero(~values["ok"])
        if values["drive_forces"].shape[1]:
            drive_forces = np.where(values["ok"][:, None], values["drive_forces"], np.nan)
    else:
        todo = range(N)
        model, par = system.model, system.par
        for i in range(N) if o else ():
            q, qd, _ = system.split(traj.y[i])
            arrays["observables"][i] = model.observables(q, par)
            arrays["observable_rates"][i] = model.observable_jacobian(q, par) @ qd
    failure = None
    for i in todo:
        try:
            with np.errstate(over="ignore", invalid="ignore"):  # the last state of a blow-up
                ev = system.evaluate(traj.t[i], traj.y[i], traj.mode[i])
        except SimulationFailure as exc:
            failure = failure or exc
            continue
        for name, out in EVALUATED.items():
            arrays[name][i] = getattr(ev, out.evaluation)
    return arrays, failure, drive_forces
