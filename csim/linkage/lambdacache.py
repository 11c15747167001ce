"""A linkage's symbolic model and numeric functions, kept on disk between runs.

The tree-joint reactions (:mod:`csim.linkage.reactions`) evaluate functions that sympy
derives from the linkage's symbolic transforms and force elements, then lambdifies: most of
a run's time after the integration for a mechanism with springs (4.7 s of the flyball
governor's 9 s). Their source depends only on the mechanism as written (not on its
parameter values, which are arguments) and on csim's linkage code, so it is filed in the
cache (``<cache>/linkage/<key>.py``) under a hash of both, and a later run of the same
mechanism reads it back instead of deriving it again.

The linkage itself (:class:`csim.linkage.model.Linkage`: the tables, the spanning tree, the
symbolic transforms, the kept and removed closure equations, the mechanism's definition) is
built from the case's ``mechanism`` and ``initial`` sections (the assembly that chooses the
independent equations runs at the parameter values and start given there) by seconds of
sympy work: :func:`cached_build` files it, pickled, under a hash of both sections as
written, the build's options and every csim source file, and a later validation of the same
case reads it back (2.7 s -> 0.1 s for Bricard's mechanism). Only a build that succeeded is
filed, and the newest :data:`MAX_LINKAGES` are kept. The cache is the user's own folder, as
numba's is; a damaged file is built again.
"""
from __future__ import annotations

import contextlib
import hashlib
import importlib.metadata
import inspect
import json
import os
import pickle
import sys
from collections.abc import Callable
from pathlib import Path

from csim.io.atomic import write_atomically
from csim.model.cache import cache_dir

HERE = Path(__file__).resolve().parent

#: what a function was lambdified from: the argument lists and the expressions
Lambdified = tuple[list, object]


def _sympy_version() -> str:
    """sympy's version, from its package's metadata: importing sympy to read it costs 0.2 s."""
    return importlib.metadata.version("sympy")


def linkage_key(mechanism: dict) -> str:
    """Hash of a ``mechanism`` section as written (parameters by name only) and csim's linkage sources."""
    shape = {k: v for k, v in mechanism.items() if k != "parameters"}
    shape["parameters"] = sorted(map(str, mechanism.get("parameters") or {}))
    parts = [json.dumps(shape, sort_keys=True, default=str), _sympy_version(),
             *(p.read_text() for p in sorted(HERE.glob("*.py")))]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


def build_key(mechanism: dict, initial: dict | None, options: dict) -> str:
    """Hash of what :func:`csim.linkage.model.build_linkage` reads: the sections as written (in
    their order: the order of drives and rows is part of the model), its options, sympy's
    version and csim's sources."""
    sources = sorted(HERE.parent.rglob("*.py"))
    parts = [json.dumps([mechanism, initial, options], default=repr), _sympy_version(),
             *(hashlib.sha256(p.read_bytes()).hexdigest() for p in sources)]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


def cached_build(key: str, build: Callable[[], object]):
    """``build()``, or the linkage a build with the same :func:`build_key` filed in the cache
    (see the module docstring; ``key`` "": not cached)."""
    if not key:
        return build()
    path = cache_dir() / "linkage" / f"{key}_linkage.pickle"
    if path.is_file():
        with contextlib.suppress(Exception):  # a damaged or foreign file: built again below
            return pickle.loads(path.read_bytes())
    linkage = build()
    with contextlib.suppress(Exception):  # a cache that cannot be written costs the next run the build
        write_atomically(path, pickle.dumps(linkage, protocol=pickle.HIGHEST_PROTOCOL))
        evict(path.parent, "*_linkage.pickle", MAX_LINKAGES)
    return linkage


#: the most linkages kept in the cache (a sweep over a parameter files one per value): the
#: least recently written go first
MAX_LINKAGES = 200


def evict(folder: Path, pattern: str, keep: int) -> None:
    """Remove all but the ``keep`` newest files of ``folder`` matching ``pattern``."""
    files = sorted(folder.glob(pattern), key=lambda p: p.stat().st_mtime)
    for old in files[:max(len(files) - keep, 0)]:
        with contextlib.suppress(OSError):  # another process removed it first
            old.unlink()


def cached_lambdify(key: str | None, name: str, make: Callable[[], Lambdified]) -> Callable:
    """``sympy.lambdify(*make(), "numpy", cse=True)``, its source read from the cache when there.

    Parameters
    ----------
    key : str or None
        :func:`linkage_key` of the mechanism (None: no cache, always derived).
    name : str
        What the function is, within the mechanism (``"kinematics"``, ``"elements_3"``).
    make : callable () -> (args, exprs)
        The symbolic work, done only when the source is not cached.
    """
    path = cache_dir() / "linkage" / f"{key}_{name}.py" if key else None
    if path is not None and path.is_file():
        with contextlib.suppress(SyntaxError, KeyError, ValueError):  # a damaged file: derived again below
            code = compile(path.read_text(), str(path), "exec")
            namespace = _numpy_namespace()
            if _resolves(code, namespace):  # (a name it needs that is not numpy's: derived again below)
                exec(code, namespace)
                return namespace["_lambdifygenerated"]
    import sympy as sp

    args, exprs = make()
    f = sp.lambdify(args, exprs, "numpy", cse=True)
    if path is not None:  # a cache that cannot be written costs the next run the derivation, nothing else
        with contextlib.suppress(OSError):
            write_atomically(path, inspect.getsource(f).encode())
    return f


def _numpy_namespace() -> dict:
    """The names sympy's ``lambdify(..., "numpy")`` gives its functions (its ``MODULES["numpy"]``: ``import
    numpy; from numpy import *; from numpy.linalg import *``, ``I`` and ``Heaviside``), made without
    importing sympy, and without the submodules numpy loads on first use that no process has loaded yet
    (``numpy.testing``, ``numpy.f2py``, ``numpy.random``, ...: the star import loaded them, 45 ms of a
    warm link-coupling run; a generated function reads none of them, and one that did would fail
    :func:`_resolves` and be derived again)."""
    import numpy
    import numpy.linalg

    lazy = getattr(numpy, "__numpy_submodules__", set())
    namespace: dict = {"numpy": numpy}
    for name in numpy.__all__:
        if name not in lazy or f"numpy.{name}" in sys.modules:
            namespace[name] = getattr(numpy, name)
    namespace.update((name, getattr(numpy.linalg, name)) for name in numpy.linalg.__all__)
    namespace.update(I=1j, Heaviside=namespace["heaviside"])
    return namespace


def _resolves(code, namespace: dict) -> bool:
    """Whether every name the module ``code`` and the functions in it read (``co_names``: globals, and
    attributes, which a generated function reads of numpy only) is in ``namespace`` or a builtin."""
    import builtins

    needed, stack = set(), [code]
    while stack:
        c = stack.pop()
        needed.update(c.co_names)
        stack.extend(k for k in c.co_consts if hasattr(k, "co_names"))
    return all(n in namespace or hasattr(builtins, n) for n in needed - {"_lambdifygenerated"})


def cache_enabled() -> bool:
    """Whether linkage functions are cached (``CSIM_LINKAGE_CACHE=0`` turns it off)."""
    return os.environ.get("CSIM_LINKAGE_CACHE", "1") not in ("0", "")
