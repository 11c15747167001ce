"""The kernels: the integration loop and the steppers DOP853, RK4, RK45, Tsit5, Vern7 and Radau
with event location, over the shared core; compiled by numba, or run by Python.

One package for every mechanism, compiled once per installation: :mod:`csim.fast.module`
loads it through a copy named by the hash of everything it depends on, so that numba's
on-disk cache is never stale (one copy for every method, the source's files unchanged, see
:mod:`.variant`), and numba compiles it on first use, then loads the machine code from its
cache in every later process. The package's own source, imported as
``csim.fast.kernels``, is never compiled: it is the interpreted backend, the same loop run by
Python (:mod:`.interpreted`; ``simulation.backend: interpreted``, and what ``CSIM_PURE_PYTHON=1``
runs), so that both backends take the same steps from one source. Nothing about a mechanism
is a compile-time constant here: the sizes, the workspace offsets and the addresses of the
mechanism's model functions are entries of ``pi`` (:mod:`csim.fast.layout`), and the model
functions (C compiled by ``cc``, :mod:`csim.fast.ccodegen`, or numba cfuncs,
:mod:`csim.fast.codegen`) are called through their addresses (:mod:`.calls`). A new mechanism
costs only its own model functions.

The physics is not here: the KKT solve, gamma* of each method, the switching functions,
the load laws, the projection, the step checks, the minimal-coordinate method's solves on
the assembly branch and its partition (:mod:`csim.physics.branch`) and the status codes are
the functions of :mod:`csim.physics` and of the method files (:mod:`csim.solver.methods`),
the same ones the Python driver calls. What is here is what must be compiled, one concept a
file, from the bottom up:

================  ===========================================================================
``variant``       whether this package is compiled (``COMPILED``): the cache's copy, not the source
``common``        the decorators, the integrators' codes, the loop's scalar slots
``tableaus``      the explicit pairs' coefficients (scipy's DOP853, :mod:`csim.physics.tableaus`)
``addresses``     compiled-only: calls by address (model, gamma*, ``feval``, elimination); the model handle
``interpreted``   the same calls from Python, for the interpreted package
``calls``         the model functions and gamma* by name, over one of the two
``system``        the right-hand side at a state, the projection, the partitioned system, GGL's DAE
``control``       step-size control: scipy's first step, the error estimators' orders
``dense``         each stepper's dense output and its evaluation
``explicit``      DOP853 and the pairs RK45, Tsit5, Vern7 (scipy's ``RungeKutta`` step)
``rk4``           the fixed-step RK4 (:class:`csim.solver.rk4.RK4`), Hermite dense output
``radau``         Radau IIA (scipy's ``Radau``, the difference Jacobian of ``num_jac``; on GGL's DAE RadauDAE's)
``events``        switching functions' zeros on the dense output (``brentq``), event records
``driver``        the loop: segments, steps, checks, events, samples, restarts (:func:`integrate`)
``entries``       the samples' recorded quantities, and one-state entries for tests and benchmark
================  ===========================================================================

The problem is passed as three flat arrays, ``par`` (the parameters), ``pf`` and ``pi``
(:func:`csim.fast.runner.pack_problem`), because numba counts a reference to every array
argument at every call of a function it does not inline: few arguments keep the
evaluation as fast as plain C. ``pi`` starts with a header (:mod:`csim.fast.layout`: the
method's code and settings' offsets, the sizes, the function addresses, the workspace
offsets), then the switching functions' loads and kinds (:mod:`csim.physics.loads`) and
the method's integer settings; ``pf`` holds the load magnitudes, the switching bounds, the
method's float settings and its gains (:meth:`csim.solver.methods.base.Method.pack`). The
workspace w holds the model terms, then the scratch of the right-hand side and of the
projection; matrices are flat and row-major, and the core functions get 1-D slices of w
(a slice costs nothing, a 2-D view a reshape).

The files import each other relatively: a copy in the cache is a package of its own.
"""
from .driver import integrate
from .entries import evaluate_samples, project_entry, rhs_entry, rhs_repeat
from .system import eliminated, feval
from .variant import COMPILED

if COMPILED:
    from .addresses import ELIMINATED_TYPES, FEVAL_TYPES
else:
    FEVAL_TYPES = ELIMINATED_TYPES = None  # the interpreted package calls them from Python

__all__ = ["COMPILED", "ELIMINATED_TYPES", "FEVAL_TYPES", "eliminated", "evaluate_samples", "feval", "integrate",
           "project_entry", "rhs_entry", "rhs_repeat"]
