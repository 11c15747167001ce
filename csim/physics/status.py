"""Status codes of a run and the kind of failure each is, for both backends.

The core functions return these codes (0 is success) with up to two numbers of detail,
``a`` and ``b``; :func:`csim.solver.failures.failure_message` turns a code into the text a
user reads. The Python driver raises :class:`csim.errors.SimulationFailure` with it; the
compiled loop returns the code and the runner calls the same function, so a failure reads
the same on both. Codes and kinds only here (the core imports nothing above it).
"""
from __future__ import annotations

OK = 0
NONFINITE_RHS = 1  # a: t, b: max |y|
NONFINITE_STATE = 2  # a: t
MAX_PHI = 3  # a: max |Phi|, b: t
STEP_COLLAPSE = 4  # a: h, b: t
MAX_STEPS = 5  # a: t
STEP_TOO_SMALL = 6  # a: t (scipy: "Required step size is less than spacing between numbers.")
SINGULAR_KKT = 7  # a: t
PROJ_SINGULAR = 8  # a: max |Phi|, b: t
PROJ_NO_CONVERGENCE = 9  # a: max |Phi|, b: t
MAX_EVENTS = 10  # a: t
RK4_RESOLUTION = 11  # a: t
SINGULAR_MASS = 12  # b: t
NO_SIGN_CHANGE = 13  # a: t
CHATTER = 14  # a: t, b: span of the last simulation.chatter_events events [s] (csim.physics.events)
# minimal coordinates (csim.physics.branch): the details are the partition's (csim.physics.partition, D_*)
DEPENDENT_NONFINITE = 15  # non-finite Phi or q in the Newton solve of the dependent coordinates
DEPENDENT_SINGULAR = 16  # Phi_v singular (a breakdown: choose the partition again)
DEPENDENT_NO_CONVERGENCE = 17  # Newton for v did not converge (a breakdown)
BRANCH_LEFT = 18  # Newton's solution left the assembly branch (a breakdown)
NO_BETTER_PARTITION = 19  # a breakdown other than BRANCH_LEFT, and no better partition at the accepted state
BRANCH_LOST = 20  # BRANCH_LEFT again after MAX_BRANCH_RESTARTS restarts from the same accepted state
INTERRUPTED = 21  # a: t (Ctrl-C: the compiled loop saw the caller's request)
# the elimination formulation (csim.physics.elimination)
ELIMINATION_FIXED_SINGULAR = 22  # Phi_v of formulation.independent above formulation.max_condition
ELIMINATION_NO_BLOCK = 23  # no dependent block within formulation.max_condition, after choosing again
ELIMINATION_SINGULAR = 24  # [R^T M; Phi_q] singular
TANGENT_MASS_SINGULAR = 25  # minimal: R^T M R singular (M singular on the constraints' tangent space)
GGL_SINGULAR_MASS = 26  # a: t (ggl solves M v' = p - Phi_q^T lambda)


#: the kind of failure each code is (:data:`csim.result.FAILURES`): what HDF5's ``failure``
#: attribute, the sweep tables and ``csim batch`` call it
KINDS = {
    NONFINITE_RHS: "blow-up", NONFINITE_STATE: "blow-up", MAX_PHI: "drift",
    STEP_COLLAPSE: "step collapse", MAX_STEPS: "max steps", STEP_TOO_SMALL: "step collapse",
    SINGULAR_KKT: "singular", PROJ_SINGULAR: "singular", PROJ_NO_CONVERGENCE: "projection",
    MAX_EVENTS: "chatter", RK4_RESOLUTION: "step", SINGULAR_MASS: "singular",
    NO_SIGN_CHANGE: "event location", CHATTER: "chatter",
    DEPENDENT_NONFINITE: "blow-up", DEPENDENT_SINGULAR: "singular", DEPENDENT_NO_CONVERGENCE: "newton",
    BRANCH_LEFT: "branch", NO_BETTER_PARTITION: "branch", BRANCH_LOST: "branch", INTERRUPTED: "interrupted",
    ELIMINATION_FIXED_SINGULAR: "singular", ELIMINATION_NO_BLOCK: "singular", ELIMINATION_SINGULAR: "singular",
    TANGENT_MASS_SINGULAR: "singular", GGL_SINGULAR_MASS: "singular",
}


def code_kind(code: int, detail=None) -> str:
    """The kind of failure of status ``code`` (:data:`KINDS`); NO_BETTER_PARTITION is the kind of
    the breakdown it could not get past (``detail``: the partition's failure details)."""
    if code == NO_BETTER_PARTITION and detail is not None:
        from csim.physics.partition import D_CODE

        inner = int(detail[D_CODE])
        if inner != NO_BETTER_PARTITION and inner in KINDS:
            return KINDS[inner]
    return KINDS.get(code, "other")
