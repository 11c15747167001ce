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
