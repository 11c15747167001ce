"""The generated mechanisms of the scaling benchmark (bench/scaling_cases.py) are valid cases
that assemble at their initial values, with the sizes and DOF their docstrings state.
Small sizes only (the linkage analysis, no derivation of the dynamics)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from csim.case import validate_case

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from scaling_cases import fourbar_chain, nbar_loop


def residual(doc, case):
    """max |Phi| at the generator's initial values (its closed-form geometry)."""
    mech = case.mechanism
    values = {**doc["initial"]["q"], **doc["initial"]["guess"]}
    q = [values[str(s)] for s in mech.coordinates]
    phi = sp.lambdify([mech.coordinates], sp.Matrix(mech.constraints), "numpy")
    return float(np.max(np.abs(np.asarray(phi(q), dtype=float))))


@pytest.mark.parametrize("n", [1, 2, 3])
def test_fourbar_chain(n):
    doc = fourbar_chain(n)
    case = validate_case(doc)
    assert len(case.mechanism.coordinates) == 2 * n + 1
    assert len(case.mechanism.constraints) == 2 * n  # 1 DOF
    assert list(doc["initial"]["q"]) == ["q_crank"]
    assert residual(doc, case) < 1e-12


@pytest.mark.parametrize("n", [4, 5, 6])
def test_nbar_loop(n):
    doc = nbar_loop(n)
    case = validate_case(doc)
    assert len(case.mechanism.coordinates) == n - 1
    assert len(case.mechanism.constraints) == 2  # n - 3 DOF
    assert len(doc["initial"]["q"]) == n - 3
    assert residual(doc, case) < 1e-12


def test_nbar_loop_needs_four_links():
    with pytest.raises(ValueError):
        nbar_loop(3)
