"""csim.fast.cache_load: cached machine code loads without numba's whole target; a miss still compiles.

The replacement of numba's ``Cache.load_overload`` initialises only the runtime. These tests
show that a warm compiled run then never loads the target's registries (the 0.4 s it saves),
that a function it loads from the cache and one it has to compile both run and give their
results (the compiler refreshes the target itself), and that a numba whose method is not
the one replaced keeps its own.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

from conftest import CONFIGS

from csim.fast import cache_load

WARM_RUN = """
import json, sys
from csim.case import load_case
from csim.pipeline import run_case
result = run_case(load_case(sys.argv[1], ["simulation.t_end=0.2", "simulation.backend=compiled"]))
print(json.dumps(dict(backend=result.backend, ok=result.ok, nfev=int(result.nfev),
                      registries="numba.np.arraymath" in sys.modules, blas="scipy.linalg" in sys.modules)))
"""


def _run(code: str, *args: str, env: dict | None = None) -> dict:
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=600,
                          env=env or dict(os.environ))
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_a_warm_run_loads_the_kernels_without_numbas_target():
    """The second run of the pendulum loads every function from the cache: no registry, no scipy.linalg."""
    first = _run(WARM_RUN, str(CONFIGS / "pendulum.yaml"))  # compiles what the cache may lack
    warm = _run(WARM_RUN, str(CONFIGS / "pendulum.yaml"))
    assert first["ok"] and warm["ok"] and warm["backend"] == "compiled" and warm["nfev"] == first["nfev"]
    assert not warm["registries"] and not warm["blas"], warm


MISS_THEN_HIT = """
import json, sys
sys.path.insert(0, sys.argv[1])
from csim.fast import cache_load
installed = cache_load.install()
import numpy as np
from probe import norm   # njit(cache=True): compiled on the first run, loaded on the second
value = float(norm(np.array([3.0, 4.0])))
print(json.dumps(dict(installed=installed, value=value, hits=sum(norm.stats.cache_hits.values()),
                      misses=sum(norm.stats.cache_misses.values()))))
"""

PROBE = '''
import math

import numpy as np
from numba import njit


@njit(cache=True)
def norm(x):
    y = x * x  # an array allocated: numba's runtime (NRT), which a cache load must initialise
    return math.sqrt(np.dot(x, x)) + 0.0 * y.sum()  # numpy's linear algebra: a registry that a cache load skips
'''


def test_a_miss_compiles_with_the_whole_target_and_a_hit_loads(tmp_path):
    """A function that needs a registry the replacement skips (np.dot, numba's linear algebra) compiles
    after install(), and the next process loads it from the cache and runs it."""
    (tmp_path / "probe.py").write_text(textwrap.dedent(PROBE))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    miss = _run(MISS_THEN_HIT, str(tmp_path), env=env)
    hit = _run(MISS_THEN_HIT, str(tmp_path), env=env)
    assert miss == dict(installed=True, value=5.0, hits=0, misses=1)
    assert hit == dict(installed=True, value=5.0, hits=1, misses=0)  # loaded through the replacement


def test_another_numba_keeps_its_own_method(monkeypatch):
    """A load_overload that is not the one replaced (another numba version) is left as it is."""
    from numba.core import caching

    def load_overload(self, sig, target_context):
        target_context.refresh()
        return None

    monkeypatch.setattr(caching.Cache, "load_overload", load_overload)
    monkeypatch.setattr(cache_load, "_STATE", {"installed": False, "tried": False})
    assert cache_load.install() is False
    assert caching.Cache.load_overload is load_overload


LINK_LATER = """
import json, sys
sys.path.insert(0, sys.argv[1])
from csim.fast import cache_load
installed = cache_load.install()
import numpy as np
from csim_fast_kernels_probe import norm, outer   # a module named as the kernels' copy: its bitcode deferred
x = np.array([3.0, 4.0])
first = float(norm(x))  # compiled on the first run; on the second loaded, its bitcode not parsed
library = norm.overloads[norm.signatures[0]].library
deferred = "_csim_bitcode" in vars(library)
value = float(outer(x))  # never cached: compiled in every process, linking in norm's library
print(json.dumps(dict(installed=installed, deferred_bitcode=cache_load._STATE["deferred"], first=first,
                      value=value, deferred=deferred, parsed_after_link=library._shared_module is not None,
                      hits=sum(norm.stats.cache_hits.values()))))
"""

LINKED_PROBE = PROBE + '''

@njit(cache=False)
def outer(x):
    return 2.0 * norm(x)
'''


def test_a_cached_library_is_parsed_only_when_a_later_compile_links_it(tmp_path):
    """The second process loads ``norm`` without parsing its bitcode, then compiles ``outer``, which
    links norm's library: the bitcode is parsed then, and ``outer`` computes 2 |x|."""
    (tmp_path / f"{cache_load.KERNELS_PREFIX}probe.py").write_text(textwrap.dedent(LINKED_PROBE))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    cold = _run(LINK_LATER, str(tmp_path), env=env)
    warm = _run(LINK_LATER, str(tmp_path), env=env)
    assert cold["installed"] and cold["deferred_bitcode"] and cold["hits"] == 0 and not cold["deferred"]
    assert warm["hits"] == 1 and warm["deferred"] and warm["parsed_after_link"]
    assert cold["value"] == warm["value"] == 10.0 and warm["first"] == 5.0


#: a function cached in a process where csim deferred the bitcode, loaded in one that cannot import csim
FILED_BY_CSIM = """
import sys
sys.path.insert(0, sys.argv[1])
from csim.fast import cache_load
assert cache_load.install() and cache_load._STATE["deferred"]
import numpy as np
from probe import norm
print(float(norm(np.array([3.0, 4.0]))))
"""
LOADED_WITHOUT_CSIM = """
import sys
sys.path.insert(0, sys.argv[1])
sys.modules["csim"] = None  # csim uninstalled
import numpy as np
from probe import norm
print(float(norm(np.array([3.0, 4.0]))), sum(norm.stats.cache_hits.values()))
"""


def test_only_the_kernels_copy_is_filed_in_csims_format(tmp_path):
    """A function of any other module cached in a csim process (a user's own, the core's) is in numba's own
    format: a process without csim loads it from the cache."""
    (tmp_path / "probe.py").write_text(textwrap.dedent(PROBE))
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    for code in (FILED_BY_CSIM, LOADED_WITHOUT_CSIM):
        done = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True,
                              timeout=600, env=env)
        assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["5.0", "1"]


def test_the_filed_bitcode_pickles_with_its_names():
    import pickle

    shared = cache_load.SharedBitcode(b"BC\xc0\xde", ["b", "a"])
    again = pickle.loads(pickle.dumps(shared, protocol=-1))
    assert type(again) is cache_load.SharedBitcode and bytes(again) == b"BC\xc0\xde"
    assert again.symbols == frozenset({"a", "b"})


def test_another_numba_keeps_its_own_unserialize(monkeypatch):
    """A ``CPUCodeLibrary._unserialize`` other than the one deferred (another numba version) is left as it is,
    and so are the methods that go with it."""
    from numba.core import codegen

    def _unserialize(cls, codegen, state):
        raise ValueError("another numba")

    library = codegen.CPUCodeLibrary
    replaced = classmethod(_unserialize)
    monkeypatch.setattr(library, "_unserialize", replaced)
    serialize, linking = library.serialize_using_object_code, library._get_module_for_linking
    assert cache_load._defer_bitcode() is False
    assert library.__dict__["_unserialize"] is replaced
    assert library.serialize_using_object_code is serialize and library._get_module_for_linking is linking
