"""Loading the kernels' machine code from numba's cache without loading every registry of numba's target.

Before it looks in its on-disk cache, numba refreshes the CPU target
(``Cache.load_overload`` calls ``target_context.refresh()``): it imports and installs the
implementations of everything numba can compile (numpy's linear algebra, which imports
``scipy.linalg`` for its BLAS check, random generators, typed containers, jitclasses, cffi,
...). That is 0.3-0.4 s of every warm run (alternated on the 2-core machine, 2026-11-27: a warm
quick-return run 1.4-1.6 s with this module, 1.7-2.1 s without), spent on code that nothing
loaded from the cache uses: a cached function is machine code that needs
only numba's runtime (NRT: the allocator that ``integrate`` and the samples' evaluation
call), whose symbols :func:`numba.core.runtime.rtsys.initialize` registers. A cache miss
compiles, and numba's compiler refreshes the target itself (``CompilerBase.__init__``), so
nothing is ever compiled without its registries.

:func:`install` replaces ``Cache.load_overload`` by :func:`_load_overload`, which does that:
the runtime, then numba's own lookup. It checks that numba's method is still the one it
replaces (numba 0.60 to 0.68: the refresh, then ``_load_overload`` under the guard against
spurious I/O errors), and leaves numba as it is otherwise.
"""
from __future__ import annotations

import ast
import inspect
import textwrap

#: whether install() replaced numba's method (False: numba's own, e.g. a numba whose method differs)
_STATE = {"installed": False, "tried": False}

#: numba's load_overload, the statements this replacement is equivalent to (ast.unparse of its body, less the docstring)
_EXPECTED = ("target_context.refresh()",
             "with self._guard_against_spurious_io_errors():\n    return self._load_overload(sig, target_context)")


def install() -> bool:
    """Load cached machine code without refreshing numba's target (once per process); returns whether it does."""
    if _STATE["tried"]:
        return _STATE["installed"]
    _STATE["tried"] = True
    from numba.core import caching

    if _statements(caching.Cache.load_overload) != _EXPECTED:  # another numba: keep its method
        return False
    caching.Cache.load_overload = _load_overload
    _STATE["installed"] = True
    return True


def _statements(fn) -> tuple[str, ...] | None:
    """The statements of a function's body, less its docstring, as ast.unparse writes them (None: no source)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    except (OSError, TypeError, SyntaxError):
        return None
    body = tree.body[0].body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    return tuple(ast.unparse(statement) for statement in body)


def _load_overload(self, sig, target_context):
    """numba's ``Cache.load_overload`` with only the runtime initialised instead of the whole target refreshed."""
    from numba.core.runtime import rtsys

    rtsys.initialize(target_context)
    with self._guard_against_spurious_io_errors():
        return self._load_overload(sig, target_context)
