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


def test_the_key_follows_the_tables_not_the_parameter_values():
    base = {"links": [{"link": 0}], "couplings": [], "parameters": {"l": 0.1}}
    assert linkage_key(base) == linkage_key({**base, "parameters": {"l": 0.2}})
    assert linkage_key(base) != linkage_key({**base, "parameters": {"l2": 0.1}})
    assert linkage_key(base) != linkage_key({**base, "gravity": [0, -9.81, 0]})
