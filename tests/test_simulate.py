"""The driver: output sampling, event bookkeeping, failures with partial results."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import qr_case

from csim.pipeline import build_system, initial_state, run_case
from csim.solver.simulate import integrate, output_times


def test_output_times_end_exactly_on_t_end():
    t = output_times(1.0, 0.3)
    np.testing.assert_allclose(t, [0.0, 0.3, 0.6, 0.9, 1.0])
    t = output_times(1.0, 0.1)
    assert t.size == 11 and t[-1] == 1.0


def test_run_samples_the_requested_grid():
    res = run_case(qr_case("simulation.t_end=0.5", "output.dt=0.05"))
    np.testing.assert_allclose(res.t, np.linspace(0, 0.5, 11), atol=1e-12)
    assert res.q.shape == (11, 3) and res.lam.shape == (11, 2) and res.work.shape == (11, 2)


def test_cutting_force_acts_only_in_its_window_on_the_backward_stroke():
    res = run_case(qr_case("simulation.t_end=2.0", "output.dt=0.002"))
    x, v = res.observables[:, 0], res.observable_rates[:, 0]
    F = res.loads[:, 1]
    on = F > 0
    assert on.any() and (~on).any()
    # well inside the conditions the force is on; well outside, off
    assert np.all(F[(v < -0.5) & (x > -3.9) & (x < 1.1)] == 2e5)
    assert np.all(F[(v > 0.5) | (x < -4.1) | (x > 1.3)] == 0.0)


def test_each_event_flips_a_labelled_condition():
    res = run_case(qr_case("simulation.t_end=1.0"))
    assert len(res.event_times) == len(res.event_labels) > 0
    assert np.all(np.diff(res.event_times) > 0)
    assert all(label.startswith("cutting_force: ") for label in res.event_labels)


def test_blow_up_is_reported_and_the_partial_result_kept():
    # no cutting force: the torque spins the crank up; a huge RK4 step then explodes
    res = run_case(qr_case("loads.cutting_force=0", "simulation.integrator=RK4", "simulation.step=0.2",
                           "simulation.t_end=20", "simulation.max_phi=1e300"))
    assert res.status == "failed"
    assert "non-finite" in res.message or "singular" in res.message
    assert 0 < res.t.size < output_times(20, 0.005).size
    assert np.all(np.isfinite(res.q))


def test_interior_samples_catch_zeros_crossed_twice_within_a_step():
    # at a loose tolerance the steps are long enough to step over the velocity sign's
    # double zero near the ram's dead centre; checking the dense output inside steps finds them
    loose = ("simulation.rtol=1e-3", "simulation.atol=1e-3")
    end_only = run_case(qr_case(*loose, "simulation.event_samples=0"))
    sampled = run_case(qr_case(*loose))
    tight = run_case(qr_case())
    assert len(end_only.event_times) < len(sampled.event_times) <= len(tight.event_times)


def test_non_finite_derivatives_fail_at_once():
    res = run_case(qr_case("initial.qd.q1=1e200"))
    assert res.status == "failed" and "non-finite right-hand side at t = 0 s" in res.message


def test_runs_far_too_long_for_their_settings_stop_at_max_steps():
    res = run_case(qr_case("simulation.max_steps=50"))
    assert res.status == "failed" and "max_steps = 50" in res.message
    assert 0 < res.t[-1] < 5.0


def test_chattering_law_fails_after_max_events():
    res = run_case(qr_case("simulation.max_events=3", "simulation.t_end=2"))
    assert res.status == "failed" and "max_events = 3" in res.message
    assert res.t[-1] < 2.0


def test_progress_is_reported_with_increasing_times():
    case = qr_case("simulation.t_end=0.5")
    system = build_system(case)
    seen = []
    integrate(system, initial_state(case, system), case.integration_settings(), progress=seen.append)
    assert len(seen) > 3 and seen == sorted(seen) and seen[-1] <= 0.5


def test_nfev_counts_every_evaluation():
    res = run_case(qr_case("simulation.integrator=RK4", "simulation.step=0.01", "simulation.t_end=0.1",
                           "loads.cutting_force=0"))
    # one initial evaluation plus four per step, ten steps
    assert res.nfev == 1 + 4 * 10


def _poisoned(n_bad):
    """y' = -y, except that evaluation number ``n_bad`` returns NaN (a wild trial iterate)."""
    calls = []

    def fun(t, y):
        calls.append(t)
        return np.full_like(y, np.nan) if len(calls) == n_bad else -y
    return fun


def test_implicit_integrators_step_past_a_non_finite_trial_evaluation():
    from csim.solver.integrators import make_integrator
    from csim.solver.simulate import _Counter
    for name in ("Radau", "BDF"):
        counter = _Counter(_poisoned(6), implicit=True)
        solver = make_integrator(name, counter, 0.0, np.array([1.0]), 1.0, rtol=1e-8, atol=1e-10)
        while solver.status == "running":
            solver.step()
        assert solver.status == "finished", name
        assert counter.non_finite_at is not None  # the NaN was seen, and rejected
        np.testing.assert_allclose(solver.y, [np.exp(-1.0)], rtol=1e-6, err_msg=name)


def test_explicit_integrators_stop_at_a_non_finite_evaluation():
    import pytest

    from csim.errors import SimulationFailure
    from csim.solver.simulate import _Counter
    counter = _Counter(_poisoned(1), implicit=False)
    with pytest.raises(SimulationFailure, match="blow-up: non-finite right-hand side at t = 0"):
        counter(0.0, np.array([1.0]))


# --------------------------------------------------------------------------- chatter (issue 13)

#: evaluations of one DOP853 restart at a pile-up: f at the restart, one for the first step's
#: size, 12 for the step, 3 for its dense output (where the event is located)
DOP853_RESTART = 17
STALL = ("loads.torque=160000",)  # a drive too weak to carry the ram through the cut: it stalls at 2.19693 s
VELOCITY_SIGN = "cutting_force: ds/dt = 0 (velocity sign)"


def test_a_chattering_law_fails_fast_naming_it():
    res = run_case(qr_case(*STALL, "simulation.backend=python"))
    assert res.status == "failed"
    assert res.message.startswith(f"chattering load law: {VELOCITY_SIGN} switched back and forth 20 times")
    assert "Filippov" in res.message and "at t = 2.19693 s" in res.message
    # 23 regular events, then 20 at one instant (before: 100,001 events and 1.7 million evaluations)
    times = np.array(res.event_times)
    assert times.size == 23 + 20 and np.all(times[23:] == times[-1])
    assert res.event_labels[23:] == [VELOCITY_SIGN] * 20
    # bounded work: the run up to the pile-up, plus one restart per piled event
    upto = run_case(qr_case(*STALL, "simulation.backend=python", f"simulation.t_end={times[23]}"))
    assert upto.ok and len(upto.event_times) == 23
    assert res.nfev <= upto.nfev + 20 * DOP853_RESTART


@pytest.mark.parametrize("overrides", [
    ("simulation.integrator=RK45",),
    ("simulation.integrator=Radau",),
    ("formulation.method=elimination",),
    ("stabilization.method=minimal", "simulation.rtol=1e-6", "simulation.atol=1e-6"),  # was 271 s to fail
])
def test_chatter_is_caught_on_every_python_path(overrides):
    res = run_case(qr_case(*STALL, "simulation.backend=python", *overrides))
    assert res.status == "failed" and res.message.startswith(f"chattering load law: {VELOCITY_SIGN}")
    assert len(res.event_times) == 23 + 20


def test_the_number_of_piled_events_is_a_setting():
    res = run_case(qr_case(*STALL, "simulation.backend=python", "simulation.chatter_events=5"))
    assert "switched back and forth 5 times" in res.message and len(res.event_times) == 23 + 5
    # above max_events, chatter_events leaves the run to max_events
    res = run_case(qr_case(*STALL, "simulation.backend=python", "simulation.chatter_events=50",
                           "simulation.max_events=30"))
    assert "simulation.max_events = 30" in res.message


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_the_default_run_is_unchanged_by_chatter_detection(backend, reference):
    # the 67 events of the independent reference, and the evaluations counted before the detector
    # existed (10,864, README "Speed"): it reads the event times only, and never trips here
    res = run_case(qr_case(f"simulation.backend={backend}"))
    assert res.ok and res.backend == backend
    np.testing.assert_allclose(res.event_times, reference["events"], atol=1e-6)
    assert res.nfev == 10_864


def test_a_drift_failure_past_the_last_sample_names_no_equation_the_samples_do_not_show():
    """RK4 with a 1 s step fails the max_phi check at the end of its first step, past every
    sample: the message gives the failing |Phi| and does not name an equation whose
    recorded residual is round-off (it used to say 'the largest residual is Phi_1's (2.2e-16)')."""
    from conftest import CONFIGS

    from csim.case import load_case
    from csim.pipeline import run_case

    result = run_case(load_case(CONFIGS / "quick_return.yaml", ["simulation.integrator=RK4", "simulation.step=1"]))
    assert result.status == "failed" and result.failure == "drift", result.message
    assert "exceeds simulation.max_phi" in result.message and "largest residual" not in result.message
