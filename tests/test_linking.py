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

TREE = '''
from numba import njit


@njit(cache=True)
def leaf(x):
    return 2.0 * x + 1.0


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
    head, tail = TREE.split("@njit(cache=True)\ndef middle")  # (the import and leaf, middle and entry)
    (tmp_path / "other_tree.py").write_text(head)
    (tmp_path / "csim_fast_kernels_tree.py").write_text(
        "from numba import njit\n\nfrom other_tree import leaf\n\n\n@njit(cache=True)\ndef middle" + tail)
    out = _compile(tmp_path, "install")
    assert out["own"] == {"entry": False, "middle": True, "leaf": False}
    assert out["declared"]["middle"] == [], "other_tree.leaf is linked into middle"
    assert (out["value"], out["middle"], out["leaf"]) == (ENTRY, MIDDLE, LEAF)


@pytest.mark.parametrize("change", ["signature", "source"])
def test_another_numba_compiles_as_it_does(change):
    """install() wraps numba's methods only where they are the ones it was written for."""
    from numba.core import caching, codegen, cpu

    if change == "signature":
        def finalize(self, strict=True):  # a numba whose finalize takes an argument
            return None
    else:
        def finalize(self):  # a numba that links otherwise
            return self._link_everything()
    numbas = [inspect.unwrap(method) for method in (cpu.CPUContext.get_executable, codegen.CPUCodeLibrary.finalize,
                                                    caching.Cache.save_overload)]  # install() may have wrapped them
    assert linking._expected(*numbas)
    assert not linking._expected(numbas[0], finalize, numbas[2])
