"""Load the compiled kernels (once per installation) and a mechanism's model functions.

The kernels (the package :mod:`csim.fast.kernels`) are the same for every mechanism. They are
imported from a copy of the package, ``<kernels>/kernels_<key>/``, where ``<kernels>`` is
:func:`csim.model.cache.kernels_dir` (``$CSIM_KERNELS_DIR``, default ``fast/`` in csim's
cache, ``$CSIM_CACHE_DIR`` or ``~/.cache/csim``) and ``<key>`` hashes everything their
machine code depends on: the kernels' files, the layout, the core (:mod:`csim.physics`), the
built-in methods' files, and the numba, numpy, scipy and Python versions. numba compiles
them on first use and keeps the machine code next to the copy (``__pycache__``); every
later process, for any mechanism, loads it from there. (numba's own cache check looks at
one file's time stamp only; the key in the name makes an edit of any dependency a new
package instead of stale machine code.) One copy serves every method, ``minimal``'s
partitioned system included, and its files are the source's, unchanged: imported under the
name ``csim_fast_kernels_<key>``, outside the package ``csim``, it knows it is the compiled
one (:mod:`csim.fast.kernels.variant`). Copies of other keys (an upgrade, an edit) that no
process has loaded for 30 days are removed when a new copy is written (:func:`prune_kernels`).

A mechanism's model functions (:mod:`csim.fast.codegen`) are built into
``<cache>/fast/<mechanism>_<key>.so`` by the system's C compiler (:mod:`csim.fast.ccodegen`,
``cc -O2``, a fraction of a second), or, where no C compiler works, into numba cfuncs in
``<mechanism>_<key>_cfunc.py`` (seconds; numba caches them too). ``<key>`` hashes the
symbolic definition and the generators. The kernels call them through their addresses,
which :func:`csim.fast.runner.pack_problem` puts into ``pi``. ``CSIM_MODEL_BACKEND``
chooses: ``auto`` (default: C, else numba), ``c`` or ``numba``.

A stabilization method whose gamma* is not in the kernels' own dispatch
(:data:`csim.fast.layout.BUILTIN_GAMMA`, e.g. one registered by a test or a user) runs
compiled too: its kernel is wrapped in a cfunc in this process and called through its
address.

Where the cache cannot be written, the files go to a temporary folder of this process.
"""
from __future__ import annotations

import contextlib
import ctypes
import functools
import hashlib
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType, SimpleNamespace

import numpy as np

from csim.fast.cache_load import KERNELS_PREFIX
from csim.fast.layout import BUILTIN_GAMMA, EXTERNAL, MODEL_FUNCTIONS, c_symbol
from csim.fast.support import numba_usable
from csim.model.cache import cache_dir, definition_key, kernels_dir
from csim.model.definition import MechanismDefinition
from csim.solver.methods import STABILIZERS

#: bump when the generated files change shape
FAST_VERSION = "4"

HERE = Path(__file__).parent
#: the kernels' package, copied whole into the cache
KERNELS = HERE / "kernels"
PHYSICS = HERE.parent / "physics"
METHODS = HERE.parent / "solver" / "methods"
#: model backends (CSIM_MODEL_BACKEND; python: the cfunc source run by Python, for the interpreted kernels only)
MODEL_BACKENDS = ("auto", "c", "numba", "python")

#: the loaded copy of the kernels (one a process; None: not loaded yet)
_KERNELS: ModuleType | None = None
#: (the loaded kernels, a function's name) -> the address of its machine code (addressed_function)
_ADDRESSES: dict[tuple[ModuleType, str], int] = {}
#: (id(definition), drives) -> (definition, model): hashing a definition takes milliseconds
_BY_DEFINITION: dict[tuple, tuple[MechanismDefinition, CompiledModel]] = {}
_MODELS: dict[str, CompiledModel] = {}
#: gamma* kernel -> its cfunc (kept alive: the kernels hold its address)
_GAMMA_CFUNCS: dict = {}


def _versions() -> str:
    import numba
    import numpy
    import scipy

    return f"numba {numba.__version__}, numpy {numpy.__version__}, scipy {scipy.__version__}, python {sys.version}"


def _hash(parts) -> str:
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:24]


# ---------------------------------------------------------------------------------------
# the kernels: one package per installation
# ---------------------------------------------------------------------------------------
@functools.cache
def _kernels_snapshot() -> tuple[str, dict[str, str]]:
    """(key, sources): the hash of everything the kernels' machine code depends on, and the
    kernels' files it hashed (file name -> text), read once per process.

    Once: the copy must hold the text its key hashed, and the process's key must not change
    under it. (When there were two copies, a key computed again after a source file changed
    under a running process named the second copy with a new key while its machine code
    referred to the first one's, which no later process could import: every ``minimal`` run
    fell back to the Python path until the cache was cleared.)
    """
    sources = {p.name: p.read_text() for p in _sources(KERNELS)}
    deps = [HERE / "layout.py", HERE / "linking.py", HERE / "cache_load.py", *_sources(PHYSICS), *_sources(METHODS)]
    parts = [FAST_VERSION, *(f"{name}\n{text}" for name, text in sources.items()), *(p.read_text() for p in deps)]
    return _hash([*parts, _versions()]), sources


def _sources(folder: Path) -> list[Path]:
    """The Python files of ``folder``, sorted; not an editor's lock or backup (``.#driver.py``)."""
    return sorted(p for p in folder.glob("*.py") if not p.name.startswith(".") and p.is_file())


def kernels_key() -> str:
    """Hash of everything the kernels' machine code depends on (fixed for the process: :func:`_kernels_snapshot`)."""
    return _kernels_snapshot()[0]


def kernels_path() -> Path:
    """The kernels' copy in the cache, a package: ``kernels_<key>/``."""
    return kernels_dir() / f"kernels_{kernels_key()}"


def _package_name() -> str:
    """The name the copy is imported under: ``csim_fast_kernels_<key>`` (:mod:`csim.fast.kernels.variant`)."""
    return f"{KERNELS_PREFIX}{kernels_key()}"


def kernels_source() -> dict[str, str]:
    """The files of the compiled copy of the kernels (name -> text): the source's, as the key hashed them."""
    return dict(_kernels_snapshot()[1])


def kernels_compiled(module: ModuleType) -> bool:
    """Whether numba's cache holds the machine code of the kernels' loop and of the functions it calls by
    address, the right-hand side and the elimination's solve (else the first run compiles them)."""
    def cached(dispatcher) -> bool:  # the copy's file that holds it, and numba's index of it there
        source = Path(dispatcher.py_func.__code__.co_filename)
        return any((source.parent / "__pycache__").glob(f"{source.stem}.{dispatcher.__name__}-*.nbi"))
    return cached(module.integrate) and cached(module.feval) and cached(module.eliminated)


def load_kernels(compiled: bool = True) -> ModuleType:
    """The kernels package (imported once per process; compiled on first use once per installation).

    Parameters
    ----------
    compiled : bool
        False: the package's own source, run by Python (the interpreted backend; numba is not imported).
    """
    global _KERNELS
    if not compiled:
        return importlib.import_module("csim.fast.kernels")
    if _KERNELS is not None:
        return _KERNELS
    from csim.fast import cache_load, linking

    cache_load.install()  # a warm run loads the machine code without loading all of numba's target
    linking.install()  # a cold one optimizes each entry point's call tree once, not once per function
    if _KernelsFinder not in sys.meta_path:
        sys.meta_path.append(_KernelsFinder)
    # numba's cache locates functions through their module, imported by name (the finder)
    _KERNELS = importlib.import_module(_package_name())
    return _KERNELS


def addressed_function(kernels: ModuleType, name: str) -> int:
    """The address of the machine code of ``kernels.<name>`` (``feval``, ``eliminated``: compiled on their own
    and called by address), compiled for ``kernels.<NAME>_TYPES`` or loaded from numba's cache on the first
    call in a process."""
    function = getattr(kernels, name)
    if not kernels.COMPILED:  # the interpreted package calls its own from Python: an id stands for the address
        return id(function)
    if (kernels, name) not in _ADDRESSES:
        from numba import types

        signature = tuple(getattr(kernels, f"{name.upper()}_TYPES"))
        function.compile(signature)
        compiled = function.overloads[signature]
        if compiled.signature.return_type != types.int64:  # the calls read an int64
            raise RuntimeError(f"{name} returns {compiled.signature.return_type}, the kernels expect int64")
        address = compiled.library.get_pointer_to_function(compiled.fndesc.llvm_func_name)
        if not address:
            raise RuntimeError(f"no machine code for {compiled.fndesc.llvm_func_name} in {kernels.__name__}")
        _ADDRESSES[kernels, name] = address
    return _ADDRESSES[kernels, name]


def _kernels_copy() -> Path:
    """The kernels' copy, written into the cache if it is not there yet (and then the copies of other keys
    that no process has used for :data:`UNUSED_DAYS` removed: :func:`prune_kernels`); its time stamp says
    when a process last loaded it."""
    path = kernels_path()
    if not path.is_dir():
        path = _writable(path)
        if not path.is_dir():
            _write_package(path, kernels_source())
            prune_kernels(path.parent)
    with contextlib.suppress(OSError):
        os.utime(path)  # used now (a copy's own files keep their stamps: numba's cache checks them)
    return path


#: a copy of the kernels of another key (an earlier csim, numba or edit) that no process has loaded for
#: this many days is removed when a new copy is written (3.3 MB a key with its machine code, 2026-11-27)
UNUSED_DAYS = 30


def prune_kernels(folder: Path, now: float | None = None) -> list[Path]:
    """Remove from ``folder`` the kernels' copies of other keys than this process's, unused for
    :data:`UNUSED_DAYS`: package copies ``kernels_<key>/`` (and ``kernels_partitioned_<key>/``, the
    second copy of csim before one served every method) and the single-file copies of csim before
    the package (``kernels_<key>.py``), with their machine code in ``__pycache__``.
    A copy's last use is the newest stamp of its folder or file (:func:`_kernels_copy` sets it at
    each load) and of its machine code's files (numba reads their index at each load: the access
    time, where the file system keeps it, tells of an older csim that sets no stamp). Returns what
    was removed."""
    now = time.time() if now is None else now
    current = {kernels_path().name}
    removed = []
    for path in sorted(folder.iterdir()) if folder.is_dir() else ():
        match = _COPY.match(path.name)
        if match is None or match.group(1) in current or (path.is_file() and path.suffix != ".py"):
            continue
        with contextlib.suppress(OSError):
            machine_code = _machine_code(path, match.group(1))
            if now - max([path.stat().st_mtime, *(_used(p) for p in machine_code)]) > UNUSED_DAYS * 86400:
                for p in machine_code:
                    p.unlink()
                shutil.rmtree(path) if path.is_dir() else path.unlink()
                removed.append(path)
    return removed


#: a copy of the kernels: ``kernels[_partitioned]_<key>`` (a package) or the same with ``.py`` (a single file)
_COPY = re.compile(r"^(kernels(?:_partitioned)?_[0-9a-f]{24})(?:\.py)?$")


def _machine_code(copy: Path, name: str) -> list[Path]:
    """numba's files of a copy: in its own ``__pycache__`` (a package), or ``<folder>/__pycache__/<name>.*``."""
    if copy.is_dir():
        return sorted((copy / "__pycache__").glob("*.nb[ic]"))
    return sorted((copy.parent / "__pycache__").glob(f"{name}.*"))


def _used(path: Path) -> float:
    """When a file was last read or written [s since the epoch]."""
    info = path.stat()
    return max(info.st_mtime, info.st_atime)


class _KernelsFinder:
    """Imports the copy of the kernels by its package name (last on ``sys.meta_path``).

    numba rebuilds a cached function's environment by importing its module by name
    (``csim_fast_kernels_<key>.system``). Importing the copy only defines its functions;
    nothing is compiled until one is called. (Its files are found through the package's
    path, as any package's.)
    """

    @staticmethod
    def find_spec(name, path=None, target=None):
        if name != _package_name():
            return None
        copy = _kernels_copy()
        return importlib.util.spec_from_file_location(name, copy / "__init__.py",
                                                      submodule_search_locations=[str(copy)])


# ---------------------------------------------------------------------------------------
# the stabilization methods
# ---------------------------------------------------------------------------------------
def compiled_methods() -> list:
    """The registered methods the compiled kernels run (gamma* by code, or through an address)."""
    return [cls for cls in STABILIZERS.values() if cls.compiled]


def _py(fn):
    return getattr(fn, "py_func", fn)


def method_dispatch(method, interpreted: bool = False) -> tuple[int, int]:
    """(code, address) of a method's gamma* for the kernels: code 0 is gamma* = gamma, 1.. the
    kernels' built-in dispatch, EXTERNAL a cfunc at ``address`` (for the interpreted kernels, the
    key of its Python kernel in :data:`csim.fast.kernels.interpreted.PYTHON_FUNCTIONS`)."""
    fn = type(method).gamma_star_kernel
    if fn is None:
        return 0, 0
    for code, builtin in enumerate(BUILTIN_GAMMA, start=1):
        if _py(builtin) is _py(fn):
            return code, 0
    if interpreted:
        from csim.fast.kernels.interpreted import PYTHON_FUNCTIONS

        PYTHON_FUNCTIONS[id(_py(fn))] = _py(fn)
        return EXTERNAL, id(_py(fn))
    if fn not in _GAMMA_CFUNCS:
        _GAMMA_CFUNCS[fn] = _gamma_cfunc(fn)
    return EXTERNAL, _GAMMA_CFUNCS[fn].address


def method_code(method) -> int:
    """The dispatch code of a method instance (0: gamma* = gamma)."""
    return method_dispatch(method)[0]


def _gamma_cfunc(kernel):
    """A cfunc with the kernels' gamma* interface (csim.fast.kernels.addresses.call_gamma) around ``kernel``."""
    from numba import carray, cfunc, njit, types

    f8p, i8p, i8 = types.CPointer(types.float64), types.CPointer(types.int64), types.int64
    signature = types.void(i8, f8p, f8p, f8p, f8p, i8, f8p, i8, i8p, i8, f8p)
    inner = kernel if hasattr(kernel, "py_func") else njit(kernel)

    def gamma_star(r, gamma, phi, phi_dot, gains, n_gains, fpar, n_fpar, ipar, n_ipar, out):
        inner(r, carray(gamma, r), carray(phi, r), carray(phi_dot, r), carray(gains, n_gains),
              carray(fpar, n_fpar), carray(ipar, n_ipar), carray(out, r))

    return cfunc(signature, error_model="numpy")(gamma_star)


# ---------------------------------------------------------------------------------------
# a mechanism's model functions
# ---------------------------------------------------------------------------------------
@dataclass
class CompiledModel:
    """A mechanism's model functions, loaded: their addresses in the order of MODEL_FUNCTIONS."""

    name: str
    #: "c" (the system's C compiler), "numba" (cfuncs) or "python" (the cfunc source run by Python)
    backend: str
    #: (m, r, k, o)
    dims: tuple[int, int, int, int]
    addresses: np.ndarray
    #: the CDLL or the cfunc module (kept alive: the kernels hold the addresses)
    handle: object = field(repr=False, default=None)
    #: why the C path was not taken ("" when it was)
    reason: str = ""


def model_key(definition: MechanismDefinition, drives: Drives | None = None) -> str:
    """Hash of everything a mechanism's model functions depend on (with ``drives``: its drive rows too)."""
    model_dir = HERE.parent / "model"  # read, not imported: importing derive imports sympy
    sources = [HERE / "codegen.py", HERE / "ccodegen.py", HERE / "layout.py", model_dir / "derive.py"]
    extra = [] if drives is None else [repr(drives)]
    return _hash([FAST_VERSION, definition_key(definition), *(p.read_text() for p in sources), *extra])


@dataclass(frozen=True)
class Drives:
    """Drives q_j = f_j(t) as constraint rows of the compiled model (:func:`csim.model.derive.with_drive_rows`).

    ``driven`` are the coordinates' indices (d,), ``expressions`` each f_j as sympy's ``srepr``
    of an expression of ``t`` and the mechanism's parameters (hashable, and exact in the key).
    """

    driven: tuple[int, ...]
    expressions: tuple[str, ...]


def model_backend() -> str:
    value = os.environ.get("CSIM_MODEL_BACKEND", "auto").strip().lower() or "auto"
    if value not in MODEL_BACKENDS:
        raise ValueError(f"CSIM_MODEL_BACKEND: got {value!r}, expected one of {', '.join(MODEL_BACKENDS)}")
    return value


def c_compiler() -> str | None:
    """The C compiler: $CC, else cc or gcc on the PATH (None: none)."""
    cc = os.environ.get("CC")
    return shutil.which(cc) if cc else (shutil.which("cc") or shutil.which("gcc"))


class _Derived:
    """The derivation of a definition (with its drive rows), made on first use only (sympy: seconds)."""

    def __init__(self, definition, drives: Drives | None = None):
        self.definition, self.drives, self._derived = definition, drives, None

    def get(self):
        if self._derived is None:
            from csim.model.derive import derive, with_drive_rows
            from csim.progress import status

            with status(f"generating the model functions of {self.definition.name!r} (sympy; first run of this "
                        f"mechanism)"):
                self._derived = derive(self.definition)
                if self.drives is not None:
                    import sympy as sp

                    self._derived = with_drive_rows(self._derived, list(self.drives.driven),
                                                    [sp.sympify(e) for e in self.drives.expressions])
        return self._derived


def _load_c(definition, key: str, derived: _Derived) -> CompiledModel:
    path = cache_dir() / "fast" / f"{definition.name}_{key}.so"
    if not path.is_file():
        path = _writable(path)
    if not path.is_file():
        cc = c_compiler()
        if cc is None:
            raise RuntimeError("no C compiler (cc, gcc or $CC) found")
        from csim.fast.ccodegen import CFLAGS, c_source
        from csim.progress import status

        source = c_source(derived.get())
        with status(f"compiling the model functions of {definition.name!r} (cc)"), \
                tempfile.TemporaryDirectory(dir=path.parent) as tmp:
            src, out = Path(tmp) / "model.c", Path(tmp) / "model.so"
            src.write_text(source)
            done = subprocess.run([cc, *CFLAGS, "-o", str(out), str(src), "-lm"], capture_output=True, text=True)
            if done.returncode != 0:
                raise RuntimeError(f"{Path(cc).name} failed: {' '.join(done.stderr.split())[:300]}")
            os.chmod(out, 0o755)
            os.replace(out, path)
    lib = ctypes.CDLL(str(path))
    addresses = [ctypes.cast(getattr(lib, c_symbol(name)), ctypes.c_void_p).value for name in MODEL_FUNCTIONS]
    dims = tuple(int(v) for v in (ctypes.c_long * 4).in_dll(lib, "csim_dims"))
    return CompiledModel(definition.name, "c", dims, np.array(addresses, dtype=np.int64), lib)


def _load_numba(definition, key: str, derived: _Derived, reason: str) -> CompiledModel:
    path = _cfunc_source_path(definition, key, derived)
    from csim.fast.cache_load import install
    from csim.progress import status

    install()  # (cached cfuncs load without numba's whole target too)
    name = f"csim_model_{path.stem}"
    with status(f"compiling the model functions of {definition.name!r} with numba (no C compiler: seconds)"):
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    addresses = [getattr(module, fn).address for fn in MODEL_FUNCTIONS]
    return CompiledModel(definition.name, "numba", tuple(module.DIMS), np.array(addresses, dtype=np.int64), module,
                         reason)


def load_model(definition: MechanismDefinition, drives: Drives | None = None,
               interpreted: bool = False) -> CompiledModel:
    """The model functions of ``definition``, with the rows of ``drives`` if given (generated and
    built on the first call for this key).

    C where a C compiler works, else numba cfuncs (``CSIM_MODEL_BACKEND`` chooses). For the
    interpreted kernels (``interpreted``), where numba is not to be used (``CSIM_PURE_PYTHON=1``,
    or not installed), the cfunc source run as Python instead; the compiled kernels refuse those.
    """
    backend = model_backend()
    if backend == "python" and not interpreted:
        raise ValueError("CSIM_MODEL_BACKEND=python: the compiled kernels call machine code; python is for "
                         "simulation.backend 'interpreted' only")
    # (the Python functions stand in for numba's cfuncs, where the interpreted kernels may not use numba)
    python_ok = backend == "python" or (interpreted and backend == "auto" and not numba_usable())
    memo_key = (id(definition), drives, backend, python_ok)
    known = _BY_DEFINITION.get(memo_key)
    if known is not None and known[0] is definition:
        return known[1]
    key = model_key(definition, drives)
    memo = f"{key}:{backend}:{python_ok}"
    if memo not in _MODELS:
        derived = _Derived(definition, drives)
        reason = f"CSIM_MODEL_BACKEND={backend}"
        model = None
        if backend in ("auto", "c"):
            try:
                model = _load_c(definition, key, derived)
            except Exception as exc:
                if backend == "c":
                    raise
                reason = f"{type(exc).__name__}: {exc}"
        if model is None and python_ok:
            model = _load_python(definition, key, derived, reason)
        _MODELS[memo] = model or _load_numba(definition, key, derived, reason)
    _BY_DEFINITION[memo_key] = (definition, _MODELS[memo])
    return _MODELS[memo]


def _cfunc_source_path(definition, key: str, derived: _Derived) -> Path:
    """The mechanism's cfunc module in the cache (:func:`csim.fast.codegen.cfunc_source`), written if missing."""
    path = cache_dir() / "fast" / f"{definition.name}_{key}_cfunc.py"
    if not path.is_file():
        path = _writable(path)
    if not path.is_file():
        from csim.fast.codegen import cfunc_source

        _write_atomic(path, cfunc_source(derived.get()))
    return path


#: the names the cfunc source takes from numba, as no-ops: run as Python, its functions are plain functions
_NO_NUMBA = {"cfunc": lambda *args, **kwargs: (lambda fn: fn),
             "types": SimpleNamespace(CPointer=lambda dtype: None, float64=None, void=lambda *args: None)}
_NUMBA_IMPORT = "from numba import cfunc, types\n"


def _load_python(definition, key: str, derived: _Derived, reason: str) -> CompiledModel:
    """The model functions as Python functions of the cfunc source, registered for the interpreted kernels
    (:data:`csim.fast.kernels.interpreted.PYTHON_FUNCTIONS`) under their ids, which stand for their addresses."""
    from csim.fast.kernels.interpreted import PYTHON_FUNCTIONS

    text = _cfunc_source_path(definition, key, derived).read_text()
    if text.count(_NUMBA_IMPORT) != 1:
        raise RuntimeError(f"the cfunc source of {definition.name!r} does not import numba as expected")
    namespace = dict(_NO_NUMBA, __name__=f"csim_model_{definition.name}_{key}_python")
    exec(compile(text.replace(_NUMBA_IMPORT, ""), f"<model functions of {definition.name}>", "exec"), namespace)
    functions = [namespace[fn] for fn in MODEL_FUNCTIONS]
    for fn in functions:
        PYTHON_FUNCTIONS[id(fn)] = fn
    return CompiledModel(definition.name, "python", tuple(namespace["DIMS"]),
                         np.array([id(fn) for fn in functions], dtype=np.int64), functions, reason)


def load_module(definition: MechanismDefinition) -> ModuleType:
    """The kernels, with the model functions of ``definition`` built (the arrays of
    :func:`csim.fast.runner.pack_problem` carry their addresses)."""
    load_model(definition)
    return load_kernels()


# ---------------------------------------------------------------------------------------
# files in the cache
# ---------------------------------------------------------------------------------------
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


def _write_package(path: Path, sources: dict[str, str]) -> None:
    """Write the package ``path`` (file name -> text) whole or not at all: written into a
    temporary folder, then renamed (a rename onto a folder another process wrote first fails,
    and that one is kept: numba's cache is keyed on its files' stamps). A temporary folder
    an hour old is one a killed process left behind, and is removed."""
    path.parent.mkdir(parents=True, exist_ok=True)
    for left in path.parent.glob(f".{path.name}-*"):
        with contextlib.suppress(OSError):
            if time.time() - left.stat().st_mtime > 3600:
                shutil.rmtree(left)
    tmp = Path(tempfile.mkdtemp(dir=path.parent, prefix=f".{path.name}-"))
    try:
        for name, text in sources.items():
            (tmp / name).write_text(text)
            os.chmod(tmp / name, 0o644)
        os.chmod(tmp, 0o755)  # mkdtemp's 0700 would keep a shared cache from others
        try:
            os.rename(tmp, path)
        except OSError:
            if not path.is_dir():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


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
