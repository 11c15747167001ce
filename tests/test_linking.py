"""csim.fast.linking: a csim callee is compiled with its own code only, an entry point once with its call tree.

A three-level call tree (``entry`` -> ``middle`` -> ``leaf``, all ``njit(cache=True)``) in a
module named as a compiled copy of the kernels is compiled in a fresh process: the callees'
modules declare their callees instead of holding them, the entry point's module holds its
whole tree, every function gives its value called from Python, only the entry point is
written to numba's cache, and a later process runs it from the cache alone. The same tree
compiled without :func:`install` holds each callee's tree in its caller's module (numba's own
linking), which shows the checks can tell the two apart.
"""
from __future__ import annotations

import inspect
import json
import os
import subprocess
import sys

import pytest

from csim.fast import linking

#: the call tree's leaf, and its import
LEAF_SOURCE = '''
from numba import njit


@njit(cache=True)
def leaf(x):
    return 2.0 * x + 1.0
'''

TREE = LEAF_SOURCE + '''

@njit(cache=True)
def middle(x):
    total = 0.0
    for i in range(3):
        total += leaf(x + i)
    return total


@njit(cache=True)
def entry(x):
    return middle(x) - leaf(x)
'''

COMPILE = """
import json, sys
sys.path.insert(0, sys.argv[1])
from csim.fast import linking
installed = linking.install() if sys.argv[2] == "install" else False
import csim_fast_kernels_tree as tree

def library(dispatcher):
    return dispatcher.overloads[dispatcher.signatures[0]].library

def declared(dispatcher):  # the csim functions its module calls without holding them
    return sorted(name for name in ("leaf", "middle") for fn in library(dispatcher)._final_module.functions
                  if fn.is_declaration and name in fn.name)

value = tree.entry(1.5)
out = dict(installed=installed, value=value, hits=sum(tree.entry.stats.cache_hits.values()))
if tree.middle.signatures:  # compiled in this process, as the entry point's callee
    out.update(own={name: linking.own_code_only(library(getattr(tree, name))) for name in ("entry", "middle", "leaf")},
               declared={name: declared(getattr(tree, name)) for name in ("entry", "middle")})
out.update(middle=tree.middle(2.0), leaf=tree.leaf(2.0))  # each called from Python too
print(json.dumps(out))
"""


def _compile(folder, mode: str) -> dict:
    done = subprocess.run([sys.executable, "-c", COMPILE, str(folder), mode], capture_output=True, text=True,
                          timeout=300, env=dict(os.environ))
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def _cached(folder) -> list[str]:
    """The functions numba's cache holds an index of (``csim_fast_kernels_tree.<name>-<line>.py3xx.nbi``)."""
    return sorted(p.name.split(".")[1].split("-")[0] for p in (folder / "__pycache__").glob("*.nbi"))


ENTRY, MIDDLE, LEAF = (4.0 + 6.0 + 8.0) - 4.0, 5.0 + 7.0 + 9.0, 5.0  # entry(1.5), middle(2.0), leaf(2.0)


def test_callees_hold_their_own_code_and_the_entry_point_its_whole_tree(tmp_path):
    (tmp_path / "csim_fast_kernels_tree.py").write_text(TREE)
    first = _compile(tmp_path, "install")
    assert first["installed"]
    assert first["own"] == {"entry": False, "middle": True, "leaf": True}
    assert first["declared"] == {"entry": [], "middle": ["leaf"]}, "middle must call leaf through its symbol"
    assert (first["value"], first["middle"], first["leaf"]) == (ENTRY, MIDDLE, LEAF)
    assert _cached(tmp_path) == ["entry"], "only the entry point may be cached: a callee needs its callees' symbols"

    second = _compile(tmp_path, "install")  # the entry point from the cache, its callees never compiled
    assert second["hits"] == 1 and "own" not in second
    assert (second["value"], second["middle"], second["leaf"]) == (ENTRY, MIDDLE, LEAF)
    # middle, called from Python, compiled as an entry point (cached), leaf as its callee (not cached)
    assert _cached(tmp_path) == ["entry", "middle"]


def test_without_install_numba_links_each_callee_into_its_caller(tmp_path):
    (tmp_path / "csim_fast_kernels_tree.py").write_text(TREE)
    plain = _compile(tmp_path, "plain")
    assert not plain["installed"]
    assert plain["own"] == {"entry": False, "middle": False, "leaf": False}
    assert plain["declared"] == {"entry": [], "middle": []}
    assert plain["value"] == ENTRY
    assert _cached(tmp_path) == ["entry", "leaf", "middle"]


def test_functions_of_other_modules_link_as_numba_links_them(tmp_path):
    """The rule is for csim's functions: a leaf from a module of another name is linked into its csim caller."""
    (tmp_path / "other_tree.py").write_text(LEAF_SOURCE)
    (tmp_path / "csim_fast_kernels_tree.py").write_text(
        "from numba import njit\n\nfrom other_tree import leaf\n" + TREE[len(LEAF_SOURCE):])
    out = _compile(tmp_path, "install")
    assert out["own"] == {"entry": False, "middle": True, "leaf": False}
    assert out["declared"]["middle"] == [], "other_tree.leaf is linked into middle"
    assert (out["value"], out["middle"], out["leaf"]) == (ENTRY, MIDDLE, LEAF)


DEAD_BRANCH = LEAF_SOURCE + '''

@njit(cache=True)
def unused(x):
    return leaf(x) + 3.0


@njit(cache=True)
def used(x):
    return leaf(x) * 5.0


@njit(cache=True)
def entry(x):
    n = 0.0
    if x * 0 == 1:  # never true: numba keeps the branch, LLVM's function passes remove it before linking
        n = unused(x)
    return used(x) + n
'''

LOAD = """
import json, sys
sys.path.insert(0, sys.argv[1])
from csim.fast import linking
linking.install()
import csim_fast_kernels_tree as tree
value = tree.entry(3.0)
library = tree.entry.overloads[tree.entry.signatures[0]].library
linkages = {} if library._disable_inspection else {  # what the entry's module makes of each csim function
    fn.name: "declared" if fn.is_declaration else fn.linkage.name for fn in library._final_module.functions
    if "csim_fast_kernels_tree" in fn.name and "cpython" not in fn.name and not fn.name.startswith("cfunc.")}
print(json.dumps(dict(value=value, hits=sum(tree.entry.stats.cache_hits.values()), linkages=linkages)))
"""


def _load(folder) -> dict:
    done = subprocess.run([sys.executable, "-c", LOAD, str(folder)], capture_output=True, text=True, timeout=300,
                          env=dict(os.environ))
    # -11: the cached entry point calls a symbol that nothing defines
    assert done.returncode == 0, f"exit {done.returncode}: {done.stderr}"
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_callee_whose_only_caller_llvm_removed_is_linked_for_its_other_callers(tmp_path):
    """leaf's first caller in the tree (unused) is gone from the entry's module by the time it is linked:
    leaf is still linked for used, and the cached entry point runs in a later process (it crashed there)."""
    (tmp_path / "csim_fast_kernels_tree.py").write_text(DEAD_BRANCH)
    first = _load(tmp_path)
    assert first["value"] == 35.0 and first["hits"] == 0
    assert "declared" not in first["linkages"].values(), first["linkages"]
    second = _load(tmp_path)
    assert second == dict(value=35.0, hits=1, linkages={})


#: a callee too large to inline at each of its 16 calls
NOT_INLINED = "from numba import njit\n\n\n@njit(cache=True)\ndef middle(x):\n    total = 0.0\n" + "".join(
    f"    for i in range(int(x) + {k}):\n        total += math.sin(total + {k}.5 * i) / (1.0 + i)\n" for k in range(12)
) + "    return total\n\n\n@njit(cache=True)\ndef entry(x):\n    return " + " + ".join(
    f"middle(x + {k})" for k in range(16)) + "\n"


def test_the_entry_point_runs_its_own_copies_in_the_compiling_process_too(tmp_path):
    """The entry's copy of a callee it calls (not inlined) is private: a weak copy would bind to the callee's
    own library, already in the JIT engine, and the compiling process would run that one."""
    (tmp_path / "csim_fast_kernels_tree.py").write_text("import math\n" + NOT_INLINED)
    first = _load(tmp_path)
    middle = {name: linkage for name, linkage in first["linkages"].items() if "6middle" in name}
    assert middle and set(middle.values()) == {"private"}, first["linkages"]
    assert _load(tmp_path)["value"] == first["value"]


def test_install_leaves_another_numba_as_it_is():
    """Where numba's methods are not those it was written for, install() changes nothing and says so."""
    code = """
import json
from numba.core import caching, codegen, cpu
from csim.fast import linking
before = (cpu.CPUContext.get_executable, codegen.CPUCodeLibrary.finalize, caching.Cache.save_overload)
linking._expected = lambda *methods: False
installed = linking.install()
after = (cpu.CPUContext.get_executable, codegen.CPUCodeLibrary.finalize, caching.Cache.save_overload)
print(json.dumps(dict(installed=installed, same=before == after)))
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == dict(installed=False, same=True)


@pytest.mark.parametrize("change", ["signature", "source", "order", "module"])
def test_another_numba_is_recognised(change):
    """_expected: numba's methods as install() wraps them, and four ways another numba could differ."""
    from numba.core import caching, codegen, cpu

    numbas = [inspect.unwrap(method) for method in (  # install() may have wrapped them in this process
        cpu.CPUContext.get_executable, codegen.CPUCodeLibrary.finalize, codegen.CPUCodeLibrary._optimize_final_module,
        codegen.CPUCodeLibrary._finalize_final_module, caching.Cache.save_overload)]
    if change == "module":
        def finalize_module(self):  # a numba that adds the module to the JIT engine before its checks
            self._codegen._add_module(self._final_module)
            self._finalize_dynamic_globals()
            self._verify_declare_only_symbols()
        assert linking._expected(*numbas)
        assert not linking._expected(*numbas[:3], finalize_module, numbas[4])
        return
    if change == "signature":
        def finalize(self, strict=True):  # a numba whose finalize takes an argument
            return None
    elif change == "source":
        def finalize(self):  # a numba that links otherwise
            return self._link_everything()
    else:
        def finalize(self):  # a numba that optimizes before it links
            self._optimize_final_module()
            for library in self._linking_libraries:
                self._final_module.link_in(library._get_module_for_linking())
    assert linking._expected(*numbas)
    assert not linking._expected(numbas[0], finalize, *numbas[2:])


ONLY = """
import json, re, sys
sys.path.insert(0, sys.argv[1])
from csim.fast import linking
if sys.argv[2] == "entry":
    linking.entry_points_only()
else:
    linking.install()
import csim_fast_kernels_tree as tree
value = tree.entry(1.5)
library = tree.entry.overloads[tree.entry.signatures[0]].library
out = dict(value=value, hits=sum(tree.entry.stats.cache_hits.values()),
           ir=re.sub(r"B[0-9]+v[0-9]+", "Bv", library.get_llvm_str()) if tree.middle.signatures else "")
try:
    out["middle"] = tree.middle(2.0)
except RuntimeError as exc:
    out["middle"] = str(exc)
print(json.dumps(out))
"""


def _only(folder, mode: str) -> dict:
    done = subprocess.run([sys.executable, "-c", ONLY, str(folder), mode], capture_output=True, text=True,
                          timeout=300, env=dict(os.environ))
    assert done.returncode == 0, f"exit {done.returncode}: {done.stderr}"
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("source", [TREE, "import math\n" + NOT_INLINED], ids=["inlined", "not-inlined"])
def test_entry_points_only_gives_the_entry_point_the_same_code_and_its_callees_none(tmp_path, source):
    """entry_points_only (csim.warmup's jobs): the entry point's optimized module is the same as where its
    callees get machine code of their own (they link in their modules as they are before LLVM's module
    passes either way), a callee called from Python raises, and the cached entry point runs in a later
    process, where its callee compiles when Python calls it."""
    (tmp_path / "csim_fast_kernels_tree.py").write_text(source)
    only = _only(tmp_path, "entry")
    assert only["middle"] == linking.STUB_MESSAGE and only["hits"] == 0
    assert _cached(tmp_path) == ["entry"]
    later = _only(tmp_path, "plain")
    assert later["hits"] == 1 and later["value"] == only["value"] and isinstance(later["middle"], float)
    for path in (tmp_path / "__pycache__").iterdir():  # (numba's cache) compiled again, with machine code for each
        path.unlink()
    plain = _only(tmp_path, "plain")
    assert plain["ir"] == only["ir"] and plain["value"] == only["value"] and plain["hits"] == 0


RECURSIVE = '''
from numba import njit


@njit(cache=True)
def even(n):
    if n == 0:
        return 1
    return odd(n - 1)


@njit(cache=True)
def odd(n):
    if n == 0:
        return 0
    return even(n - 1)


@njit(cache=True)
def entry(x):
    n = int(x)
    return float(even(n) + 10 * odd(n))
'''


def test_a_recursive_tree_is_not_cached(tmp_path):
    """numba calls a recursive function through a global that only the compiling process resolves: the entry
    point is left out of the cache (numba's own linking cached it, and a later process crashed)."""
    (tmp_path / "csim_fast_kernels_tree.py").write_text(RECURSIVE)
    assert _load(tmp_path)["value"] == 10.0  # entry(3.0): even(3) = 0, odd(3) = 1
    assert _cached(tmp_path) == []
    assert _load(tmp_path)["value"] == 10.0


def test_a_recursive_tree_does_not_run_where_callees_have_no_machine_code(tmp_path):
    """Under entry_points_only numba cannot resolve the recursive call (it points at the callee's machine code):
    a RuntimeError, not a crash; a later process compiles and runs it as before."""
    (tmp_path / "csim_fast_kernels_tree.py").write_text(RECURSIVE)
    code = ("import sys; sys.path.insert(0, sys.argv[1]); from csim.fast import linking; linking.entry_points_only()\n"
            "import csim_fast_kernels_tree as tree\ntree.entry(3.0)")
    done = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 1 and "RuntimeError" in done.stderr and "unresolved symbol" in done.stderr, done.stderr
    assert _cached(tmp_path) == []
    assert _load(tmp_path)["value"] == 10.0
