"""The message of each failed run's status code (:mod:`csim.physics.status`), for both backends.

The Python driver raises :func:`failure` where a core function returns a code; the compiled
runner calls :func:`failure_message` with the code its loop returned, so a failure reads
the same on both. The messages name the likely cause (a stabilizer gain beyond the
integrator's stability region, a chattering switch, a lost assembly branch).
"""
from __future__ import annotations

from csim.physics.radau import (
    DAE_ALGEBRAIC,
    DAE_COLS,
    DAE_DIVERGED,
    DAE_H,
    DAE_NCOLS,
    DAE_NO_CONVERGENCE,
    DAE_NONFINITE_F,
    DAE_NONFINITE_INCREMENT,
    DAE_REASON,
    DAE_RESIDUAL0,
    DAE_SINGULAR_MATRIX,
    DAE_SINGULAR_REPEATED,
    DAE_SLOW,
    DAE_T,
    DAE_TOL,
    DAE_VALUE,
    DAE_ZERO_COLUMNS,
    NEWTON_MAXITER,
)
from csim.physics.status import (
    BRANCH_LEFT,
    BRANCH_LOST,
    CHATTER,
    DEPENDENT_NO_CONVERGENCE,
    DEPENDENT_NONFINITE,
    DEPENDENT_SINGULAR,
    ELIMINATION_FIXED_SINGULAR,
    ELIMINATION_NO_BLOCK,
    ELIMINATION_SINGULAR,
    GGL_SINGULAR_MASS,
    INTERRUPTED,
    MAX_EVENTS,
    MAX_PHI,
    MAX_STEPS,
    NO_BETTER_PARTITION,
    NO_SIGN_CHANGE,
    NONFINITE_RHS,
    NONFINITE_STATE,
    PROJ_NO_CONVERGENCE,
    PROJ_SINGULAR,
    RK4_RESOLUTION,
    SINGULAR_KKT,
    SINGULAR_MASS,
    STEP_COLLAPSE,
    STEP_TOO_SMALL,
    TANGENT_MASS_SINGULAR,
    code_kind,
)


def failure(code: int, a: float, b: float, settings, method=None, switches=(), detail=None, coordinates=()):
    """The :class:`csim.errors.SimulationFailure` of status ``code``: its message
    (:func:`failure_message`, same arguments) and its kind (:func:`code_kind`)."""
    from csim.errors import SimulationFailure

    return SimulationFailure(failure_message(code, a, b, settings, method, switches, detail, coordinates),
                             code_kind(code, detail))


def failure_message(code: int, a: float, b: float, settings, method=None, switches=(), detail=None,
                    coordinates=()) -> str:
    """What went wrong, for status ``code`` with details ``a``, ``b``.

    Parameters
    ----------
    code : int
        A status code of this module (not OK).
    a, b : float
        The details the code's comment above names.
    settings : csim.solver.settings.IntegrationSettings
        The run's settings (limits are quoted by their case-file keys).
    method : object, optional
        The stabilization method (the projection's messages quote its tolerance; a
        divergence names a gain times a fixed step beyond the integrator's stability region,
        :func:`csim.solver.stability.stability_cause`).
    switches : sequence of str, optional
        Labels of the switching functions involved (CHATTER names them).
    detail : ndarray, optional
        The failure details of a partitioned integration (:mod:`csim.physics.partition`),
        for the codes from DEPENDENT_NONFINITE on.
    coordinates : sequence of str, optional
        The coordinates' names (those codes name them).
    """
    s = settings
    if code in (NONFINITE_RHS, NONFINITE_STATE, MAX_PHI):
        return _divergence(code, a, b, s, method)
    if code == STEP_COLLAPSE:
        return (f"step-size collapse: an accepted step of {a:.3g} s at t = {b:.6g} s is below simulation.min_step "
                f"= {s.min_step:g} s (a singular configuration, or stiffness beyond this integrator)")
    if code == MAX_STEPS:
        return (f"more than simulation.max_steps = {s.max_steps} steps by t = {a:.6g} s: "
                f"the motion is too fast or too stiff for these settings (raise max_steps to go on)")
    if code == STEP_TOO_SMALL:
        why = TOO_SMALL_STEP if detail is None or not detail[DAE_REASON] else dae_step_message(detail)
        return f"integrator {s.integrator} failed at t = {a:.6g} s: {why}"
    if code == SINGULAR_KKT:
        return ("singular KKT matrix: the constraint Jacobian Phi_q lost rank (a singular "
                "configuration of the mechanism) or M is singular")
    if code == PROJ_SINGULAR:
        return (f"projection at t = {b:.6g} s: the constraint Jacobian has lost rank (a singular configuration, "
                f"or drives that ask for a motion the mechanism cannot make)")
    if code == PROJ_NO_CONVERGENCE:
        return (f"projection: Gauss-Newton did not reach max |Phi| <= {method.tol:g} in "
                f"{method.max_iter} iterations (max |Phi| = {a:.3e})")
    if code == MAX_EVENTS:
        return (f"more than simulation.max_events = {s.max_events} switching events "
                f"by t = {a:.6g} s: the load law chatters")
    if code == RK4_RESOLUTION:
        return f"integrator RK4 failed at t = {a:.6g} s: step {s.step:g} s is below the resolution of t = {a:g} s"
    if code == SINGULAR_MASS:
        text = (f"projection at t = {b:.6g} s: the mass matrix is singular (moving links without mass), so it "
                f"cannot be the projection's metric")
        owner = getattr(method, "metric_fixed_by", "")  # a method whose own projection this is (ggl)
        if owner:
            return f"{text}; {owner} projects in the mass metric and solves with M^-1: it needs mass on every " \
                   f"moving link"
        return f"{text}; set stabilization.projection_metric: minimum_norm"
    if code == NO_SIGN_CHANGE:
        return f"numerical error after t = {a:.6g} s: ValueError: f(a) and f(b) must have different signs"
    if code == CHATTER:
        return _chatter_message(a, b, settings, switches)
    if code == INTERRUPTED:  # as the Python driver words it
        return f"interrupted by the user after t = {a:.6g} s"
    if code == ELIMINATION_FIXED_SINGULAR:
        return ("the dependent block Phi_v of the constraint Jacobian is singular or nearly so: "
                "||Phi_q||_1 ||Phi_v^-1||_1 exceeds formulation.max_condition with the independent coordinates "
                "fixed by formulation.independent (left out, they are chosen again as the mechanism moves)")
    if code == ELIMINATION_NO_BLOCK:
        return ("no dependent block Phi_v has ||Phi_q||_1 ||Phi_v^-1||_1 within formulation.max_condition: the "
                "constraint Jacobian is singular or nearly so (a singular configuration), or "
                "formulation.max_condition is too small")
    if code == ELIMINATION_SINGULAR:
        return "singular system [R^T M; Phi_q] in the elimination formulation"
    if code == GGL_SINGULAR_MASS:
        return (f"ggl: the mass matrix is singular at t = {a:.6g} s (moving links without mass or inertia): ggl "
                f"solves M v' = p - Phi_q^T lambda, so it needs mass on every moving link")
    if code == TANGENT_MASS_SINGULAR:
        return ("minimal: R^T M R is singular: the mass matrix is singular on the constraints' tangent space "
                "(moving links without mass or inertia), so the motion is not determined by the forces")
    if DEPENDENT_NONFINITE <= code <= BRANCH_LOST:
        return _partition_message(code, detail, method, coordinates)
    return f"integration failed with status {code}"


#: scipy's message for a step below the spacing of the numbers at t
TOO_SMALL_STEP = "Required step size is less than spacing between numbers."


def non_finite_note(t: float) -> str:
    """What a failed implicit integrator's message adds where the right-hand side was non-finite at
    trial states (Newton iterates, Jacobian columns) it rejected, the last at time ``t`` [s]."""
    return f" (the right-hand side was non-finite at trial states, last at t = {t:.6g} s)"


def dae_step_message(detail) -> str:
    """Why Radau for DAEs stopped (:class:`csim.solver.dae.RadauDAE`'s message, and the compiled Radau's): its
    step fell below the smallest one after Newton failures (the last one's reason) or error-test failures, or
    the iteration matrix is singular for every step. ``detail``: the layout of :mod:`csim.physics.radau`
    (DAE_REASON ...)."""
    reason, t, h = int(detail[DAE_REASON]), detail[DAE_T], detail[DAE_H]
    if reason == DAE_ZERO_COLUMNS:
        columns = [int(c) for c in detail[DAE_COLS:DAE_COLS + int(detail[DAE_NCOLS])]]
        return (f"Newton iteration did not converge at t = {t:.9g}; singular iteration matrix: dF/dy is zero in the "
                f"columns {columns} of algebraic variables (they do not enter F)")
    if reason == DAE_SINGULAR_REPEATED:
        return (f"Newton iteration did not converge at t = {t:.9g}; singular iteration matrix "
                f"({int(detail[DAE_VALUE])} times in this step).")
    newton = {DAE_NONFINITE_F: "non-finite right-hand side",
              DAE_NONFINITE_INCREMENT: "non-finite Newton increment",
              DAE_DIVERGED: "iteration diverged", DAE_SLOW: "slow convergence",
              DAE_NO_CONVERGENCE: f"no convergence in {NEWTON_MAXITER} iterations",
              DAE_SINGULAR_MATRIX: "singular iteration matrix",
              DAE_ALGEBRAIC: f"algebraic residual {detail[DAE_VALUE]:.3g} above its tolerance {detail[DAE_TOL]:.3g} "
                             f"after {NEWTON_MAXITER} iterations"}.get(reason)
    if newton is None:  # the error test cut the step down (DAE_ERROR_TEST)
        message = TOO_SMALL_STEP
    else:
        message = (f"Newton iteration did not converge at t = {t:.9g}; {newton} (step size {h:.3g} is less than "
                   f"spacing between numbers).")
    residual = detail[DAE_RESIDUAL0]
    if residual == residual:  # failing on the first step: suspect the initial state
        message += (" Is the initial state consistent (the algebraic equations and the hidden constraints)? "
                    f"max |F_alg(t0, y0)| = {residual:.3g}.")
    return message


def _chatter_message(t: float, span: float, settings, switches) -> str:
    """CHATTER's message: what chatters, when, what it means and what to do."""
    s = settings
    what = "; ".join(switches) or "a switching function"
    # sliding (Filippov) state: both modes drive the switching function back to zero
    return (f"chattering load law: {what} switched back and forth {s.chatter_events} times within "
            f"{span:.3g} s at t = {t:.6g} s (simulation.chatter_events = {s.chatter_events} events closer "
            f"together, on average, than simulation.min_step = {s.min_step:g} s). The law has no consistent "
            f"mode at this instant: with its condition holding the motion makes it fail, and without, hold "
            f"again. Both sides drive into the switching surface, a sliding (Filippov) state with no "
            f"classical solution (e.g. a drive too weak to carry the mechanism through a velocity-switched "
            f"force: it stalls), which event location cannot step through. Change the load law or its "
            f"magnitude, or run the fixed-step RK4 with simulation.events: false, which averages over the "
            f"switching (to O(h))")


def _divergence(code: int, a: float, b: float, settings, method) -> str:
    """A blow-up or torn-apart joints, and the likely cause: a stabilizer gain times a fixed
    step beyond the integrator's stability region, else drift."""
    from csim.solver.stability import stability_cause

    unstable = stability_cause(method, settings)
    if code == NONFINITE_RHS:
        text = f"blow-up: non-finite right-hand side at t = {a:.6g} s (max |y| = {b:.3g})"
    elif code == NONFINITE_STATE:
        text = f"blow-up: non-finite state at t = {a:.6g} s"
    else:
        from csim.solver.integrators import INTEGRATORS

        info = INTEGRATORS.get(getattr(settings, "integrator", ""))
        remedy = "tighten the tolerances" if info is None or info.adaptive else "lower simulation.step"
        if getattr(method, "projects", False):  # checked on the step's end, before it is projected
            return (f"constraint violation: max |Phi| = {a:.3g} at t = {b:.6g} s, at the end of a step before its "
                    f"projection, exceeds simulation.max_phi = {settings.max_phi:g}: the integrator drifts that "
                    f"far in one step, and projecting back from there may reach another assembly; {remedy} "
                    f"(the recorded samples are projected, so their max |Phi| is smaller)")
        text = (f"constraint violation: max |Phi| = {a:.3g} at t = {b:.6g} s exceeds simulation.max_phi = "
                f"{settings.max_phi:g}; the joints have drifted apart")
        if unstable is None:
            return text + f" (stabilize, or {remedy})"
    if unstable is None:
        return text
    return f"{text}: {unstable}, so the stabilizer drives the constraint error up (lower simulation.step)"


def _partition_message(code: int, detail, method, names) -> str:
    """The message of a failed solve of the dependent coordinates, or of a run that could not go on after one."""
    from csim.physics.partition import D_CODE, D_COORD, D_HEAD, D_PHI, D_PRED, D_SOLVED

    if code == NO_BETTER_PARTITION:
        return (f"{_partition_message(int(detail[D_CODE]), detail, method, names)} (no better coordinate partition "
                f"exists at the last accepted state)")
    if code == BRANCH_LOST:
        from csim.physics.partition import MAX_BRANCH_RESTARTS

        return (f"{_partition_message(BRANCH_LEFT, detail, method, names)} (again after {MAX_BRANCH_RESTARTS} "
                f"restarts from the last accepted state, and no better coordinate partition exists there)")
    n = (detail.size - D_HEAD) // 2
    u = ", ".join(f"{names[int(i)]} = {v:.6g}" for v, i in zip(detail[D_HEAD:D_HEAD + n], detail[D_HEAD + n:]))
    if code == DEPENDENT_NONFINITE:
        return f"blow-up: non-finite constraint residual at the independent coordinates {u}"
    if code == DEPENDENT_SINGULAR:
        return f"minimal: the dependent block Phi_v is singular at the independent coordinates {u}"
    if code == DEPENDENT_NO_CONVERGENCE:
        return (f"minimal: Newton-Raphson for the dependent coordinates did not reach max |Phi| <= {method.tol:g} in "
                f"{method.max_iter} iterations (max |Phi| = {detail[D_PHI]:.3e}); the mechanism cannot be assembled "
                f"at the independent coordinates {u}")
    lands = branch_test_text(detail)
    return (f"minimal: the assembly branch changes between the last accepted state and the independent coordinates "
            f"{u}, even in the shortest pieces of the way: Newton's solution for the dependent coordinates lands "
            f"{lands} ({names[int(detail[D_COORD])]}: {detail[D_PRED]:.6g} predicted, {detail[D_SOLVED]:.6g} solved)")


def branch_test_text(detail) -> str:
    """Which branch test a solution failed, with its numbers (csim.physics.partition.same_branch's details)."""
    from csim.physics.partition import BRANCH_JUMP, D_BOUND, D_TEST, D_VALUE

    value, bound = detail[D_VALUE], detail[D_BOUND]
    if detail[D_TEST] == BRANCH_JUMP:
        return f"{value:.3g} from the branch's prediction (at most {bound:.3g} on the branch)"
    return f"with its slope dv/du changed by {value:.3g} (at most {bound:.3g} on the branch)"
