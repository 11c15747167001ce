"""Which cases the compiled backend runs (``simulation.backend``), without importing numba.

``simulation.backend``:

``auto`` (default)
    compiled when the combination is supported (below) and numba is installed, the Python
    path otherwise: an explicit fallback, chosen per case, never a silent difference in
    results (both paths give the same results to round-off). A supported combination where
    numba is not installed, or ``CSIM_PURE_PYTHON=1`` rules it out, runs interpreted.
``compiled``
    the compiled kernels; an unsupported combination is rejected by the case validation
    with the key and the reason. Under ``CSIM_PURE_PYTHON=1``, interpreted.
``interpreted``
    the compiled kernels' own source run by Python (:mod:`csim.fast.kernels.interpreted`): the
    same loop, steps and model functions as ``compiled``, without numba; for debugging the
    compiled path (a breakpoint anywhere in the loop) and for checking it. About as fast as
    ``python``, a few hundred times slower than ``compiled``. Supports what ``compiled`` does.
``python``
    the reference Python path (:func:`csim.solver.simulate.integrate`: scipy's integrators,
    and every formulation and method), for debugging.

Supported: ``formulation.method`` ``kkt`` and ``elimination`` (not with ``minimal``); every
``stabilization.method`` whose class says ``compiled = True`` (:mod:`csim.solver.methods`);
``simulation.integrator`` DOP853, RK45, Tsit5, Vern7, RK4 or Radau (each scipy's, or csim's Python
class's, step for step, :mod:`csim.fast.kernels`; on ``ggl``'s DAE the algorithm of
:class:`csim.solver.dae.RadauDAE`, whose steps it takes to a few in a thousand, since its decisions
there read increments at the round-off of the multipliers); events on or off; drives
(``mechanism.drive_mode: dynamic``) with every such method.
"""
from __future__ import annotations

import importlib.util

from csim.solver.methods import STABILIZERS

BACKENDS = ("auto", "python", "compiled", "interpreted")
#: the backends that run the kernels (compiled, or their source run by Python)
KERNEL_BACKENDS = ("compiled", "interpreted")

#: what the compiled backend implements
FORMULATIONS = ("kkt", "elimination")
INTEGRATORS = ("DOP853", "RK45", "Tsit5", "Vern7", "RK4", "Radau")


def compiled_stabilizers() -> list[str]:
    """The registered methods the compiled kernels run."""
    return [name for name, cls in STABILIZERS.items() if cls.compiled]


def unsupported(case) -> list[str]:
    """Why the compiled backend cannot run a (validated) case (:class:`csim.case.Case`): [] when it can.

    Each entry names the key, the value and the reason.
    """
    reasons = []
    formulation = case.formulation.method
    method = case.stabilization.method
    if formulation not in FORMULATIONS:
        reasons.append(f"formulation.method {formulation!r}: the compiled backend implements "
                       f"{', '.join(FORMULATIONS)}")
    elif formulation == "elimination" and method == "minimal":
        reasons.append("formulation.method 'elimination' and stabilization.method 'minimal' together: the "
                       "partitioned system keeps its own partition where the compiled elimination keeps its; the "
                       "KKT formulation gives minimal the same motion, compiled")
    if method not in compiled_stabilizers():
        reasons.append(f"stabilization.method {method!r}: not implemented in compiled code; "
                       f"the compiled backend supports {', '.join(compiled_stabilizers())}")
    if case.linkage is not None and case.linkage.redundant and method not in ("minimal",):
        # (minimal does not take a dynamic drive: csim.solver.driven.driven_problems)
        alternative = "" if case.driven else "; the compiled backend runs such a mechanism with 'minimal'"
        reasons.append(f"stabilization.method {method!r} on an overconstrained linkage: its independent constraint "
                       f"equations are chosen again as it moves, on the Python path (csim.solver.redundant)"
                       f"{alternative}")
    integrator = case.simulation.integrator
    if integrator not in INTEGRATORS:
        reasons.append(f"simulation.integrator {integrator!r}: the compiled backend implements "
                       f"{', '.join(INTEGRATORS)} ({integrator} runs on the Python path only)")
    return reasons


def numba_available() -> bool:
    return importlib.util.find_spec("numba") is not None


def numba_usable() -> bool:
    """Whether numba may be used here: installed, and not ruled out by ``CSIM_PURE_PYTHON=1``."""
    from csim.physics.jit import pure_python

    return not pure_python() and numba_available()


def resolve_backend(case) -> str:
    """``"compiled"``, ``"interpreted"`` or ``"python"``: the backend that runs a validated case
    (:class:`csim.case.Case`)."""
    backend = case.simulation.backend
    if backend in ("python", "interpreted"):
        return backend
    if backend == "auto" and unsupported(case):
        return "python"
    return "compiled" if numba_usable() else "interpreted"


def why_not_compiled(case, backend: str) -> str:
    """Why a case resolved to ``backend`` under ``simulation.backend`` auto or compiled ("" when it asked for
    that backend, or it is compiled)."""
    from csim.physics.jit import pure_python

    if backend == "compiled" or case.simulation.backend == backend:
        return ""
    if backend == "python":
        return "; ".join(unsupported(case))
    return "CSIM_PURE_PYTHON=1 rules numba out" if pure_python() else "numba is not installed"
