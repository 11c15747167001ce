"""The on-disk cache of generated model code, and the keys it is filed under.

Nothing here imports sympy unless code has to be generated: a warm run of a registered
mechanism (:class:`csim.model.light.LightDefinition`) reads its key from a snapshot and
its functions from this cache.
"""
from __future__ import annotations

import contextlib
import hashlib
import marshal
import os
import sys
from pathlib import Path
from types import CodeType

from csim.io.atomic import write_atomically
from csim.model.definition import MechanismDefinition
from csim.model.light import LightDefinition

#: Generated functions: name -> (arguments, attribute of DerivedModel, kind of output).
#: kind "matrix" returns (rows, cols), "vector" returns (rows,), "scalar" a float,
#: "points" returns (rows/d, d), d = 2 or 3 (DerivedModel.point_dim). The argument ``t`` is
#: the time [s], a float (the symbol ``t`` of the load laws).
FUNCTIONS: dict[str, tuple[tuple[str, ...], str, str]] = {
    "mass": (("q", "par"), "mass", "matrix"),
    "velocity_terms": (("q", "qd", "par"), "velocity_terms", "vector"),
    "gravity": (("q", "par"), "gravity", "vector"),
    "phi": (("q", "par"), "phi", "vector"),
    "phi_q": (("q", "par"), "phi_q", "matrix"),
    "gamma": (("q", "qd", "par"), "gamma", "vector"),
    "load_coordinates": (("q", "par"), "load_coordinates", "vector"),
    "load_matrix": (("q", "par"), "load_matrix", "matrix"),
    "load_jacobian": (("q", "par"), "load_jacobian", "matrix"),
    "load_law": (("q", "qd", "t", "par"), "load_law", "vector"),
    "kinetic_energy": (("q", "qd", "par"), "kinetic_energy", "scalar"),
    "potential_energy": (("q", "par"), "potential_energy", "scalar"),
    "observables": (("q", "par"), "observables", "vector"),
    "observable_jacobian": (("q", "par"), "observable_jacobian", "matrix"),
    "points": (("q", "par"), "points", "points"),
}

#: Bump when the generated code changes shape, to invalidate old caches.
CODEGEN_VERSION = "4"


#: id(definition) -> (definition, its key): printing a large definition takes a fifth of a second
_KEYS: dict[int, tuple[MechanismDefinition, str]] = {}
#: the most keys remembered (a sweep builds a definition per run)
_MAX_KEYS = 64


def remember_key(definition: MechanismDefinition, key: str) -> None:
    """Let :func:`definition_key` of this very object return ``key`` (computed by it before, on
    an equal definition: a linkage read back from the cache carries its definition's key)."""
    if len(_KEYS) >= _MAX_KEYS:
        _KEYS.clear()
    _KEYS[id(definition)] = (definition, key)


def definition_key(definition: MechanismDefinition) -> str:
    """A hash of everything the generated code depends on (a light definition carries its own)."""
    if isinstance(definition, LightDefinition):
        return definition.key
    known = _KEYS.get(id(definition))
    if known is not None and known[0] is definition:
        return known[1]
    key = _definition_key(definition)
    remember_key(definition, key)
    return key


def _definition_key(definition: MechanismDefinition) -> str:
    """:func:`definition_key`, computed."""
    import sympy as sp

    parts = [
        CODEGEN_VERSION,
        definition.name,
        sp.srepr(definition.coordinates),
        sp.srepr(definition.velocities),
        sp.srepr(definition.parameter_symbols),
        sp.srepr(definition.kinetic_energy),
        sp.srepr(definition.potential_energy),
        sp.srepr(definition.constraints),
        sp.srepr([ld.coordinate for ld in definition.loads]),
        sp.srepr([ld.direction for ld in definition.loads]),
        sp.srepr([ld.law for ld in definition.loads]),
        sp.srepr([o.expression for o in definition.observables]),
        sp.srepr(list(definition.drawing.points.values()) if definition.drawing else []),
    ]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


def cache_dir() -> Path:
    """Where generated model sources are cached."""
    root = os.environ.get("CSIM_CACHE_DIR")
    return Path(root) if root else Path.home() / ".cache" / "csim"


def kernels_dir() -> Path:
    """Where the compiled kernels live (one copy per installation, filed under the hash of
    their sources and versions): ``$CSIM_KERNELS_DIR``, else ``fast/`` in :func:`cache_dir`.

    The test suite keeps its generated models in a private cache but uses the kernels that
    ``make install`` compiled here (tests/conftest.py), so no test session compiles them again.
    """
    root = os.environ.get("CSIM_KERNELS_DIR")
    return Path(root) if root else cache_dir() / "fast"


def source_path(definition: MechanismDefinition) -> Path:
    """The cached source of ``definition``'s numeric model (:func:`cached_source`)."""
    return cache_dir() / f"{definition.name}-{definition_key(definition)}.py"


def cached_source(definition: MechanismDefinition, use_cache: bool = True) -> str:
    """Generated source for ``definition``, derived anew only when not cached."""
    path = source_path(definition)
    if use_cache and path.is_file():
        return path.read_text()
    from csim.model.codegen import generate_source  # sympy: only to generate
    from csim.model.derive import derive
    from csim.progress import status

    with status(f"deriving the equations of motion of {definition.name!r} (sympy; first run of this mechanism)"):
        source = generate_source(derive(definition))
    if use_cache:
        with contextlib.suppress(OSError):  # a cache that cannot be written is not an error
            write_atomically(path, source.encode())
    return source


def cached_code(definition: MechanismDefinition, source: str, use_cache: bool = True) -> CodeType:
    """``compile(source)`` for ``definition``'s numeric model, its bytecode kept beside the
    cached source (the 81 links of A02 with N = 40: 0.75 s to compile, 4 ms to read back).

    The file is named after the source's hash and the interpreter (``sys.implementation.cache_tag``),
    so that a changed source or another Python never reads it; a damaged one is compiled again.
    """
    name = f"<csim model {definition.name}>"
    if not use_cache:
        return compile(source, name, "exec")
    digest = hashlib.sha256(source.encode()).hexdigest()[:24]
    path = source_path(definition).with_suffix(f".{digest}.{sys.implementation.cache_tag}.code")
    with contextlib.suppress(OSError, ValueError, EOFError, TypeError):
        code = marshal.loads(path.read_bytes())
        if isinstance(code, CodeType):
            return code
    code = compile(source, name, "exec")
    with contextlib.suppress(OSError):  # a cache that cannot be written costs the next run the compile
        write_atomically(path, marshal.dumps(code))
    return code
