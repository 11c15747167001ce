"""Fixed steps against the stabilizers' constraint-error dynamics (csim/solver/stability.py).

The stability function is checked against the closed-form polynomial and against one step
of csim's own RK4 on y' = lambda y; the bounds against their closed forms (the real root of
x^3 - 4 x^2 + 12 x - 24 = 0 on the real axis, 2 sqrt(2) on the imaginary axis); the
methods' error modes against the eigenvalues of the full system's Jacobian, taken by finite
differences at a consistent state of the pendulum. Runs show the warning before the run
and the failure message naming the product.
"""
from __future__ import annotations

import cmath
import math

import numpy as np
import pytest
from conftest import CONFIGS, invoke

from csim.case import load_case
from csim.physics.status import MAX_PHI
from csim.physics.switching import SWITCHING_NAMES, slope_at_zero, switch
from csim.pipeline import build_system, initial_state
from csim.solver.failures import failure_message
from csim.solver.methods import make_stabilizer
from csim.solver.settings import IntegrationSettings
from csim.solver.stability import (
    MARGIN,
    inside,
    ray_bound,
    real_axis_bound,
    stability_cause,
    stability_function,
    stability_warnings,
)


def cardano_rk4_bound() -> float:
    """R(-x) = 1 for x != 0 <=> x^3 - 4 x^2 + 12 x - 24 = 0; its one real root by Cardano."""
    a, b, c, d = 1.0, -4.0, 12.0, -24.0
    p = (3 * a * c - b * b) / (3 * a * a)
    q = (2 * b**3 - 9 * a * b * c + 27 * a * a * d) / (27 * a**3)
    root = math.sqrt(q * q / 4 + p**3 / 27)
    return np.cbrt(-q / 2 + root) + np.cbrt(-q / 2 - root) - b / (3 * a)


def test_rk4_real_axis_bound_is_the_closed_form_2_7853():
    bound = cardano_rk4_bound()
    assert bound == pytest.approx(2.7853, abs=1e-4)
    assert real_axis_bound("RK4") == pytest.approx(bound, rel=1e-12)
    assert inside("RK4", -(bound - 1e-6)) and not inside("RK4", -(bound + 1e-6))


def test_rk4_imaginary_axis_bound_is_2_sqrt_2():
    # |R(iy)|^2 = 1 - y^6/72 + y^8/576 <= 1 up to y = sqrt(8)
    assert ray_bound("RK4", 1j) == pytest.approx(math.sqrt(8.0), rel=1e-9)


@pytest.mark.parametrize("z", [-1.0, -2.5 + 0.5j, 0.3 - 2j, -3.0, 1.5j])
def test_stability_function_is_the_rk4_polynomial_and_one_step_of_csims_rk4(z):
    polynomial = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    assert stability_function("RK4", z) == pytest.approx(polynomial, rel=1e-14)
    from csim.solver.rk4 import RK4

    # y' = lambda y as a real 2-vector (re, im); one step of h = 0.1 multiplies y0 by R(h lambda)
    h = 0.1
    lam = z / h
    A = np.array([[lam.real, -lam.imag], [lam.imag, lam.real]]) if isinstance(lam, complex) else \
        np.array([[lam, 0.0], [0.0, lam]])
    solver = RK4(lambda t, y: A @ y, 0.0, np.array([1.0, 0.0]), 1.0, step=h)
    solver.step()
    assert complex(*solver.y) == pytest.approx(polynomial, rel=1e-13)


@pytest.mark.parametrize("name", list(SWITCHING_NAMES))
def test_switching_slope_at_zero_matches_a_finite_difference(name):
    width = {None: 1.0, "eps": 1e-3, "c": 250.0}[SWITCHING_NAMES[name]]
    code = list(SWITCHING_NAMES).index(name)
    ds = 1e-9
    slope = (switch(code, ds, width) - switch(code, -ds, width)) / (2 * ds)
    if name == "sgn":
        assert slope_at_zero(name, None) == math.inf and slope > 1e8
    else:
        assert slope_at_zero(name, width) == pytest.approx(slope, rel=1e-6)


def jacobian_eigenvalues(*overrides: str) -> np.ndarray:
    """Eigenvalues of the pendulum's right-hand side, by central differences at a consistent state."""
    case = load_case(CONFIGS / "pendulum.yaml", ["initial.q_offset={}", "simulation.backend=python", *overrides])
    system = build_system(case)
    y0 = initial_state(case, system)
    mode = system.mode_at(y0)
    n, e = y0.size, 1e-7
    J = np.column_stack([(system.rhs(0.0, y0 + e * np.eye(n)[i], mode) - system.rhs(0.0, y0 - e * np.eye(n)[i], mode))
                         / (2 * e) for i in range(n)])
    return np.linalg.eigvals(J)


def assert_modes_are_eigenvalues(method: str, settings: dict, *overrides: str, linear=lambda mode: True):
    modes = [m for m in make_stabilizer(method, settings).error_modes() if linear(m)]
    eig = jacobian_eigenvalues(f"stabilization.method={method}", *overrides)
    for mode in modes:
        lam = mode.gain * complex(mode.shape)
        assert np.min(np.abs(eig - lam)) < 1e-4 * abs(lam), (mode, eig)
    return [m.gain * complex(m.shape) for m in modes]


@pytest.mark.parametrize("d", [0.5, 1.0, 2.0])
def test_baumgarte_modes_are_the_eigenvalues_of_the_system(d):
    w = 300.0
    assert_modes_are_eigenvalues("baumgarte", dict(d=d, w=w), f"stabilization.d={d}", f"stabilization.w={w}")
    shapes = sorted((complex(m.shape) for m in make_stabilizer("baumgarte", dict(d=d, w=w)).error_modes()),
                    key=lambda s: (s.real, s.imag))
    roots = sorted(np.roots([1.0, 2 * d, 1.0]), key=lambda s: (s.real, s.imag))
    assert np.allclose(shapes, roots) or (d == 1.0 and np.allclose(shapes, [-1.0]))


@pytest.mark.parametrize("switching", ["tanh", "atan", "sat", "sqrt"])
def test_sliding_mode_modes_are_the_eigenvalues_of_the_system(switching):
    # linear at s = 0: -Lambda and -(K + k sw'(0)); -K alone is the rate once sw has saturated
    settings = dict(Lambda=50.0, K=200.0, k=0.5, c=300.0, eps=1 / 300, switching=switching)
    overrides = [f"stabilization.{k}={v}" for k, v in settings.items()]
    lams = assert_modes_are_eigenvalues("sliding_mode", settings, *overrides,
                                        linear=lambda mode: mode.keys != "stabilization.K")
    slope = {"tanh": 300.0, "atan": 600.0 / math.pi, "sat": 300.0, "sqrt": 300.0}[switching]
    assert sorted(lam.real for lam in lams) == pytest.approx([-(200.0 + 0.5 * slope), -50.0])


def test_complex_baumgarte_roots_use_the_region_not_the_interval():
    # d = 0.5: h lambda = w h (-0.5 +- 0.866 i); its own bound, computed on that ray
    method = make_stabilizer("baumgarte", dict(d=0.5, w=100.0))
    shape = complex(-0.5, math.sqrt(0.75))
    bound = ray_bound("RK4", shape)
    assert abs(stability_function("RK4", bound * shape)) == pytest.approx(1.0, abs=1e-9)
    assert stability_warnings(method, "RK4", 0.95 * MARGIN * bound / 100.0) == []
    (text,) = stability_warnings(method, "RK4", 1.05 * bound / 100.0)
    assert "stability region" in text and "for d = 0.5" in text


def test_adaptive_integrators_and_methods_without_gains_are_not_checked():
    assert stability_warnings(make_stabilizer("baumgarte", dict(w=1e6)), "DOP853", 1.0) == []
    assert stability_warnings(make_stabilizer("projection", {}), "RK4", 1.0) == []


def test_per_constraint_gains_name_the_constraint():
    method = make_stabilizer("baumgarte", dict(w=[10.0, 1000.0]))
    (text,) = stability_warnings(method, "RK4", 3e-3)
    assert "stabilization.w * simulation.step = 3 (constraint 2) lies outside" in text


def test_saturating_switching_beyond_the_bound_chatters_and_is_not_a_growth():
    method = make_stabilizer("sliding_mode", dict(K=10.0, k=1.0, c=4e3))
    (text,) = stability_warnings(method, "RK4", 1e-3)
    assert text.startswith("(stabilization.K + stabilization.k * stabilization.c) * simulation.step = 4.01 "
                           "lies outside RK4's stability interval (2.785)")
    assert "chatters" in text
    (text,) = stability_warnings(make_stabilizer("sliding_mode", dict(K=3500.0)), "RK4", 1e-3)
    assert text.startswith("stabilization.K * simulation.step = 3.5 lies outside") and "will grow" in text


def test_max_phi_message_names_the_product_only_when_it_is_the_cause():
    rk4 = IntegrationSettings(integrator="RK4", step=0.03)
    unstable = failure_message(MAX_PHI, 0.2, 1.0, rk4, make_stabilizer("baumgarte", dict(w=100.0)))
    assert "stabilization.w * simulation.step = 3 lies outside RK4's stability interval (2.785)" in unstable
    assert "tighten the tolerances" not in unstable
    drift = failure_message(MAX_PHI, 0.2, 1.0, rk4, make_stabilizer("baumgarte", dict(w=10.0)))
    # RK4 has no tolerances: the remedy is a shorter step
    assert "lower simulation.step" in drift and "tolerances" not in drift and "simulation.step =" not in drift
    adaptive = failure_message(MAX_PHI, 0.2, 1.0, IntegrationSettings(integrator="DOP853"),
                               make_stabilizer("baumgarte", dict(w=10.0)))
    assert "tighten the tolerances" in adaptive
    assert stability_cause(None, rk4) is None


PENDULUM_RK4 = ["--set", "stabilization.w=100", "--set", "simulation.integrator=RK4", "--set", "simulation.t_end=1"]


def test_a_run_beyond_the_bound_warns_and_fails_naming_the_product(tmp_path):
    result = invoke("run", CONFIGS / "pendulum.yaml", *PENDULUM_RK4, "--set", "simulation.step=0.03",
                    "-o", tmp_path / "out.h5")
    assert result.exit_code == 1, result.output
    product = "stabilization.w * simulation.step = 3 lies outside RK4's stability interval (2.785)"
    assert f"csim: warning: {product}" in result.output
    failure = result.output.split("csim: simulation failed:")[1]
    assert product in failure and "tighten the tolerances" not in failure


def test_a_run_inside_the_bound_does_not_warn(tmp_path):
    case = load_case(CONFIGS / "pendulum.yaml", [*PENDULUM_RK4[1::2], "simulation.step=0.02"])
    assert case.warnings == []
    result = invoke("run", CONFIGS / "pendulum.yaml", *PENDULUM_RK4, "--set", "simulation.step=0.02",
                    "-o", tmp_path / "out.h5")
    assert result.exit_code == 0, result.output
    assert "warning" not in result.output


def test_close_to_the_bound_warns_because_nonlinear_constraints_diverge_there():
    # measured: the pendulum with w = 100 diverges from w h = 2.6 on (0.93 of the bound 2.785)
    case = load_case(CONFIGS / "pendulum.yaml", [*PENDULUM_RK4[1::2], "simulation.step=0.027"])
    (text,) = case.warnings
    assert text.startswith("stabilization.w * simulation.step = 2.7 is close to the edge of RK4's stability interval")
    assert cmath.isclose(MARGIN * real_axis_bound("RK4"), 2.5068, rel_tol=1e-4)
