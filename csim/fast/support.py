"""Which cases the compiled backend runs (``simulation.backend``), without importing numba.

``simulation.backend``:

``auto`` (default)
    compiled when the combination is supported (below) and numba is installed, the Python
    path otherwise: an explicit fallback, chosen per case, never a silent difference in
    results (both paths give the same results to round-off).
``compiled``
    the compiled kernels; an unsupported combination is rejected by the case validation
    with the key and the reason.
``python``
    the reference Python path (:func:`csim.solver.simulate.integrate`), for debugging.

Supported: ``formulation.method: kkt``; every ``stabilization.method`` whose class says
``compiled = True`` (:mod:`csim.solver.methods`); ``simulation.integrator`` DOP853 or RK4;
events on or off.
"""
from __future__ import annotations

import importlib.util

from csim.solver.methods import STABILIZERS

BACKENDS = ("auto", "python", "compiled")

#: what the compiled backend implements
FORMULATIONS = ("kkt",)
INTEGRATORS = ("DOP853", "RK4")


def compiled_stabilizers() -> list[str]:
    """The registered methods the compiled kernels run."""
    return [name for name, cls in STABILIZERS.items() if cls.compiled]


def unsupported(data: dict) -> list[str]:
    """Why the compiled backend cannot run a (validated) case: [] when it can.

    Each entry names the key, the value and the reason.
    """
    reasons = []
    formulation = data.get("formulation", {}).get("method")
    if formulation is not None and formulation not in FORMULATIONS:
        reasons.append(f"formulation.method {formulation!r}: the compiled backend implements the KKT formulation "
                       f"only (the elimination gives the same motion in exact arithmetic); use 'kkt'")
    method = data.get("stabilization", {}).get("method")
    if method is not None and method not in compiled_stabilizers():
        why = {"ggl": "GGL is an index-2 DAE solved by the Python Radau IIA for DAEs"}
        reasons.append(f"stabilization.method {method!r}: {why.get(method, 'not implemented in compiled code')}; "
                       f"the compiled backend supports {', '.join(compiled_stabilizers())}")
    if data.get("mechanism", {}).get("drive_mode") == "dynamic":
        reasons.append("mechanism.drive_mode 'dynamic': the drives are constraints that depend on time, which the "
                       "compiled kernels do not evaluate (csim.solver.driven runs on the Python path)")
    integrator = data.get("simulation", {}).get("integrator")
    if integrator is not None and integrator not in INTEGRATORS:
        reasons.append(f"simulation.integrator {integrator!r}: the compiled backend implements "
                       f"{' and '.join(INTEGRATORS)} (scipy's {integrator} runs on the Python path)")
    return reasons


def numba_available() -> bool:
    return importlib.util.find_spec("numba") is not None


def resolve_backend(data: dict) -> str:
    """``"compiled"`` or ``"python"``: the backend that runs a validated case."""
    backend = data.get("simulation", {}).get("backend", "auto")
    if backend == "python":
        return "python"
    if backend == "compiled":
        return "compiled"
    return "compiled" if not unsupported(data) and numba_available() else "python"
