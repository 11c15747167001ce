"""csim.linkage.lambdacache: a linkage's numeric functions derived once, read back after."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from csim.linkage.lambdacache import cached_lambdify, linkage_key


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CSIM_CACHE_DIR", str(tmp_path))
    return tmp_path / "linkage"


def _make(calls):
    def make():
        calls.append(1)
        q, p = sp.symbols("q_A p_1", real=True)
        return [[q], [p]], [sp.Matrix([[sp.sin(q) * p, q**2]]), sp.Matrix(2, 0, [])]
    return make


def test_the_source_is_derived_once_then_read_back(cache):
    calls = []
    first = cached_lambdify("k1", "kinematics", _make(calls))
    assert calls == [1] and (cache / "k1_kinematics.py").is_file()
    second = cached_lambdify("k1", "kinematics", _make(calls))
    assert calls == [1]  # no symbolic work the second time
    a, b = first([0.3], [2.0]), second([0.3], [2.0])
    np.testing.assert_array_equal(a[0], b[0])
    assert b[0][0, 0] == pytest.approx(2.0 * np.sin(0.3)) and b[1].shape == (2, 0)


def test_a_damaged_file_is_derived_again_and_no_key_caches_nothing(cache):
    calls = []
    cached_lambdify("k2", "f", _make(calls))
    (cache / "k2_f.py").write_text("def broken(:\n")
    again = cached_lambdify("k2", "f", _make(calls))
    assert calls == [1, 1] and again([0.0], [1.0])[0][0, 1] == 0.0
    cached_lambdify(None, "f", _make(calls))
    assert calls == [1, 1, 1] and sorted(p.name for p in cache.iterdir()) == ["k2_f.py"]


def test_a_cached_source_that_needs_a_name_numpy_lacks_is_derived_again(cache):
    """A cached source runs in numpy's names, made without sympy (lambdacache._numpy_namespace); one that
    reads a name outside them (a printer's helper of another sympy version) is derived again, not run."""
    calls = []
    cached_lambdify("k3", "f", _make(calls))
    text = (cache / "k3_f.py").read_text()
    (cache / "k3_f.py").write_text(text.replace("sin(", "sympy_only_sin("))
    again = cached_lambdify("k3", "f", _make(calls))
    assert calls == [1, 1] and again([0.3], [2.0])[0][0, 0] == pytest.approx(2.0 * np.sin(0.3))


def test_reading_a_cached_source_imports_no_sympy(cache):
    """The 0.2 s of sympy's import is not spent on a cache hit (a warm run's functions: reactions, watch,
    drives); the cache's key needs sympy's version only, from its package's metadata."""
    import os
    import subprocess
    import sys

    cached_lambdify("k4", "f", _make([]))
    code = ("import sys; from csim.linkage.lambdacache import cached_lambdify, linkage_key; "
            "f = cached_lambdify('k4', 'f', lambda: 1 / 0); linkage_key({'links': []}); "
            "print(f([0.3], [2.0])[0][0, 0], 'sympy' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "CSIM_CACHE_DIR": str(cache.parent)}).stdout.split()
    assert float(out[0]) == pytest.approx(2.0 * np.sin(0.3)) and out[1] == "False"


def test_the_key_follows_the_tables_not_the_parameter_values():
    base = {"links": [{"link": 0}], "couplings": [], "parameters": {"l": 0.1}}
    assert linkage_key(base) == linkage_key({**base, "parameters": {"l": 0.2}})
    assert linkage_key(base) != linkage_key({**base, "parameters": {"l2": 0.1}})
    assert linkage_key(base) != linkage_key({**base, "gravity": [0, -9.81, 0]})


# ---------------------------------------------------------------------------------------
# the linkage itself (build_linkage through cached_build) and the constraint watch
# ---------------------------------------------------------------------------------------
def _bricard():
    from conftest import CONFIGS

    from csim.case import parse_yaml

    path = CONFIGS / "iftomm" / "a04_bricard.yaml"
    return parse_yaml(path.read_text(), str(path))


def _counting_builds(monkeypatch):
    import csim.linkage.model as model

    calls, real = [], model._build_linkage

    def counted(*args):
        calls.append(1)
        return real(*args)
    monkeypatch.setattr(model, "_build_linkage", counted)
    return calls


def test_a_linkage_is_built_once_then_read_back_whole(cache, monkeypatch):
    from csim.linkage.model import build_linkage
    from csim.model.cache import _definition_key

    data = _bricard()
    calls = _counting_builds(monkeypatch)
    first = build_linkage(data["mechanism"], data.get("initial"))
    again = build_linkage(data["mechanism"], data.get("initial"))
    assert calls == [1] and len(list(cache.glob("*_linkage.pickle"))) == 1
    assert again is not first and again.build_key == first.build_key != ""
    assert [e.status for e in again.reduction.equations] == [e.status for e in first.reduction.equations]
    # the definition read back prints to the key it was filed with (the key is not just carried over)
    assert _definition_key(again.definition) == _definition_key(first.definition) == again.definition_key
    terms_a, terms_b = first.definition.recursive(), again.definition.recursive()  # (a partial now: picklable)
    assert [str(e) for e in terms_a.phi] == [str(e) for e in terms_b.phi]


def test_other_values_or_start_build_again_a_damaged_file_too(cache, monkeypatch):
    from csim.linkage.model import build_linkage

    data = _bricard()
    calls = _counting_builds(monkeypatch)
    build_linkage(data["mechanism"], data.get("initial"))
    other = {**data["mechanism"], "parameters": {**(data["mechanism"].get("parameters") or {}), "extra_p": 1.0}}
    build_linkage(other, data.get("initial"))                             # parameters as written: a new key
    build_linkage(data["mechanism"], {"guess": {"q_j1": 0.2}})             # another start: a new key
    assert calls == [1, 1, 1] and len(list(cache.glob("*_linkage.pickle"))) == 3
    for path in cache.glob("*_linkage.pickle"):
        path.write_bytes(b"not a pickle")
    build_linkage(data["mechanism"], data.get("initial"))
    assert calls == [1, 1, 1, 1]
    monkeypatch.setenv("CSIM_LINKAGE_CACHE", "0")
    build_linkage(data["mechanism"], data.get("initial"))
    assert calls == [1, 1, 1, 1, 1]


def test_the_constraint_watch_read_back_equals_the_one_derived(cache):
    import dataclasses

    from csim.linkage.model import build_linkage
    from csim.linkage.plan import LightLinkage

    data = _bricard()
    linkage = build_linkage(data["mechanism"], data.get("initial"))

    def watch(key: str):
        # at the tables' parameter values (none of the definition's given)
        plan = dataclasses.replace(linkage.plan(), build_key=key)
        return LightLinkage(plan, lambda: linkage, linkage).constraint_watch([], np.zeros(0))

    derived = watch("")                                            # no key: derived here
    assert not list(cache.glob("*_watch_*.py"))
    filed = watch(linkage.build_key)                               # derived, then filed
    read = watch(linkage.build_key)                                # read back
    assert {p.name.split("_", 1)[1] for p in cache.glob("*_watch_*.py")} == \
        {"watch_phi.py", "watch_pattern.py", "watch_jac.py", "watch_gamma.py"}
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, qd = rng.normal(size=5), rng.normal(size=5)
        for watch in (filed, read):
            np.testing.assert_array_equal(watch.phi(q), derived.phi(q))
            np.testing.assert_array_equal(watch.phi_q(q), derived.phi_q(q))
            np.testing.assert_array_equal(watch.gamma_removed(q, qd), derived.gamma_removed(q, qd))
    assert derived.removed.size == 1 and np.any(derived.phi_q(q) != 0)


def test_the_linkage_cache_keeps_the_newest(tmp_path):
    import os

    from csim.linkage.lambdacache import evict

    for i in range(5):
        path = tmp_path / f"k{i}_linkage.pickle"
        path.write_bytes(b"x")
        os.utime(path, (1000 + i, 1000 + i))
    (tmp_path / "k0_watch_phi.py").write_text("")
    evict(tmp_path, "*_linkage.pickle", 2)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["k0_watch_phi.py", "k3_linkage.pickle",
                                                          "k4_linkage.pickle"]


#: a short run on the Python path (no model compiled into the test's own cache)
QUICK = ["simulation.t_end=0.05", "simulation.backend=python"]


def test_a_cached_linkage_keeps_its_symbolic_parts_pickled_until_they_are_read(cache):
    # a warm run reads its linkage's plan back from the cache and never the symbolic linkage
    # (its functions are cached too); read back, its transforms, closure equations and
    # energies stay blobs of bytes until read
    from pathlib import Path

    from csim.case import load_case
    from csim.pipeline import run_case

    path = Path(__file__).resolve().parents[1] / "configs" / "fourbar_gravity.yaml"
    first = load_case(path, QUICK)
    assert run_case(first).ok  # every function derived and cached
    assert first.linkage.loaded
    built = first.linkage.full()
    assert "_deferred" not in vars(built.frames)
    case = load_case(path, QUICK)  # its plan read back from the cache
    assert run_case(case).ok
    assert not case.linkage.loaded, "a warm run read the symbolic linkage"
    read = case.linkage.full()  # read back from the cache
    deferred = [read.frames, read.definition, *read.reduction.equations]
    assert all("_deferred" in vars(x) for x in deferred)
    assert "links" not in vars(read.frames) and "kinetic_energy" not in vars(read.definition)
    # read: unpickled, the same expressions
    assert read.frames.links.keys() == built.frames.links.keys()
    for key, T in built.frames.links.items():
        assert sp.simplify(read.frames.links[key] - T) == sp.zeros(4, 4)
    assert read.frames.joint_frame(1, 1) == built.frames.joint_frame(1, 1)
    assert sp.simplify(read.definition.kinetic_energy - built.definition.kinetic_energy) == 0
    assert [str(e.expression) for e in read.reduction.equations] == \
        [str(e.expression) for e in built.reduction.equations]


#: in a fresh process: the namespace's names against sympy's star imports, and numpy's lazy submodules it loaded
NAMESPACE = """
import json, sys
import numpy
from csim.linkage.lambdacache import _numpy_namespace
ns = _numpy_namespace()
loaded = sorted(name for name in numpy.__numpy_submodules__ if f"numpy.{name}" in sys.modules)
ref = {}
exec("import numpy; from numpy import *; from numpy.linalg import *", ref)
print(json.dumps(dict(loaded=loaded, missing=sorted(set(ref) - set(ns) - {"__builtins__"}),
                      different=sorted(k for k in ns if k in ref and ns[k] is not ref[k]))))
"""


def test_the_numpy_namespace_is_sympys_without_numpys_submodules_not_loaded_yet():
    """What a generated function is executed in: sympy's names for "numpy", except the submodules that numpy
    loads on first use (numpy.testing, numpy.f2py, numpy.random, ...: 45 ms of a warm run, read by none)."""
    import json
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", NAMESPACE], capture_output=True, text=True, check=True)
    out = json.loads(done.stdout.splitlines()[-1])
    import numpy
    lazy = set(numpy.__numpy_submodules__)
    assert set(out["loaded"]) <= {"linalg", "lib", "exceptions", "dtypes"}, out  # (numpy's own import loads these)
    assert "testing" not in out["loaded"] and "random" not in out["loaded"]
    assert set(out["missing"]) <= lazy and "testing" in out["missing"], out
    assert out["different"] == [], out
