"""Compiling the kernels with one optimization of each entry point's call tree, not one per function.

numba compiles every function it types into a library of its own and finalizes it at once
(``CPUCodeLibrary.finalize``): it links in the LLVM IR of every callee, whose own library
already holds the callee's callees, optimizes the whole (O3) and emits its machine code. A
function deep in the kernels is so optimized and emitted once for itself and again inside
each of its callers, their callers, and so on up to the entry point: the kernels' call tree
is deep (``integrate`` -> ``_take_step`` -> ``_explicit_step`` -> ``_rk_stages`` -> ...), and
this repetition was 125 of the 200 s of the partitioned copy's cold compile on the 2-core
machine (2026-11-27: LLVM's module optimization 69 s and machine code 55 s, in 196 finalizations).

Where :func:`install` has run, a csim function compiled *inside the compile of another one*
(a callee: numba types it because its caller calls it) is finalized with its own code only.
Its callees stay declarations in its module, which its machine code calls through their
symbols (the JIT engine resolves them: each callee was finalized, and so emitted, before it).
A function compiled at the outermost level (an entry point that Python calls or whose
address is taken: ``integrate``, ``feval``, ``evaluate_samples``, ...) links in the IR of its
whole call tree, collected through those callees, and optimizes and emits it once: the
machine code the kernels run is, as before, one module per entry point with its callees
inlined where LLVM finds it pays.

A callee finalized so is not written to numba's cache: its machine code needs its callees'
symbols, which a later process that loads it alone would not have. A later process that needs
it compiles it again (only when an entry point compiles: a warm run loads the entry points,
whose machine code holds their call trees). Functions of other packages (numba's own
implementations: ``np.empty``, string formatting) are linked as numba links them.
"""
from __future__ import annotations

import inspect
import threading

#: where a library's function comes from for the rule: a csim module, or a compiled copy of the kernels
_CSIM_MODULES = ("csim.", "csim_fast_kernels")

#: whether install() changed numba (False: not yet, or a numba whose methods differ from those it wraps)
_STATE = {"installed": False, "tried": False}
#: how many numba:compile events are open in this thread (1: a function compiled from the outermost level)
_DEPTH = threading.local()


def install() -> bool:
    """Compile csim's functions as this module describes, from now on in this process (once); returns
    whether it does (not where numba's methods are not those this module wraps: numba then compiles as it does)."""
    if _STATE["tried"]:
        return _STATE["installed"]
    _STATE["tried"] = True
    from numba.core import caching, codegen, cpu, event

    if not _expected(cpu.CPUContext.get_executable, codegen.CPUCodeLibrary.finalize, caching.Cache.save_overload):
        return False
    event.register("numba:compile", _depth_listener())
    _wrap(cpu.CPUContext, "get_executable", _get_executable)
    _wrap(codegen.CPUCodeLibrary, "finalize", _finalize)
    _wrap(caching.Cache, "save_overload", _save_overload)
    _STATE["installed"] = True
    return True


def _expected(get_executable, finalize, save_overload) -> bool:
    """Whether numba's methods take the arguments the wrappers pass, and ``finalize`` links
    ``self._linking_libraries`` and then optimizes, as numba 0.68's does."""
    def parameters(fn):
        return list(inspect.signature(fn).parameters)
    try:
        source = inspect.getsource(finalize)
    except (OSError, TypeError):
        return False
    return (parameters(get_executable) == ["self", "library", "fndesc", "env"]
            and parameters(finalize) == ["self"] and parameters(save_overload)[:2] == ["self", "sig"]
            and "in self._linking_libraries" in source and "self._optimize_final_module()" in source)


def _wrap(cls, name, replacement):
    original = getattr(cls, name)

    def method(self, *args):
        return replacement(original, self, *args)
    method.__name__, method.__doc__, method.__wrapped__ = name, replacement.__doc__, original
    setattr(cls, name, method)


def _depth_listener():
    from numba.core.event import Listener

    class DepthListener(Listener):
        """Counts the numba:compile events open in the current thread."""

        def on_start(self, event):
            _DEPTH.n = getattr(_DEPTH, "n", 0) + 1

        def on_end(self, event):
            _DEPTH.n -= 1
    return DepthListener()


def own_code_only(library) -> bool:
    """Whether ``library`` was (or is to be) finalized with its own code only: a csim callee."""
    return getattr(library, "_csim_own_code", False)


def _get_executable(original, context, library, fndesc, env):
    """numba's ``CPUContext.get_executable`` (which finalizes ``library``), the library of a csim function
    compiled inside another compile marked to be finalized with its own code only."""
    if getattr(_DEPTH, "n", 0) > 1 and fndesc.modname.startswith(_CSIM_MODULES):
        library._csim_own_code = True
    return original(context, library, fndesc, env)


def _finalize(original, library):
    """numba's ``CPUCodeLibrary.finalize``: a csim callee links only the libraries of other packages (its csim
    callees stay declarations); any other library links every csim callee of its call tree too."""
    own, other = [], []
    for linked in dict.fromkeys(library._linking_libraries):  # in order, once each
        (own if own_code_only(linked) else other).append(linked)
    if own_code_only(library):
        library._csim_callees = own
        library._linking_libraries = other
    elif own:
        library._linking_libraries = other + _call_tree(own)
    return original(library)


def _call_tree(callees: list) -> list:
    """The csim callees' libraries and, through them, their own csim callees', each once, depth first."""
    seen, stack = {}, list(reversed(callees))
    while stack:
        library = stack.pop()
        if library in seen:
            continue
        seen[library] = None
        stack.extend(reversed(getattr(library, "_csim_callees", ())))
    return list(seen)


def _save_overload(original, cache, sig, cres):
    """numba's ``Cache.save_overload``, except for a csim callee finalized with its own code only."""
    if own_code_only(cres.library):
        return None
    return original(cache, sig, cres)
