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
address is taken: ``integrate``, ``feval``, ``evaluate_samples``, ...; a function compiled
first as a callee stays so in that process, where Python may call it too) links in the IR of its
whole call tree, collected through those callees, as private copies, and optimizes and emits
it once: the machine code the kernels run, in the compiling process as in every later one,
is as before one module per entry point with its callees inlined where LLVM finds it pays
(:func:`_link_tree` says why the copies are private, and why it links until nothing of the
tree is left declared).

A callee's callers link in its module as it was before LLVM's module passes (:func:`_optimize_final_module`),
so that what an entry point runs does not depend on whether its callees got machine code of their
own: in a process that calls only entry points (:func:`entry_points_only`, the warm-up's jobs) they
get none, and no module passes either.

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

#: the globals through which numba calls a recursive function, which only the compiling process resolves
_UNRESOLVED = ".numba.unresolved$"
#: whether install() changed numba (False: not yet, or a numba whose methods differ from those it wraps), and
#: whether a csim callee gets machine code of its own (:func:`entry_points_only`)
_STATE = {"installed": False, "tried": False, "callee_code": True}
#: what numba's ``_finalize_final_module`` does before it adds the module to the JIT engine (a callee
#: without machine code of its own does only this)
_SCANS = ("_finalize_dynamic_globals", "_verify_declare_only_symbols")
#: how many numba:compile events are open in this thread (1: a function compiled from the outermost level)
_DEPTH = threading.local()


def install() -> bool:
    """Compile csim's functions as this module describes, from now on in this process (once); returns
    whether it does (not where numba's methods are not those this module wraps: numba then compiles as it does)."""
    if _STATE["tried"]:
        return _STATE["installed"]
    _STATE["tried"] = True
    from numba.core import caching, codegen, cpu, event

    if not _expected(cpu.CPUContext.get_executable, codegen.CPUCodeLibrary.finalize,
                     codegen.CPUCodeLibrary._optimize_final_module, codegen.CPUCodeLibrary._finalize_final_module,
                     caching.Cache.save_overload):
        return False
    event.register("numba:compile", _depth_listener())
    _wrap(cpu.CPUContext, "get_executable", _get_executable)
    _wrap(codegen.CPUCodeLibrary, "finalize", _finalize)
    _wrap(codegen.CPUCodeLibrary, "_optimize_final_module", _optimize_final_module)
    _wrap(codegen.CPUCodeLibrary, "_finalize_final_module", _finalize_final_module)
    _wrap(caching.Cache, "save_overload", _save_overload)
    _STATE["installed"] = True
    return True


def _expected(get_executable, finalize, optimize, finalize_module, save_overload) -> bool:
    """Whether numba's methods take the arguments the wrappers pass, ``finalize`` links
    ``self._linking_libraries`` and then calls ``self._optimize_final_module()``, and
    ``_finalize_final_module`` scans the module and then adds it to the JIT engine, as numba 0.68's do."""
    def parameters(fn):
        return list(inspect.signature(fn).parameters)
    try:
        source, module_source = inspect.getsource(finalize), inspect.getsource(finalize_module)
    except (OSError, TypeError):
        return False
    links, optimizes = source.find("in self._linking_libraries"), source.find("self._optimize_final_module()")
    scans = [module_source.find(f"self.{step}()") for step in _SCANS]
    adds = module_source.find("self._codegen._add_module(self._final_module)")
    return (parameters(get_executable) == ["self", "library", "fndesc", "env"] and parameters(finalize) == ["self"]
            and parameters(optimize) == ["self"] and parameters(finalize_module) == ["self"]
            and parameters(save_overload)[:2] == ["self", "sig"] and 0 <= links < optimizes
            and 0 <= scans[0] < scans[1] < adds)


def entry_points_only() -> None:
    """From now on in this process, a csim callee gets no machine code of its own: its callers link in
    its module (:func:`_optimize_final_module`), and Python calls only entry points (:mod:`csim.warmup`'s
    jobs), so that machine code would never run.

    On the 2-core machine (2026-11-27) emitting the callees' machine code took 4.4 s of the
    loop job's 36 s and 2.2 s of the right-hand side's 28 s, and their modules' optimization 3.1 s
    and 1.8 s. Calling such a callee from Python in this process raises a RuntimeError that says
    so, never a crash: the overload its dispatcher keeps for typing its callers runs a stub.
    A recursive function does not run in such a process either (numba resolves the recursive call
    to the callee's machine code, which it has not got: "unresolved symbol", a RuntimeError); the
    kernels have none, and a recursive tree is never cached anyway (:func:`_link_tree`): a later
    process compiles it on first use, as it would have (tests/test_linking.py).
    """
    if install():
        _stub_pointer()
        _STATE["callee_code"] = False


#: what a call from Python of a callee without machine code raises (:func:`entry_points_only`)
STUB_MESSAGE = ("csim compiled this function only into the entry points that call it, in this process "
                "(csim.fast.linking.entry_points_only): it has no machine code of its own to call from Python here")


def _stub_pointer() -> int:
    """The address of a CPython function ``(self, args, kwargs)`` that raises RuntimeError(:data:`STUB_MESSAGE`),
    the machine code of every callee without its own (:func:`entry_points_only`); built once per process, with
    this process's addresses of ``PyErr_SetString`` and ``RuntimeError`` in it (never cached)."""
    if "stub" not in _STATE:
        import ctypes

        from llvmlite import ir
        from numba.core.compiler_lock import global_compiler_lock
        from numba.core.registry import cpu_target

        library = cpu_target.target_context.codegen().create_library("csim_callee_stub")
        module = library.create_ir_module("csim_callee_stub")
        obj, address = ir.IntType(8).as_pointer(), ir.IntType(64)
        text = bytearray(STUB_MESSAGE.encode() + b"\0")
        message = ir.GlobalVariable(module, ir.ArrayType(ir.IntType(8), len(text)), "csim_callee_stub_message")
        message.global_constant, message.linkage = True, "internal"
        message.initializer = ir.Constant(message.type.pointee, text)
        stub = ir.Function(module, ir.FunctionType(obj, [obj, obj, obj]), "csim_callee_without_machine_code")
        builder = ir.IRBuilder(stub.append_basic_block())
        # PyErr_SetString(RuntimeError, message); return NULL
        set_string = builder.inttoptr(ir.Constant(address, ctypes.cast(ctypes.pythonapi.PyErr_SetString,
                                                                       ctypes.c_void_p).value),
                                      ir.FunctionType(ir.VoidType(), [obj, obj]).as_pointer())
        builder.call(set_string, [builder.inttoptr(ir.Constant(address, id(RuntimeError)), obj),
                                  builder.bitcast(message, obj)])
        builder.ret(ir.Constant(obj, None))
        with global_compiler_lock:
            library.add_ir_module(module)
            library.finalize()
        _STATE["stub"] = (library.get_pointer_to_function(stub.name), library)
    return _STATE["stub"][0]


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
            _DEPTH.n = max(getattr(_DEPTH, "n", 0) - 1, 0)
    return DepthListener()


def own_code_only(library) -> bool:
    """Whether ``library`` is a csim callee finalized (or to be finalized) with its own code only."""
    return getattr(library, "_csim_own_code", False)


def _get_executable(original, context, library, fndesc, env):
    """numba's ``CPUContext.get_executable`` (which finalizes ``library``), the library of a csim function
    compiled inside another compile marked to be finalized with its own code only (not a library numba's
    cache loaded: that one is finalized already, whole)."""
    if (getattr(_DEPTH, "n", 0) > 1 and fndesc.modname.startswith(_CSIM_MODULES)
            and not getattr(library, "_finalized", True)):
        library._csim_own_code = True
        if not _STATE["callee_code"]:  # (entry_points_only) finalized without machine code, a stub for Python
            from numba import _dynfunc

            library.finalize()
            return _dynfunc.make_function(fndesc.lookup_module(), fndesc.qualname.split(".")[-1],
                                          f"{fndesc.qualname!r}, compiled into its callers only", _stub_pointer(),
                                          env, (library, _STATE["stub"][1]))
    return original(context, library, fndesc, env)


def _finalize(original, library):
    """numba's ``CPUCodeLibrary.finalize``, which links ``_linking_libraries`` and then optimizes: a csim
    callee links only the libraries of other packages (its csim callees stay declarations); any other
    library is given its tree of csim callees, linked in by :func:`_optimize_final_module`."""
    own, other = [], []
    for linked in dict.fromkeys(library._linking_libraries):  # in order, once each
        (own if own_code_only(linked) else other).append(linked)
    library._linking_libraries = other
    if own_code_only(library):
        library._csim_callees = own
    elif own:
        library._csim_tree = _call_tree(own)
    return original(library)


def _optimize_final_module(original, library):
    """numba's ``CPUCodeLibrary._optimize_final_module`` (LLVM's module passes), after linking in the
    library's tree of csim callees (:func:`_link_tree`), where it has one.

    A csim callee's callers link in its module as it is *before* these passes (numba's: after), and
    optimize it once, inside theirs: the entry points' machine code is the same whether or not their
    callees get machine code of their own, which needs the passes, and where they do not
    (:func:`entry_points_only`) the passes are skipped (3.1 s of the loop job's 32 s, 1.8 s of the
    right-hand side's 25 s; the entry points' own passes took no longer).
    """
    tree = getattr(library, "_csim_tree", None)
    if tree:
        _link_tree(library, tree)
    if own_code_only(library):
        library._shared_module = _for_linking(library._final_module.clone())
        if not _STATE["callee_code"]:
            return None
    return original(library)


def _for_linking(module):
    """``module`` with its exported functions made ``linkonce_odr``, as numba's ``_get_module_for_linking``
    makes them (each caller may link in a copy; LLVM drops those it does not call)."""
    for fn in module.functions:
        if not fn.is_declaration and fn.linkage.name == "external":
            fn.linkage = "linkonce_odr"
    return module


def _finalize_final_module(original, library):
    """numba's ``CPUCodeLibrary._finalize_final_module``, which adds the module to the JIT engine (its
    machine code), except for a csim callee where :func:`entry_points_only` holds: only its checks."""
    if own_code_only(library) and not _STATE["callee_code"]:
        for step in _SCANS:
            getattr(library, step)()
        library._finalized = True
        return None
    return original(library)


def _link_tree(library, tree: list) -> None:
    """Link the modules of the csim callees ``tree`` into ``library``'s final module, until none of their
    functions is left declared there, and make the copies private.

    Again and again: LLVM links a ``linkonce_odr`` function (each callee's functions are, in
    the module numba gives for linking) only where the module already refers to it, so a
    callee linked before its first caller, or one whose only caller LLVM's function passes
    removed from a module linked earlier, is left out. Private: in the JIT engine each
    callee's own library defines the same names, and the engine binds a weak
    (``linkonce_odr``) symbol to the definition it already has, which would have this
    process run the callees' own code (their callees not inlined) instead of these copies.
    Not internal: LLVM's machine code loader files an internal function's symbol among the
    global ones, and a library loaded later (a core function from numba's cache, with its own
    weak copy of the same callee) was bound to this copy, whose arguments LLVM had changed
    (it may drop or specialize those of a function nothing outside the module calls): a
    crash. A private function has no symbol in the machine code at all.
    A name left declared (none is expected), or a recursive call (which numba resolves in the
    compiling process only, for any function), keeps the library out of numba's cache: in a
    later process nothing would define it.
    """
    module = library._final_module
    owner = {}  # the functions the tree defines -> the callee whose module defines them
    for callee in tree:
        for fn in callee._get_module_for_linking().functions:
            if not fn.is_declaration and fn.linkage.name not in ("private", "internal"):  # (local ones link along)
                owner.setdefault(fn.name, callee)
    pending, missing = tree, None
    while pending:
        for callee in pending:
            module.link_in(callee._get_module_for_linking(), preserve=True)
            library._reload_init.update(callee._reload_init)
        still = {fn.name for fn in module.functions if fn.is_declaration and fn.name in owner}
        if still == missing:  # linking their callees again defined nothing more
            library._csim_incomplete = True
            break
        missing, pending = still, list(dict.fromkeys(owner[name] for name in sorted(still)))
    for fn in module.functions:
        if not fn.is_declaration and fn.name in owner:
            fn.linkage = "private"
    if any(gv.name.startswith(_UNRESOLVED) for gv in module.global_variables):
        library._csim_incomplete = True  # recursion: numba resolves the call in this process only


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
    """numba's ``Cache.save_overload``, except for a csim callee finalized with its own code only (and for
    a library :func:`_link_tree` could not complete)."""
    if own_code_only(cres.library) or getattr(cres.library, "_csim_incomplete", False):
        return None
    return original(cache, sig, cres)
