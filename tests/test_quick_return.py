"""The quick-return mechanism against the brief and an independent minimal-coordinate model."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import qr_case

from csim.pipeline import run_case
from csim.solver.initial import consistent_initial_state

P = dict(l1=1.5, l2=4.0, l3=1.9, h1=2.0, h2=4.0, a1=0.0, a2=2.0, a3=0.95, m1=4000.0, m2=100.0, m3=30.0,
         m4=5.0, m5=50.0, J1=4000.0, J2=100.0, J3=10.0, J4=0.05, g=9.81)


def brief_terms(q, qd):
    """The brief's (corrected) formulas, typed in as the reference."""
    q1, q2, q3 = q
    _, qd2, qd3 = qd
    p = P
    c = p["m3"] * p["l2"] * p["a3"] + p["m5"] * p["l2"] * p["l3"]
    M = np.array([
        [p["J1"] + p["m1"] * p["a1"] ** 2 + p["m4"] * p["l1"] ** 2, 0, 0],
        [0, p["J2"] + p["J4"] + p["m2"] * p["a2"] ** 2 + p["m3"] * p["l2"] ** 2 + p["m5"] * p["l2"] ** 2,
         c * np.cos(q2 - q3)],
        [0, c * np.cos(q2 - q3), p["J3"] + p["m3"] * p["a3"] ** 2 + p["m5"] * p["l3"] ** 2],
    ])
    Cqd = np.array([0, c * np.sin(q2 - q3) * qd3**2, -c * np.sin(q2 - q3) * qd2**2])
    h = p["g"] * np.array([(p["m1"] * p["a1"] + p["m4"] * p["l1"]) * np.cos(q1),
                           (p["m2"] * p["a2"] + p["m3"] * p["l2"]) * np.cos(q2), p["m3"] * p["a3"] * np.cos(q3)])
    phi = np.array([p["l1"] * np.sin(q1 - q2) + p["h1"] * np.cos(q2),
                    -p["l2"] * np.sin(q2) - p["l3"] * np.sin(q3) + p["h2"]])
    phi_q = np.array([
        [p["l1"] * np.cos(q1 - q2), -p["l1"] * np.cos(q1 - q2) - p["h1"] * np.sin(q2), 0],
        [0, -p["l2"] * np.cos(q2), -p["l3"] * np.cos(q3)],
    ])
    B = np.array([[1, 0], [0, -p["l2"] * np.sin(q2)], [0, -p["l3"] * np.sin(q3)]])
    return M, Cqd, h, phi, phi_q, B


@pytest.mark.parametrize("seed", range(5))
def test_derived_terms_equal_the_brief(qr_model, qr_par, seed):
    rng = np.random.default_rng(seed)
    q, qd = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-10, 10, 3)
    M, Cqd, h, phi, phi_q, B = brief_terms(q, qd)
    np.testing.assert_allclose(qr_model.mass(q, qr_par), M, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(qr_model.velocity_terms(q, qd, qr_par), Cqd, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(qr_model.gravity(q, qr_par), h, rtol=1e-13, atol=1e-9)
    np.testing.assert_allclose(qr_model.phi(q, qr_par), phi, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(qr_model.phi_q(q, qr_par), phi_q, rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(qr_model.load_matrix(q, qr_par), B, rtol=1e-13, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_gamma_is_minus_the_time_derivative_of_the_jacobian_times_qd(qr_model, qr_par, seed):
    # gamma = -(d/dt Phi_q) qd, with d/dt Phi_q = lim (Phi_q(q + eps qd) - Phi_q(q - eps qd)) / (2 eps)
    rng = np.random.default_rng(100 + seed)
    q, qd = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-10, 10, 3)
    eps = 1e-6
    dphi_q = (qr_model.phi_q(q + eps * qd, qr_par) - qr_model.phi_q(q - eps * qd, qr_par)) / (2 * eps)
    np.testing.assert_allclose(qr_model.gamma(q, qd, qr_par), -dphi_q @ qd, rtol=1e-7, atol=1e-6)


def test_kinetic_energy_is_half_qd_M_qd(qr_model, qr_par):
    rng = np.random.default_rng(7)
    q, qd = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-10, 10, 3)
    T = 0.5 * qd @ brief_terms(q, qd)[0] @ qd
    assert qr_model.kinetic_energy(q, qd, qr_par) == pytest.approx(T, rel=1e-13)


def test_initial_conditions_reproduce_the_brief(qr_model, qr_par):
    state = consistent_initial_state(qr_model, qr_par, {"q1": 3.0020}, {"q1": 6.2832}, {"q2": 2.0, "q3": 2.8})
    np.testing.assert_allclose(np.round(state.q, 4), [3.0020, 2.1628, 2.7751], atol=1e-12)
    np.testing.assert_allclose(np.round(state.qd, 4), [6.2832, 2.3656, -2.9769], atol=1e-12)
    assert np.max(np.abs(qr_model.phi(state.q, qr_par))) < 1e-12
    assert np.max(np.abs(qr_model.phi_q(state.q, qr_par) @ state.qd)) < 1e-12
    assert np.cos(state.q[2]) < 0


@pytest.fixture(scope="module")
def tight_runs():
    return {method: run_case(qr_case("simulation.rtol=1e-10", "simulation.atol=1e-10",
                                     f"formulation.method={method}", "simulation.integrator=DOP853"))
            for method in ("kkt", "elimination")}


@pytest.mark.parametrize("method", ["kkt", "elimination"])
def test_motion_agrees_with_minimal_coordinate_reference(tight_runs, reference, method):
    result = tight_runs[method]
    assert result.ok, result.message
    assert result.t[-1] == 5.0
    assert abs(result.q[-1, 0] - reference["q1"]) < 1e-6
    assert abs(result.qd[-1, 0] - reference["qd1"]) < 1e-5
    # the same switching instants, located to well within the motion tolerance
    assert len(result.event_times) == len(reference["events"])
    np.testing.assert_allclose(result.event_times, reference["events"], atol=1e-7)


@pytest.mark.parametrize("method", ["kkt", "elimination"])
def test_energy_balance(tight_runs, method):
    result = tight_runs[method]
    # T + V - (T0 + V0) - work of torque and cutting force, relative to the run's energy scale
    assert result.energy_error_relative < 1e-6
    # the cutting force really did work, so the check is not vacuous
    assert result.work[-1, 1] < -1e5 and result.work[-1, 0] > 1e5


def test_formulations_agree_with_each_other(tight_runs):
    kkt, eli = tight_runs["kkt"], tight_runs["elimination"]
    np.testing.assert_allclose(kkt.q, eli.q, atol=1e-6)
    np.testing.assert_allclose(kkt.lam, eli.lam, rtol=1e-5, atol=1e-2 * np.max(np.abs(kkt.lam)) * 1e-3)


def _rk4_crank_error(steps, reference_q1, *extra):
    errors = []
    for h in steps:
        res = run_case(qr_case("simulation.integrator=RK4", f"simulation.step={h}", "simulation.t_end=1.0", *extra))
        assert res.ok, res.message
        errors.append(abs(res.q[-1, 0] - reference_q1))
    return np.array(errors)


def test_rk4_converges_at_fourth_order_on_the_smooth_variant():
    extra = ("loads.cutting_force=0",)
    ref = run_case(qr_case("simulation.t_end=1.0", "simulation.rtol=1e-12", "simulation.atol=1e-12", *extra))
    steps = [0.004, 0.002, 0.001]
    errors = _rk4_crank_error(steps, ref.q[-1, 0], *extra)
    orders = np.log2(errors[:-1] / errors[1:])
    assert np.all(orders > 3.6), (errors, orders)
    assert np.all(orders < 4.4), (errors, orders)


def test_event_location_keeps_rk4_convergent_where_stepping_over_switches_does_not():
    ref = run_case(qr_case("simulation.t_end=1.0", "simulation.rtol=1e-12", "simulation.atol=1e-12"))
    steps = [0.004, 0.002, 0.001, 0.0005]
    located = _rk4_crank_error(steps, ref.q[-1, 0])
    stepped = _rk4_crank_error(steps, ref.q[-1, 0], "simulation.events=false")
    # located: fourth order over the whole range of steps
    assert np.log2(located[0] / located[-1]) / 3 > 3.5, located
    # stepped over: an O(h) error from each discontinuity, erratic in h, no high-order convergence
    assert np.all(stepped > 0.2 * np.array(steps)), stepped
    assert np.all(stepped > 100 * located), (stepped, located)
