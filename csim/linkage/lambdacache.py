"""Numeric functions of a linkage, their generated source kept on disk between runs.

The tree-joint reactions (:mod:`csim.linkage.reactions`) evaluate functions that sympy
derives from the linkage's symbolic transforms and force elements, then lambdifies: most of
a run's time after the integration for a mechanism with springs (4.7 s of the flyball
governor's 9 s). Their source depends only on the mechanism as written (not on its
parameter values, which are arguments) and on csim's linkage code, so it is filed in the
cache (``<cache>/linkage/<key>.py``) under a hash of both, and a later run of the same
mechanism reads it back instead of deriving it again.
"""
from __future__ import annotations

import contextlib
import hashlib
import inspect
import json
import os
from collections.abc import Callable
from pathlib import Path

from csim.io.atomic import write_atomically
from csim.model.cache import cache_dir

HERE = Path(__file__).resolve().parent

#: what a function was lambdified from: the argument lists and the expressions
Lambdified = tuple[list, object]


def linkage_key(mechanism: dict) -> str:
    """Hash of a ``mechanism`` section as written (parameters by name only) and csim's linkage sources."""
    import sympy

    shape = {k: v for k, v in mechanism.items() if k != "parameters"}
    shape["parameters"] = sorted(map(str, mechanism.get("parameters") or {}))
    parts = [json.dumps(shape, sort_keys=True, default=str), sympy.__version__,
             *(p.read_text() for p in sorted(HERE.glob("*.py")))]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


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
    import sympy as sp

    path = cache_dir() / "linkage" / f"{key}_{name}.py" if key else None
    if path is not None and path.is_file():
        namespace = dict(sp.lambdify([], 0, "numpy").__globals__)  # numpy's names, as lambdify's own
        try:
            exec(compile(path.read_text(), str(path), "exec"), namespace)
            return namespace["_lambdifygenerated"]
        except (SyntaxError, KeyError, ValueError):  # a damaged file: derived again below
            pass
    args, exprs = make()
    f = sp.lambdify(args, exprs, "numpy", cse=True)
    if path is not None:  # a cache that cannot be written costs the next run the derivation, nothing else
        with contextlib.suppress(OSError):
            write_atomically(path, inspect.getsource(f).encode())
    return f


def cache_enabled() -> bool:
    """Whether linkage functions are cached (``CSIM_LINKAGE_CACHE=0`` turns it off)."""
    return os.environ.get("CSIM_LINKAGE_CACHE", "1") not in ("0", "")
