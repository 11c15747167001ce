"""Compiled backend: numba model functions and integration loops, entered once per run.

``simulation.backend`` in a case file selects it (see :mod:`csim.fast.support`). Modules:

``support``  which cases it runs (no numba import)
``codegen``  njit model functions generated from the symbolic derivation
``ccodegen``  the same model functions as C, for ``cc``
``kernels``  the loop, steppers and event location, compiled (a copy in the cache) or interpreted
``module``   generated module: cache on disk, load
``cache_load``  numba's cache lookup without refreshing its whole target (warm runs)
``linking``  each entry point's call tree optimized and emitted once (cold compiles)
``runner``   pack a system into arrays, call the loop, build the Trajectory
"""
from csim.fast.support import BACKENDS, KERNEL_BACKENDS, resolve_backend, unsupported

__all__ = ["BACKENDS", "KERNEL_BACKENDS", "integrate_compiled", "prepare_compiled", "resolve_backend", "unsupported"]


def integrate_compiled(system, y0, settings, progress=None, interpreted: bool = False):
    """:func:`csim.solver.simulate.integrate` in compiled code (imports numba on first use), or with
    ``interpreted`` the same source run by Python; ``progress(t)`` gets the time reached while it runs."""
    from csim.fast.runner import integrate_compiled as run

    return run(system, y0, settings, progress=progress, interpreted=interpreted)


def prepare_compiled(system, y0, settings):
    """Load (on a cold cache: compile) the kernels of ``system`` without integrating."""
    from csim.fast.runner import prepare

    prepare(system, y0, settings)
