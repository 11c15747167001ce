"""Where the methods fail, with numbers, and how csim reports it.

Each test states the mechanism of the failure and checks the figure that shows it:
drift growth without stabilization, Baumgarte turning the ODE stiff, chattering of the
exact sgn against its smooth replacements, the singular dependent block of the
elimination, and a load law that chatters. Measured values (this machine) are quoted in
the comments.
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS, qr_case

from csim.case import load_case
from csim.physics.partition import block_inverse
from csim.pipeline import build_system, run_case


def pendulum(*overrides):
    return run_case(load_case(CONFIGS / "pendulum.yaml", list(overrides)))


def test_drift_without_stabilization_grows_over_a_long_run():
    # 100 s of the pendulum at rtol = 1e-6 from a consistent start: integration error feeds
    # Phi'' = 0 with nothing to pull it back (measured: 8.7e-6 in [0, 10] s, 6.2e-4 in [90, 100] s)
    res = pendulum("stabilization.method=none", "initial.q_offset={}", "simulation.t_end=100",
                   "simulation.rtol=1e-6", "simulation.atol=1e-6", "output.dt=0.1")
    assert res.ok
    phi = np.abs(res.phi[:, 0])
    early, late = phi[res.t <= 10].max(), phi[res.t >= 90].max()
    assert late > 20 * early
    # and Baumgarte holds it down over the same run
    held = pendulum("stabilization.method=baumgarte", "initial.q_offset={}", "simulation.t_end=100",
                    "simulation.rtol=1e-6", "simulation.atol=1e-6", "output.dt=0.1")
    assert np.abs(held.phi[held.t >= 90]).max() < late / 100


@pytest.mark.slow
def test_quick_return_drift_grows_over_100_s():
    # the paper's mechanism: max |Phi| per 10 s window rises through the run
    res = run_case(qr_case("simulation.t_end=100", "simulation.rtol=1e-8", "simulation.atol=1e-8", "output.dt=0.05"))
    assert res.ok
    phi = np.abs(res.phi).max(axis=1)
    windows = [phi[(res.t >= a) & (res.t < a + 10)].max() for a in range(0, 100, 10)]
    assert windows[-1] > 10 * windows[0]


def test_baumgarte_beyond_rk4s_stability_bound_blows_up():
    # d = 1 puts both constraint eigenvalues at -w; RK4 is stable on the negative real axis
    # up to w h = 2.785 (tests/test_stability.py). Measured with w = 100: w h = 2.0 decays
    # (|Phi| in the last second 3.9e-4 from 8.7e-3), 2.5 holds, 2.6 and above diverge: the
    # frozen Jacobian is stable up to 2.785, so the nonlinear constraint pulls the bound down.
    w = 100.0
    stable = pendulum(f"stabilization.w={w}", "simulation.integrator=RK4", "simulation.step=0.02", "simulation.t_end=3")
    assert stable.ok
    assert np.abs(stable.phi[stable.t > 2]).max() < np.abs(stable.phi[0]).max() / 10
    unstable = pendulum(f"stabilization.w={w}", "simulation.integrator=RK4", "simulation.step=0.03",
                        "simulation.t_end=3")
    assert unstable.status == "failed"
    assert "simulation.max_phi" in unstable.message
    assert unstable.t[-1] < 0.5  # caught within a few steps, partial result kept
    assert unstable.t.size > 1


@pytest.mark.parametrize("backend", ["compiled", "python"])
def test_projections_max_phi_failure_says_it_was_before_the_projection(backend):
    # the check reads each step's end before it is projected (a far drift could be projected
    # onto another assembly); the samples are projected, so the message must say which it saw
    # (at rtol 1e-4 a step drifts 8e-6 m at t = 0.083 s while every sample holds 2e-16)
    res = run_case(qr_case("stabilization.method=projection", "simulation.max_phi=1e-7", "simulation.rtol=1e-4",
                           "simulation.atol=1e-4", "simulation.t_end=0.5", f"simulation.backend={backend}"))
    assert res.status == "failed" and res.failure == "drift"
    assert "before its projection" in res.message and "stabilize" not in res.message
    assert np.nanmax(np.abs(res.phi)) < 1e-12


def test_large_baumgarte_gain_makes_an_explicit_integrator_crawl():
    # RK45's step is bounded by stability, h ~ 3.3 / w, not by accuracy: the work grows with w
    # (measured: 536 evaluations at w = 10, 19,094 at w = 1e3)
    soft = pendulum("stabilization.w=10", "simulation.integrator=RK45", "simulation.rtol=1e-6", "simulation.atol=1e-8")
    stiff = pendulum("stabilization.w=1e3", "simulation.integrator=RK45", "simulation.rtol=1e-6",
                     "simulation.atol=1e-8")
    assert soft.ok and stiff.ok
    assert stiff.nfev > 20 * soft.nfev
    # the steps are held below RK45's stability bound on the real axis (about 3.3 / w)
    assert stiff.t[-1] / stiff.nsteps < 3.3 / 1e3 < soft.t[-1] / soft.nsteps


SLIDING = ["stabilization.method=sliding_mode", "stabilization.k=1", "stabilization.c=1e3", "stabilization.eps=1e-3",
           "simulation.t_end=2", "output.dt=0.001"]


def _late_s(res):
    s = res.phi_dot[:, 0] + 10.0 * res.phi[:, 0]  # Lambda = 10
    return s[res.t > 1.0]


def test_exact_sgn_chatters_where_its_smooth_replacements_do_not():
    # fixed step h = 1e-3, k = 1: with sgn each step kicks s by about k h, so s rattles at
    # that size instead of settling (measured max |s| after 1 s: 1.7e-4 with sgn, 4.8e-7 with
    # tanh(c s) and s / sqrt(s^2 + eps^2), whose slope k c h = 1 is inside RK4's stability)
    rk4 = ["simulation.integrator=RK4", "simulation.step=1e-3"]
    sgn = pendulum(*SLIDING, "stabilization.switching=sgn", *rk4)
    for smooth in ("tanh", "sqrt"):
        res = pendulum(*SLIDING, f"stabilization.switching={smooth}", *rk4)
        assert res.ok
        assert np.abs(_late_s(sgn)).max() > 100 * np.abs(_late_s(res)).max()


def test_exact_sgn_stalls_an_adaptive_integrator():
    # the right-hand side jumps by 2 k wherever s crosses zero: RK45 halves its step at every
    # crossing and crawls (measured: 42,373 steps for 1.5 s), the smooth tanh needs 6,704
    # evaluations for the 2 s; max_steps turns the crawl into a clear failure
    sgn = pendulum(*SLIDING, "stabilization.switching=sgn", "simulation.integrator=RK45", "simulation.rtol=1e-6",
                   "simulation.atol=1e-8", "simulation.max_steps=3000")
    assert sgn.status == "failed" and "simulation.max_steps" in sgn.message
    assert sgn.t[-1] < 1.0
    smooth = pendulum(*SLIDING, "stabilization.switching=tanh", "simulation.integrator=RK45", "simulation.rtol=1e-6",
                      "simulation.atol=1e-8", "simulation.max_steps=3000")
    assert smooth.ok and smooth.nsteps < 3000


def _block_condition(phi_q, dependent) -> float:
    """||Phi_q||_1 ||Phi_v^-1||_1 of the columns ``dependent`` (csim.physics.partition.block_inverse)."""
    r, m = phi_q.shape
    return block_inverse(np.ascontiguousarray(phi_q, dtype=float).ravel(), np.asarray(dependent, np.int64), r, m,
                         np.empty(r * r), np.empty(r, np.int64), np.empty(r), np.empty(r * r))


def test_fixed_partition_meets_the_rocker_dead_point():
    # With the rocker angle q2 independent, Phi_v = d Phi / d(q1, q3) is singular where the
    # rocker reverses (dq2/dq1 = 0): ||Phi_q|| ||Phi_v^-1|| passes 1e8 at t = 0.11 s and the
    # run stops, naming the cause. Chosen automatically, the crank stays independent and the
    # condition never exceeds 12.
    fixed = run_case(qr_case("formulation.method=elimination", "formulation.independent=[q2]", "simulation.t_end=1"))
    assert fixed.status == "failed"
    assert "dependent block Phi_v" in fixed.message and "formulation.independent" in fixed.message
    assert 0.05 < fixed.t[-1] < 0.2

    auto = run_case(qr_case("formulation.method=elimination", "simulation.t_end=1"))
    assert auto.ok
    system = build_system(qr_case())
    cond = {tuple(v): max(_block_condition(system.model.phi_q(q, system.par), v) for q in auto.q)
            for v in ([1, 2], [0, 2])}
    assert cond[(1, 2)] < 12  # crank independent: well conditioned throughout (measured 11.9)
    assert cond[(0, 2)] > 100  # rocker independent: near-singular within the first second


def test_a_stalling_drive_chatters_where_the_reference_has_no_classical_solution():
    # With the crank torque lowered to 160,000 N m the drive cannot carry the ram through the
    # cut: the independent 1-DOF reference stops the crank (v_D = 0) at t* = 2.1969254305 s inside
    # the force's window, where the velocity-sign condition g = -v_D has no consistent mode:
    # with the force on, dg/dt = -30.6 m/s^2 (v_D turns positive, the force goes off); with it
    # off, dg/dt = +49.3 m/s^2 (the torque drives the ram back, the force comes on). That is a
    # sliding (Filippov) state. csim's run stops there with chatter, naming that condition,
    # after 20 events at one instant (before: 100,000, and 1.7 million evaluations).
    from quick_return_reference import MinimalQuickReturn
    from scipy.integrate import solve_ivp

    ref = MinimalQuickReturn(torque=160000.0)
    _, y, _ = ref.solve(t_end=2.19)

    def stop(t, y, active):
        return ref.switching(y)[2]  # -v_D

    stop.terminal, stop.direction = True, -1.0
    sol = solve_ivp(ref.rhs, (2.19, 2.3), y[-1], method="DOP853", rtol=1e-12, atol=1e-12, events=stop, args=(True,))
    t_stall, y_stall = sol.t_events[0][0], sol.y_events[0][0]
    assert np.all(ref.switching(y_stall)[:2] > 0.3)  # well inside the window: only the velocity sign switches

    def g_rate(active):  # d(-v_D)/dt = -(x_D'' w^2 + x_D' w'), x_D'' by central differences
        q, w = y_stall
        h = 1e-6
        xdd = (ref._xD_prime(q + h) - ref._xD_prime(q - h)) / (2 * h)
        return -(xdd * w**2 + ref._xD_prime(q) * ref.rhs(t_stall, y_stall, active)[1])

    assert g_rate(True) < -10 and g_rate(False) > 10  # both modes drive g back to zero

    res = run_case(qr_case("loads.torque=160000"))
    assert res.status == "failed"
    assert res.message.startswith("chattering load law: cutting_force: ds/dt = 0 (velocity sign)")
    assert abs(res.event_times[-1] - t_stall) < 1e-8  # measured 4e-10 s
    assert len(res.event_times) == 23 + 20


@pytest.fixture
def blind_classifier(monkeypatch):
    """The message classifier (csim.result.failure_kind) files every message as "other": a kind a
    result still names came from where its failure was raised."""
    import csim.result

    monkeypatch.setattr(csim.result, "failure_kind", lambda message: "other")


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_the_failure_kind_comes_from_the_status_code_not_the_message(blind_classifier, backend):
    # every kind below is carried from where the failure was raised (its status code): with the
    # message classifier made blind, the results still name it
    runs = {
        "drift": pendulum("stabilization.w=100", "simulation.integrator=RK4", "simulation.step=0.03",
                          "simulation.t_end=3", f"simulation.backend={backend}"),
        "max steps": pendulum(*SLIDING, "stabilization.switching=sgn", "simulation.integrator=DOP853",
                              "simulation.rtol=1e-6", "simulation.atol=1e-8", "simulation.max_steps=300",
                              f"simulation.backend={backend}"),
    }
    for kind, res in runs.items():
        assert res.status == "failed" and res.backend == backend
        assert res.failure == kind, (kind, res.message)
    fixed = run_case(qr_case("formulation.method=elimination", "formulation.independent=[q2]", "simulation.t_end=1",
                             f"simulation.backend={backend}"))
    assert fixed.failure == "singular" and fixed.backend == backend


def test_an_rk4_step_below_the_resolution_of_t_is_the_same_kind_on_the_python_path(blind_classifier, monkeypatch):
    # the compiled RK4 reports RK4_RESOLUTION; the Python one fails inside the solver, and its kind
    # comes from the same table (its message is not read: the classifier is blinded)
    from csim.physics import status as st
    from csim.solver import rk4

    monkeypatch.setattr(rk4.RK4, "_step_impl", lambda self: (False, "step 0.01 s is below the resolution of t"))
    res = pendulum("simulation.integrator=RK4", "simulation.step=0.01", "simulation.backend=python")
    assert res.status == "failed" and res.failure == st.KINDS[st.RK4_RESOLUTION] == "step"


def test_a_kinematic_analysis_that_loses_assembly_carries_its_kind(blind_classifier):
    # the four-bar of tests/test_cli.py that closes at q_crank = 0 but not at pi
    res = run_case(load_case(CONFIGS / "fourbar.yaml", ["mechanism.parameters.a=0.3"]))
    assert res.run_kind == "kinematic" and res.status == "failed" and res.failure == "assembly"


def test_rk4_drift_names_the_step_and_the_summary_the_last_sample():
    from conftest import qr_case

    from csim.pipeline import run_case

    result = run_case(qr_case("simulation.integrator=RK4", "simulation.step=1"))
    assert result.failure == "drift" and "lower simulation.step" in result.message
    assert "tolerances" not in result.message
    items = dict(result.summary_items())
    assert "final time" not in items and items["last sample"] == "0 s"
