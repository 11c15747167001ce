"""``kernel``: compile a core function with numba on first use, else leave it as Python.

The functions of :mod:`csim.physics` are called both from Python (the reference driver)
and from inside compiled loops. Compiled, the Python driver calls the machine code (a
dispatcher call costs about a microsecond); without numba the same source runs as plain
Python, slower but identical in what it computes. ``CSIM_PURE_PYTHON=1`` forces the
latter (for debugging, and to test that the core never depends on numba).

numba is imported on the first call of a core function, or when the compiled kernels load
(:func:`activate`), never at import: a command that only reads a case (``csim describe``,
``csim schema``, ``csim plot``, the validation) does not pay its 0.3 s. Until then a core
function is a :class:`LazyKernel`, which numba types as the dispatcher it becomes.

Nor does numba make a dispatcher of each of them before it compiles something: a warm run
loads the kernels' entry points from numba's cache, whose machine code holds everything they
call, and making the hundred-odd dispatchers of the core and of the kernels took about 10 ms
of its 0.47 s (2026-11-27: the kernels' import 22 ms, 13 ms without them). The first compile in
a process binds them all (:func:`_bind_dispatchers`), before numba types anything. (A
``numba.cfunc`` compiles without that event: a cfunc compiled first types the LazyKernels it
calls as their dispatchers, and the first of those to compile binds.)
"""
from __future__ import annotations

import contextlib
import functools
import os

#: no function here allocates, so none needs numba's reference counting of arrays (NRT): without
#: it a call costs no atomic operations per array argument or slice (half of an evaluation's time)
NJIT_OPTIONS = dict(cache=True, error_model="numpy", _nrt=False)

#: numba's njit once imported (None: not yet, or pure Python), whether the import was tried, and whether the
#: LazyKernels bound in csim's modules were replaced by their dispatchers (at the first compile)
_NUMBA = {"njit": None, "tried": False, "bound": False}
#: the :func:`jitable` functions, registered with numba when it loads
_JITABLES: list = []
#: how many :func:`plain` blocks are open
_PLAIN = {"depth": 0}
#: the :func:`inline_kernel` functions (their LazyKernels), and for each numba:compile event open whether
#: it is an :func:`inlining_root`'s (:func:`_switch_inlining`)
_INLINING = {"kernels": [], "open": [], "on": False}


def pure_python() -> bool:
    """Whether ``CSIM_PURE_PYTHON`` rules numba out in this process."""
    return os.environ.get("CSIM_PURE_PYTHON", "") not in ("", "0")


def activate():
    """Import numba (once) and make the core compilable; returns its njit, or None for pure Python."""
    if _NUMBA["tried"]:
        return _NUMBA["njit"]
    _NUMBA["tried"] = True
    if pure_python():
        return None
    try:
        from numba import njit
        from numba.core.typing.typeof import typeof
        from numba.extending import typeof_impl
    except Exception:  # numba missing or broken: the Python driver still runs
        return None

    @typeof_impl.register(LazyKernel)
    def _typeof_lazy(value, context):  # a compiled caller sees the dispatcher
        return typeof(value.compiled(), context.purpose)

    _NUMBA["njit"] = njit
    for fn in _JITABLES:
        _register_jitable(fn)
    _bind_at_first_compile()
    _switch_inlining()
    return njit


def _bind_at_first_compile():
    """Have the first compile of this process (numba's ``numba:compile`` event, which numba broadcasts
    before it types a function, and never for a function it loads from its cache) bind the dispatchers."""
    from numba.core import event

    class BindListener(event.Listener):
        def on_start(self, ev):
            if not _NUMBA["bound"]:
                _bind_dispatchers()

        def on_end(self, ev):
            pass
    event.register("numba:compile", BindListener())


def _bind_dispatchers():
    """Replace every LazyKernel bound in a loaded csim module by its dispatcher: numba inlines an
    ``inline_kernel`` (and resolves a call statically) only where the global it sees is a dispatcher.
    From then on a new core function is its dispatcher at once (:func:`_lazy`)."""
    import sys

    _NUMBA["bound"] = True
    for name, module in list(sys.modules.items()):
        if not name.startswith("csim") or module is None:
            continue
        for key, value in list(vars(module).items()):
            if isinstance(value, LazyKernel):
                setattr(module, key, value.compiled())


def _switch_inlining():
    """Have every compile (numba's numba:compile event, which it broadcasts before it types a function,
    and again when done) switch the :func:`inline_kernel` functions' inlining in numba's IR on where
    the function compiled is an :func:`inlining_root` or is compiled inside one's compile (a callee it
    types), off for any other, and back when it ends. (Listed after the binding's listener: the
    dispatchers exist when it switches them.)"""
    from numba.core import event

    class InliningListener(event.Listener):
        def on_start(self, ev):
            py_func = getattr(ev.data.get("dispatcher"), "py_func", None)
            inside = bool(_INLINING["open"]) and _INLINING["open"][-1]
            _INLINING["open"].append(inside or getattr(py_func, "_csim_inlining_root", False))
            _set_inlining(_INLINING["open"][-1])

        def on_end(self, ev):
            if _INLINING["open"]:  # (none where the listener came in during a compile under way)
                _INLINING["open"].pop()
            _set_inlining(bool(_INLINING["open"]) and _INLINING["open"][-1])
    event.register("numba:compile", InliningListener())


def _set_inlining(on: bool) -> None:
    """Whether numba inlines the :func:`inline_kernel` functions in its IR into the callers it compiles
    from now on (its ``inline`` option, which it reads from the callee's dispatcher at each call site)."""
    _INLINING["on"] = on
    for lazy in _INLINING["kernels"]:
        if lazy._compiled is not None and hasattr(lazy._compiled, "targetoptions"):
            lazy._compiled.targetoptions["inline"] = "always" if on else "never"


def inlining_root(fn):
    """Decorator: numba inlines the :func:`inline_kernel` functions in its IR into ``fn`` and into the
    functions compiled as ``fn``'s callees, where sizes passed as constants fix their loops (the
    right-hand side: :func:`inline_kernel`). Returns ``fn`` marked, for the decorator that compiles it."""
    fn._csim_inlining_root = True
    return fn


def compiled() -> bool:
    """Whether the core functions are compiled in this process (imports numba)."""
    return activate() is not None


class LazyKernel:
    """A core function, compiled by numba (njit with ``options``) on its first call; the plain function without numba.

    Attributes
    ----------
    py_func : function
        The Python function numba compiles.
    python : function
        What runs where it is not compiled: ``py_func``, or a twin that makes Python's scalars
        compute as the compiled code does (:func:`inline_kernel`'s ``python``).
    """

    def __init__(self, fn, options: dict, python=None):
        functools.update_wrapper(self, fn)
        self.py_func, self._options, self._compiled = fn, options, None
        self.python = python or fn

    def compiled(self):
        """The numba dispatcher (or the plain function where numba does not load)."""
        if self._compiled is None:
            njit = activate()
            options = dict(self._options)
            if options.get("inline") == "switched":  # an inline_kernel: as the compile under way has it
                options["inline"] = "always" if _INLINING["on"] else "never"
            self._compiled = self.python if njit is None else njit(**options)(self.py_func)
        return self._compiled

    def __call__(self, *args):
        if self._compiled is None and _PLAIN["depth"]:
            return self.python(*args)
        return (self._compiled or self.compiled())(*args)


@contextlib.contextmanager
def plain():
    """Within the block, a core function not yet compiled in this process runs as plain Python.

    For one-off work on the Python side (the consistent initial state: a few Newton
    iterations), which takes microseconds in Python, while loading each function it calls
    from numba's cache takes about 0.2 s (1.8 s of a warm run's 2.2 s before). Functions
    already compiled keep their machine code.
    """
    _PLAIN["depth"] += 1
    try:
        yield
    finally:
        _PLAIN["depth"] -= 1


def kernel(fn):
    """Decorator: ``fn`` compiled by numba (njit, cached on disk, numpy's error model) on first use, or plain."""
    return _lazy(fn, NJIT_OPTIONS)


def _lazy(fn, options, python=None):
    """A LazyKernel, or the dispatcher itself once the dispatchers are bound (:func:`_bind_dispatchers`)."""
    lazy = LazyKernel(fn, options, python)
    if options.get("inline") == "switched":  # an inline_kernel (_set_inlining)
        _INLINING["kernels"].append(lazy)
    return lazy.compiled() if _NUMBA["bound"] else lazy


def inline_always(fn):
    """:func:`kernel`, and inlined in numba's IR into every compiled caller: for the small functions
    that pass many arrays on (a call passes each as a struct of seven words, which costs more than
    their body), cheap to inline."""
    return _lazy(fn, dict(inline="always", **NJIT_OPTIONS))


def inline_kernel(fn=None, *, python=None):
    """:func:`kernel`, and inlined in numba's IR into an :func:`inlining_root`'s compile (the right-hand
    side), so that the sizes it passes as constants fix its loop lengths (the KKT solve of a right-hand
    side: about 0.6x the time of a call). Elsewhere (the loop, the Python path's calls) a call, which
    LLVM inlines where it pays: without the IR inlining there the loop compiled 4-5 s faster on the
    2-core machine, and the compiled rows took 0-2 % longer (alternated, 2026-11-27).

    ``python`` (``@inline_kernel(python=twin)``): what runs in its place where it is not compiled,
    for the rare operation whose Python scalars compute otherwise than compiled code (numpy's
    complex division, :func:`csim.physics.linalg.quotient`)."""
    if fn is None:
        return lambda f: inline_kernel(f, python=python)
    return _lazy(fn, dict(inline="switched", **NJIT_OPTIONS), python)


def jitable(fn=None, *, inline: bool = False):
    """Decorator for a core function that evaluates the model (:mod:`csim.physics.model`): ``fn`` itself
    to a Python caller, compiled into the compiled callers that call it.

    The Python driver passes a Python model object (the functions of :mod:`csim.physics.model`
    call its methods); the compiled kernels pass their tuple (model functions called through
    their addresses, :mod:`csim.fast.kernels`), for which the kernels overload those functions.
    The function is compiled as part of each compiled caller (numba's ``register_jitable``), so
    it is cached with the caller, never on its own. It must not allocate.

    ``inline=True`` (``@jitable(inline=True)``) inlines it in numba's IR into its compiled
    callers: a call of a numba function passes every array argument as a struct of seven
    words, which for a function of twenty arrays called once per step (the projection) costs
    more than its body's small loops (without it the projection's RK4 row took 3 % longer,
    2026-11-27). Only for functions with one or two compiled callers.
    """
    if fn is None:
        return lambda f: jitable(f, inline=inline)
    fn._csim_inline = inline
    _JITABLES.append(fn)
    if _NUMBA["njit"] is not None:
        _register_jitable(fn)
    return fn


def _register_jitable(fn):
    from numba.extending import register_jitable

    inline = "always" if getattr(fn, "_csim_inline", False) else "never"
    register_jitable(error_model="numpy", _nrt=False, inline=inline)(fn)
