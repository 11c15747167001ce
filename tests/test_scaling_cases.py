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


# ---------------------------------------------------------------------------------------
# the large families through the dynamics, against independent checks
# ---------------------------------------------------------------------------------------
def numeric(doc):
    """The case and its generated Python model functions (csim.model.numeric)."""
    from csim.model import build_numeric_model

    case = validate_case(doc)
    return case, build_numeric_model(case.mechanism, use_cache=False)


def loop_geometry(doc, q):
    """Joint points J0..J(n-1) of an N-bar loop by planar geometry: bar i from J(i-1) at the
    absolute angle theta_i = q_J0 + ... + q_J(i-1) (relative angles), and the ground pivot of
    the cut joint J(n-1)."""
    bars = doc["mechanism"]["links"][1:]
    lengths = [bar["joints"][1][1][0] for bar in bars]
    theta = np.cumsum(q)
    points = [np.zeros(2)]
    for length, angle in zip(lengths, theta):
        points.append(points[-1] + length * np.array([np.cos(angle), np.sin(angle)]))
    ground = doc["mechanism"]["links"][0]["joints"][1][1]
    return np.array(points), np.array(ground[:2], dtype=float)


def lagrange_residual(model, q, qd, par, h=1e-6):
    """C qd - [(d(M qd)/dq) qd - dT/dq] by central differences of M and T (Lagrange's equations)."""
    m = q.size
    dMqd = np.zeros(m)
    dT = np.zeros(m)
    for k in range(m):
        e = np.zeros(m)
        e[k] = h
        dMqd += (model.mass(q + e, par) @ qd - model.mass(q - e, par) @ qd) / (2 * h) * qd[k]
        dT[k] = (model.kinetic_energy(q + e, qd, par) - model.kinetic_energy(q - e, qd, par)) / (2 * h)
    return model.velocity_terms(q, qd, par) - (dMqd - dT)


def check_constraint_terms(model, q, qd, par, h=1e-4):
    """Phi_q by central differences of Phi, and gamma = -d^2/dt^2 Phi(q + t qd) at t = 0."""
    m = q.size
    J = np.array([(model.phi(q + h * e, par) - model.phi(q - h * e, par)) / (2 * h) for e in np.eye(m)]).T
    assert np.allclose(model.phi_q(q, par), J, atol=1e-8)
    second = (model.phi(q + h * qd, par) - 2 * model.phi(q, par) + model.phi(q - h * qd, par)) / h ** 2
    assert np.allclose(model.gamma(q, qd, par), -second, atol=1e-5 * max(1.0, np.max(np.abs(second))))


@pytest.mark.parametrize("n", [6, pytest.param(12, marks=pytest.mark.slow)])
def test_nbar_loop_model_against_planar_geometry(n):
    """A closed N-bar loop's joint points and closure Phi against hand-written planar geometry,
    Phi_q and gamma against differences of Phi, C qd against Lagrange's equations from M and T,
    T = qd.M.qd/2, and h against the potential m g y of the bars."""
    doc = nbar_loop(n)
    case, model = numeric(doc)
    names = case.mechanism.coordinate_names
    par = model.parameter_vector()
    rng = np.random.default_rng(n)
    for _ in range(3):
        q, qd = rng.uniform(-np.pi, np.pi, n - 1), rng.uniform(-2, 2, n - 1)
        points, ground = loop_geometry(doc, q)
        obs = dict(zip([o.name for o in case.mechanism.observables], model.observables(q, par)))
        for k in range(1, n - 1):  # J0 and J(n-1) are named on the ground first: fixed, not observed
            assert np.allclose([obs[f"J{k}_x"], obs[f"J{k}_y"]], points[k], atol=1e-13)
        # the cut joint: J(n-1) of the last bar on the ground pivot
        assert np.allclose(np.sort(np.abs(model.phi(q, par))), np.sort(np.abs(points[-1] - ground)), atol=1e-13)
        check_constraint_terms(model, q, qd, par)
        assert np.allclose(lagrange_residual(model, q, qd, par), 0, atol=1e-7)
        assert np.isclose(model.kinetic_energy(q, qd, par), 0.5 * qd @ model.mass(q, par) @ qd, rtol=1e-12)
        # V = sum m g y_c over the bars, y_c at mid-length
        masses = [bar["mass"] for bar in doc["mechanism"]["links"][1:]]
        V = sum(mass * 9.81 * (points[i][1] + points[i + 1][1]) / 2 for i, mass in enumerate(masses))
        assert np.isclose(model.potential_energy(q, par), V, rtol=1e-12)
    assert names[0] == "q_J0"


@pytest.mark.parametrize("n", [4, pytest.param(16, marks=pytest.mark.slow)])
def test_fourbar_chain_model_terms(n):
    """A chain of four-bar loops: Phi_q and gamma against differences of Phi, C qd against
    Lagrange's equations from M and T."""
    case, model = numeric(fourbar_chain(n))
    par = model.parameter_vector()
    rng = np.random.default_rng(n)
    q, qd = rng.uniform(-np.pi, np.pi, 2 * n + 1), rng.uniform(-2, 2, 2 * n + 1)
    check_constraint_terms(model, q, qd, par)
    assert np.allclose(lagrange_residual(model, q, qd, par), 0, atol=1e-7)


@pytest.mark.parametrize("n", [4, pytest.param(8, marks=pytest.mark.slow), pytest.param(32, marks=pytest.mark.slow)])
def test_fourbar_chain_under_gravity_conserves_energy(n):
    """A long chain released at rest under gravity (compiled model functions): T + V stays
    constant and the loops stay closed."""
    from csim.pipeline import run_case

    doc = fourbar_chain(n)
    doc["simulation"] = {"t_end": 0.5, "rtol": 1e-10, "atol": 1e-10}
    result = run_case(validate_case(doc))
    assert result.ok, result.message
    assert np.ptp(result.q[:, 0]) > 0.1                       # it moves
    assert result.energy_error_relative < 1e-7
    assert result.max_phi < 1e-8
