"""Build, cache and load the compiled module of one mechanism.

The module is one Python file: the imports of :mod:`csim.fast.kernels` (the core functions
of :mod:`csim.physics`), the model functions generated from the symbolic derivation
(:mod:`csim.fast.codegen`), the dispatch ``method_gamma_star`` over the registered
stabilization methods that have a compiled path (:func:`method_dispatch_source`), and the
rest of the kernels' text. It is written to ``<cache>/fast/<mechanism>_<key>.py``, where
``<cache>`` is csim's model cache (``$CSIM_CACHE_DIR``, default ``~/.cache/csim``) and
``<key>`` hashes everything the compiled code depends on: the symbolic definition, the
sources of the kernels, of the core, of the methods' gamma* functions, of this module, of
the generator and of the derivation, and the numba, numpy and scipy versions.
Where the cache cannot be written, the module goes to a temporary folder of this process.
numba compiles its functions on first use and, with
``cache=True``, stores the machine code next to the file (``__pycache__``), so only the
first run of a mechanism pays for the sympy derivation and the compilation.
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType

from csim.model.cache import cache_dir, definition_key
from csim.model.definition import MechanismDefinition
from csim.solver.methods import STABILIZERS

#: bump when the generated module changes shape
FAST_VERSION = "2"

KERNELS = Path(__file__).with_name("kernels.py")
PHYSICS = Path(__file__).parents[1] / "physics"
#: where the kernels' own imports end and their body starts
_BODY_MARK = "# ---- the loop's constants"

_LOADED: dict[str, ModuleType] = {}
#: (id(definition), compiled methods) -> (definition, module): hashing a definition takes milliseconds
_BY_DEFINITION: dict[tuple, tuple[MechanismDefinition, ModuleType]] = {}


def _versions() -> str:
    import numba
    import numpy
    import scipy

    return f"numba {numba.__version__}, numpy {numpy.__version__}, scipy {scipy.__version__}"


def compiled_methods() -> list:
    """The registered methods whose gamma* the kernels call, in dispatch order (code = index + 1).

    Code 0 is gamma* = gamma (a method with a compiled path and no gamma_star_kernel).
    """
    return [cls for cls in STABILIZERS.values() if cls.compiled and cls.gamma_star_kernel is not None]


def method_code(method) -> int:
    """The dispatch code of a method instance (0: gamma* = gamma)."""
    dispatched = compiled_methods()
    return dispatched.index(type(method)) + 1 if type(method) in dispatched else 0


def _kernel_function(cls):
    """The plain Python function behind a method's gamma* kernel (a numba dispatcher or not)."""
    fn = cls.gamma_star_kernel
    return getattr(fn, "py_func", fn)


def method_dispatch_source() -> str:
    """``method_gamma_star(mk, r, gamma, phi, phi_dot, gains, fpar, ipar, out)``: gamma* by method code."""
    lines = ["# ---- gamma* of the stabilization methods with a compiled path (csim.solver.methods), by code ----"]
    for code, cls in enumerate(compiled_methods(), start=1):
        fn = _kernel_function(cls)
        lines.append(f"from {fn.__module__} import {fn.__name__} as _gamma_star_{code}  # {cls.name}")
    lines += ["", "", "@hot",
              "def method_gamma_star(mk, r, gamma, phi, phi_dot, gains, fpar, ipar, out):",
              '    """gamma* (r,) into out by the method\'s code; 0 is gamma* = gamma."""']
    for code, _ in enumerate(compiled_methods(), start=1):
        lines += [f"    {'if' if code == 1 else 'elif'} mk == {code}:",
                  f"        _gamma_star_{code}(r, gamma, phi, phi_dot, gains, fpar, ipar, out)", "        return"]
    lines += ["    for i in range(r):", "        out[i] = gamma[i]"]
    return "\n".join(lines) + "\n"


def module_key(definition: MechanismDefinition) -> str:
    """Hash of everything the compiled module of ``definition`` depends on."""
    model_dir = Path(__file__).parents[1] / "model"  # read, not imported: importing derive imports sympy
    sources = [KERNELS, Path(__file__), Path(__file__).with_name("codegen.py"), model_dir / "derive.py",
               *sorted(PHYSICS.glob("*.py"))]
    methods = [inspect.getsource(_kernel_function(cls)) for cls in compiled_methods()]
    parts = [FAST_VERSION, definition_key(definition), *(p.read_text() for p in sources), *methods,
             method_dispatch_source(), _versions(), sys.version]
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


def module_path(definition: MechanismDefinition) -> Path:
    return cache_dir() / "fast" / f"{definition.name}_{module_key(definition)}.py"


def generate_module_source(definition: MechanismDefinition) -> str:
    """The full source of the compiled module (derives the model: seconds)."""
    from csim.fast.codegen import model_source
    from csim.model.derive import derive

    kernels = KERNELS.read_text()
    header = (f'"""csim compiled module of {definition.name!r}, generated by csim.fast.module. '
              f'Do not edit."""\n')
    # the kernels' own imports come first; the model functions use math, numpy and njit
    body = kernels.split('"""', 2)[2]  # drop the kernels' docstring
    imports, _, rest = body.partition(_BODY_MARK)
    return (header + imports + model_source(derive(definition)) + "\n\n" + method_dispatch_source() + "\n\n"
            + _BODY_MARK + rest)


def _write_atomic(path: Path, text: str) -> None:
    """Write ``path`` whole or not at all (workers of ``csim compare`` may race for it)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.chmod(tmp, 0o644)  # mkstemp's 0600 would keep a shared cache from others
        if not path.exists():  # another process was first: its file is the same
            os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)


_FALLBACK_DIR: Path | None = None


def _writable(path: Path) -> Path:
    """``path``, or the same name in a temporary folder of this process if its folder cannot be written."""
    global _FALLBACK_DIR
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        if os.access(path.parent, os.W_OK):
            return path
    except OSError:
        pass
    if _FALLBACK_DIR is None:
        _FALLBACK_DIR = Path(tempfile.mkdtemp(prefix="csim-fast-"))
    return _FALLBACK_DIR / path.name


def load_module(definition: MechanismDefinition) -> ModuleType:
    """The compiled module of ``definition`` (generated on the first call for this key)."""
    memo = (id(definition), tuple(compiled_methods()))  # a method registered later makes a new module
    known = _BY_DEFINITION.get(memo)
    if known is not None and known[0] is definition:
        return known[1]
    path = module_path(definition)
    if not path.is_file():
        path = _writable(path)
    key = str(path)
    if key in _LOADED:
        _BY_DEFINITION[memo] = (definition, _LOADED[key])
        return _LOADED[key]
    if not path.is_file():
        from csim.progress import status

        with status(f"generating the compiled module of {definition.name!r} (sympy)"):
            _write_atomic(path, generate_module_source(definition))
    name = f"csim_fast_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module  # numba's cache locates functions through their module
    spec.loader.exec_module(module)
    _LOADED[key] = module
    _BY_DEFINITION[memo] = (definition, module)
    return module
