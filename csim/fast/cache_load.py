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

It also keeps a cached library's bitcode unparsed until something links it. numba caches a
function as its machine code and, for linking it into a later caller, the LLVM bitcode of
its module (for an entry point of the kernels: its whole call tree, :mod:`csim.fast.linking`),
and on every load it parses that bitcode only to read the names the module defines (38 ms
of the 0.6 s of a warm quick-return run, 2026-11-27). For the functions of the kernels' copy,
:func:`_serialize` files those names with the bitcode (:class:`SharedBitcode`, still bytes to
numba's own loader); :func:`_unserialize` registers them and keeps the bitcode, which
:func:`_module_for_linking` parses on the first link (none in a warm run: nothing calls the
entry points from compiled code). Only for the kernels' copy, whose cache is keyed by a hash
of this file among others (:func:`csim.fast.module.kernels_key`): any other function numba
caches in a csim process (the core's, beside its sources; a user's own) is filed in numba's
own format, which loads in a process without csim and after any edit of this file.
"""
from __future__ import annotations

import ast
import inspect
import re
import textwrap

#: whether install() replaced numba's method (False: numba's own, e.g. a numba whose method differs), whether
#: it was tried, and whether it deferred the bitcode too (False: numba's methods differ from those expected)
_STATE = {"installed": False, "tried": False, "deferred": False}
#: the module-name prefix of the kernels' copy (csim.fast.module), the libraries whose bitcode is deferred
KERNELS_PREFIX = "csim_fast_kernels_"
#: a function of the kernels' copy in numba's mangled names: _ZN<length><module>...
_OF_KERNELS = re.compile(rf"_ZN\d+{KERNELS_PREFIX}")

#: numba's load_overload, the statements this replacement is equivalent to (ast.unparse of its body, less the docstring)
_EXPECTED = ("target_context.refresh()",
             "with self._guard_against_spurious_io_errors():\n    return self._load_overload(sig, target_context)")
#: the statements of numba's methods that the bitcode's deferral relies on (numba 0.60 to 0.68): those of
#: ``_unserialize`` (its object branch is the one :func:`_unserialize` restates), how
#: ``serialize_using_object_code`` makes the bitcode, and the first two of ``_get_module_for_linking`` (a
#: module parsed already is the one it returns)
_EXPECTED_UNSERIALIZE = (
    "name, kind, data = state", "self = codegen.create_library(name)", "assert isinstance(self, cls)",
    "if kind == 'bitcode':\n    self._final_module = ll.parse_bitcode(data)\n    self._finalize_final_module()\n"
    "    return self\nelif kind == 'object':\n    object_code, shared_bitcode = data\n"
    "    self.enable_object_caching()\n    self._set_compiled_object(object_code)\n"
    "    self._shared_module = ll.parse_bitcode(shared_bitcode)\n    self._finalize_final_module()\n"
    "    self._codegen._engine._load_defined_symbols(self._shared_module)\n    return self\n"
    "else:\n    raise ValueError('unsupported serialization kind %r' % (kind,))")
_EXPECTED_SERIALIZE = ("self._ensure_finalized()",
                       "data = (self._get_compiled_object(), self._get_module_for_linking().as_bitcode())",
                       "return (self.name, 'object', data)")
_EXPECTED_LINKING = ("self._ensure_finalized()", "if self._shared_module is not None:\n    return self._shared_module")
_EXPECTED_SYMBOLS = ("for gsets in (mod.functions, mod.global_variables):\n"
                     "    self._defined_symbols |= {gv.name for gv in gsets if not gv.is_declaration}",)


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
    _STATE["deferred"] = _defer_bitcode()
    return True


def _defer_bitcode() -> bool:
    """Install :func:`_serialize`, :func:`_unserialize` and :func:`_module_for_linking` where numba's
    methods are those they stand in for; returns whether it did."""
    from numba.core import codegen

    library = codegen.CPUCodeLibrary
    unserialize, serialize = library._unserialize.__func__, library.serialize_using_object_code
    for_linking = library._get_module_for_linking
    if (any(hasattr(method, "__wrapped__") for method in (unserialize, serialize, for_linking))  # wrapped already
            or _statements(unserialize) != _EXPECTED_UNSERIALIZE or _statements(serialize) != _EXPECTED_SERIALIZE
            or (_statements(for_linking) or ())[:2] != _EXPECTED_LINKING
            or _statements(codegen.JitEngine._load_defined_symbols) != _EXPECTED_SYMBOLS):
        return False
    from csim.fast.linking import _wrap

    def wrapper(cls, codegen, state):
        return _unserialize(unserialize, cls, codegen, state)
    wrapper.__name__, wrapper.__doc__, wrapper.__wrapped__ = "_unserialize", _unserialize.__doc__, unserialize
    library._unserialize = classmethod(wrapper)
    _wrap(library, "serialize_using_object_code", _serialize)
    _wrap(library, "_get_module_for_linking", _module_for_linking)
    return True


def _statements(fn) -> tuple[str, ...] | None:
    """The statements of a function's body, less its docstring, as ast.unparse writes them (None: no source)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(fn)))
    except (OSError, TypeError, SyntaxError):
        return None
    if not tree.body or not isinstance(tree.body[0], ast.FunctionDef | ast.AsyncFunctionDef):
        return None  # (a lambda, say)
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


class SharedBitcode(bytes):
    """A cached library's bitcode for linking (numba's bytes), with the names of what its module defines.

    Parameters
    ----------
    data : bytes
        The bitcode numba filed (``CPUCodeLibrary._get_module_for_linking().as_bitcode()``).
    symbols : iterable of str
        The functions and global variables the module defines (not those it only declares): what
        numba's ``JitEngine._load_defined_symbols`` reads from it when it loads the library.
    """

    def __new__(cls, data: bytes, symbols=()):
        shared = super().__new__(cls, data)
        shared.symbols = frozenset(symbols)
        return shared

    def __reduce__(self):
        return SharedBitcode, (bytes(self), sorted(self.symbols))


def _serialize(original, library):
    """numba's ``serialize_using_object_code``; for a function of the kernels' copy, the bitcode filed with
    the names its module defines."""
    state = original(library)
    name, kind, (object_code, bitcode) = state
    module = library._get_module_for_linking()  # the module that bitcode was written from
    if not _of_kernels(module):
        return state
    symbols = [gv.name for gvs in (module.functions, module.global_variables) for gv in gvs if not gv.is_declaration]
    return name, kind, (object_code, SharedBitcode(bitcode, symbols))


def _of_kernels(module) -> bool:
    """Whether a library's module for linking is that of a function of the kernels' copy: the function it
    exports (numba's for linking: ``linkonce_odr``, not private) is named for the copy's module."""
    return any(_OF_KERNELS.match(fn.name) for fn in module.functions
               if not fn.is_declaration and fn.linkage.name == "linkonce_odr")


def _unserialize(original, cls, codegen, state):
    """numba's ``CPUCodeLibrary._unserialize``, except that a library whose bitcode came with its names
    (:class:`SharedBitcode`) registers those names and keeps the bitcode for :func:`_module_for_linking`."""
    name, kind, data = state
    if kind != "object" or not isinstance(data[1], SharedBitcode):
        return original(cls, codegen, state)
    object_code, shared = data
    library = codegen.create_library(name)
    assert isinstance(library, cls)
    library.enable_object_caching()
    library._set_compiled_object(object_code)
    library._csim_bitcode = shared
    library._finalize_final_module()
    library._codegen._engine._defined_symbols |= shared.symbols  # what _load_defined_symbols would read
    return library


def _module_for_linking(original, library):
    """numba's ``_get_module_for_linking``, the deferred bitcode parsed first where there is one."""
    bitcode = library.__dict__.get("_csim_bitcode")
    if bitcode is not None and library._shared_module is None:
        import llvmlite.binding as ll

        library._shared_module = ll.parse_bitcode(bitcode)
        del library._csim_bitcode
    return original(library)
