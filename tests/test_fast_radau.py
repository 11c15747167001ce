"""The compiled Radau IIA (csim.fast.kernels) against scipy's Radau on the Python path, and the
compiled drive rows (csim.model.derive.with_drive_rows) against csim.solver.driven.

The compiled Radau is a port of scipy's: the same steps, Jacobians and LU factorizations on
the same problem, where the two differ only by round-off (its LU is csim's loop, scipy's is
LAPACK's). Its accuracy is checked against references that do not come from csim: the
quick-return mechanism's tight reference, and the flyball governor's rotating-frame
equations (tests/iftomm_reference.py).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIGS, qr_case

from csim.case import load_case
from csim.pipeline import build_system, initial_state, run_case
from csim.solver.simulate import integrate

pytest.importorskip("numba")

sys.path.insert(0, str(Path(__file__).parent))
from iftomm_reference import a05_motion

A05 = CONFIGS / "iftomm" / "a05_flyball_governor.yaml"


def test_the_coefficients_are_scipys():
    from scipy.integrate._ivp import common, radau

    from csim.physics import radau as ours

    for name in ("C", "E", "T", "TI", "TI_COMPLEX", "P"):
        assert np.array_equal(getattr(ours, name), getattr(radau, name)), name
    for name in ("MU_REAL", "MU_COMPLEX", "NEWTON_MAXITER"):
        assert getattr(ours, name) == getattr(radau, name), name
    for name in ("NUM_JAC_DIFF_REJECT", "NUM_JAC_DIFF_SMALL", "NUM_JAC_DIFF_BIG", "NUM_JAC_MIN_FACTOR",
                 "NUM_JAC_FACTOR_INCREASE", "NUM_JAC_FACTOR_DECREASE"):
        assert getattr(ours, name) == getattr(common, name), name


def _both_paths(*overrides):
    case = qr_case("simulation.integrator=Radau", *overrides)
    system = build_system(case)
    y0 = initial_state(case, system)
    from csim.fast import integrate_compiled

    return system, integrate_compiled(system, y0, case.integration_settings()), \
        integrate(system, y0, case.integration_settings())


@pytest.mark.parametrize("overrides", [(), ("simulation.max_step=0.003",), ("simulation.first_step=1e-4",),
                                       ("stabilization.method=baumgarte",), ("stabilization.method=minimal",)],
                         ids=["plain", "max_step", "first_step", "baumgarte", "minimal"])
def test_compiled_radau_takes_scipys_steps_one_for_one(overrides):
    """Up to the first cutting-force event (0.093 s): every step, Jacobian and LU factorization
    as scipy's Radau takes them, and the states equal to round-off. (Over a long run the two
    round-offs may part one accept/reject decision: the step sequence of either path moves as
    much under a change of rtol in its 13th digit.)"""
    system, fast, ref = _both_paths("simulation.rtol=1e-7", "simulation.atol=1e-7", "simulation.t_end=0.09",
                                    *overrides)
    assert fast.status == ref.status == "success" and not ref.event_times
    assert (fast.nsteps, fast.njev, fast.nlu) == (ref.nsteps, ref.njev, ref.nlu)
    assert fast.nsteps >= 10 and fast.nlu >= 4
    # scipy's Jacobian evaluates f at the step's start again (jac(t, y) is not given f): once a Jacobian
    assert ref.nfev - fast.nfev == ref.njev
    np.testing.assert_allclose(fast.y, ref.y, rtol=0, atol=1e-9)


def test_a_failed_radau_says_the_right_hand_side_was_non_finite_at_trial_states_on_both_backends():
    """The governor's shaft driven by w t - 4 (0.3 - t)^1.5, not defined after t = 0.3 s: Radau's trial
    states beyond it are not finite, it halves its step until it is too small, and both backends say
    so, in the same words (the compiled one said only that the step was too small before)."""
    messages = {}
    for backend in ("python", "compiled"):
        case = load_case(CONFIGS / "iftomm" / "a05_flyball_governor.yaml",
                         ["mechanism.drive={shaft: w*t - 4*(0.3 - t)^1.5}", "simulation.t_end=0.5",
                          "simulation.min_step=1e-300", f"simulation.backend={backend}"])
        result = run_case(case)
        assert result.backend == backend and result.status == "failed"
        messages[backend] = result.message
    assert messages["compiled"] == messages["python"]
    assert messages["compiled"].startswith("integrator Radau failed at t = 0.3 s: Required step size")
    assert messages["compiled"].endswith("(the right-hand side was non-finite at trial states, last at t = 0.3 s)")


def test_compiled_radau_follows_scipys_through_the_events():
    """The quick-return mechanism with its cutting-force switches over 2 s: the same events, the
    steps within a few percent, the states equal to well within the tolerance."""
    system, fast, ref = _both_paths("simulation.rtol=1e-7", "simulation.atol=1e-7", "simulation.t_end=2")
    assert fast.status == ref.status == "success"
    assert abs(fast.nsteps - ref.nsteps) <= 0.03 * ref.nsteps and fast.nsteps > 200
    assert len(fast.event_times) == len(ref.event_times) > 5 and fast.event_labels == ref.event_labels
    # the Newton iterations stop within their tolerance (about sqrt(rtol) of the error scale): the
    # two round-offs part there, and each restart at an event carries the difference on
    # (measured 2e-8 s in the event times, 8.5e-6 in a velocity of 6 rad/s)
    assert np.max(np.abs(np.subtract(fast.event_times, ref.event_times))) < 2e-7
    m = system.m
    assert np.max(np.abs(fast.y[:, :2 * m] - ref.y[:, :2 * m])) < 1e-4


def test_compiled_radau_meets_the_tight_reference(reference):
    res = run_case(qr_case("simulation.integrator=Radau", "simulation.rtol=1e-9", "simulation.atol=1e-9",
                           "stabilization.method=projection"))
    assert res.ok and res.backend == "compiled", res.message
    assert abs(res.q[-1, 0] - reference["q1"]) < 1e-6
    assert np.allclose(res.event_times, reference["events"], atol=1e-6)


def test_compiled_radau_converges_at_high_order():
    """Cutting force off (a smooth problem): the error at t = 1 s against the number of steps
    falls at the order of Radau IIA (5; at least 3.5 asked), the reference another integrator's."""
    base = ["simulation.integrator=Radau", "simulation.t_end=1", "loads.cutting_force=0"]
    ref = run_case(qr_case(*base, "simulation.integrator=DOP853", "simulation.rtol=1e-13", "simulation.atol=1e-13"))
    assert ref.ok and ref.nsteps > 100
    steps, errors = [], []
    for tol in (1e-5, 1e-7):
        res = run_case(qr_case(*base, f"simulation.rtol={tol}", f"simulation.atol={tol}"))
        assert res.backend == "compiled" and res.ok
        steps.append(res.nsteps)
        errors.append(abs(res.q[-1, 0] - ref.q[-1, 0]))
    order = np.log(errors[0] / errors[1]) / np.log(steps[1] / steps[0])
    assert order > 3.5, (steps, errors, order)  # measured 4.8


@pytest.fixture(scope="module")
def a05_runs():
    return {backend: run_case(load_case(A05, [f"simulation.backend={backend}"])) for backend in ("compiled", "python")}


def test_the_governor_runs_compiled_by_default():
    from csim.fast import resolve_backend

    assert resolve_backend(load_case(A05)) == "compiled"


def test_compiled_drive_rows_take_the_python_paths_steps(a05_runs):
    """A05 (three free joints, the shaft driven): the steps and Jacobians of both paths (within
    2 %: see test_compiled_radau_takes_scipys_steps_one_for_one; measured equal), the slider
    within 1e-7 m, the drive torque and work and the energy balance alike."""
    fast, slow = a05_runs["compiled"], a05_runs["python"]
    assert fast.ok and slow.ok, (fast.message, slow.message)
    assert (fast.backend, slow.backend) == ("compiled", "python")
    for a, b in ((fast.nsteps, slow.nsteps), (fast.njev, slow.njev), (fast.nlu, slow.nlu)):
        assert abs(a - b) <= 0.02 * b, (a, b)
    assert np.max(np.abs(fast.q - slow.q)) < 1e-7
    assert np.max(np.abs(fast.qd - slow.qd)) < 1e-5
    scale = np.max(np.abs(slow.drive_forces))
    assert scale > 10.0                                             # 49 N m: a torque worth measuring
    assert np.max(np.abs(fast.drive_forces - slow.drive_forces)) < 1e-5 * scale
    assert np.max(np.abs(fast.drive_work - slow.drive_work)) < 1e-5 * np.max(np.abs(slow.drive_work))
    assert fast.energy_error_relative < 1e-4 and slow.energy_error_relative < 1e-4
    assert fast.lam.shape == slow.lam.shape == (fast.t.size, 0)    # the drive rows are not the mechanism's


def test_compiled_governor_against_its_rotating_frame_equations(a05_runs):
    fast = a05_runs["compiled"]
    s_ref = a05_motion(fast.t)[0][:, 0]
    assert np.max(np.abs(fast.q[:, fast.coordinate_names.index("s_slide")] - s_ref)) < 1e-5  # measured 2.7e-6 m
    shaft = fast.coordinate_names.index("q_shaft")
    assert np.allclose(fast.q[:, shaft], 2 * np.pi * fast.t, rtol=0, atol=1e-9)


@pytest.mark.parametrize("method", ["none", "baumgarte", "sliding_mode", "projection"])
def test_compiled_drive_rows_on_a_closed_loop_equal_python(method):
    """The driven slider-crank of tests/test_driven.py (a loop and a drive: the stabilized rates of
    the drive row, and the projection's velocity target, need Phi_t = -f'(t)), DOP853, on both paths."""
    from test_driven import _data

    from csim.case import validate_case

    overrides = {"none": {}, "baumgarte": {"d": 1.0, "w": 20.0}, "sliding_mode": {}, "projection": {}}[method]
    runs = {}
    for backend in ("compiled", "python"):
        data = _data(backend=backend, rtol=1e-9, atol=1e-9)
        data["stabilization"] = {"method": method, **overrides}
        runs[backend] = run_case(validate_case(data))
    fast, slow = runs["compiled"], runs["python"]
    assert fast.ok and slow.ok and fast.backend == "compiled", (fast.message, slow.message)
    assert fast.nsteps == slow.nsteps
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.phi, slow.phi, rtol=0, atol=1e-10)
    np.testing.assert_allclose(fast.phi_dot, slow.phi_dot, rtol=0, atol=1e-8)
    scale = np.max(np.abs(slow.drive_forces))
    np.testing.assert_allclose(fast.drive_forces, slow.drive_forces, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(fast.drive_work, slow.drive_work, rtol=0, atol=1e-7 * scale)


def test_projection_onto_the_drives_runs_compiled_and_takes_the_python_paths_steps():
    """A05 with ``projection``: the shaft's drive row is projected onto at each step's time (its
    velocity target Phi_t = -f'(t), csim.physics.projection.project) by the kernels, with the same
    steps as the Python path (within 2 %, as for Radau above; measured equal) and the shaft on its
    drive to round-off."""
    from csim.fast.support import unsupported

    runs = {b: run_case(load_case(A05, ["stabilization.method=projection", "simulation.t_end=2",
                                        f"simulation.backend={b}"])) for b in ("compiled", "python")}
    fast, slow = runs["compiled"], runs["python"]
    assert unsupported(load_case(A05, ["stabilization.method=projection"])) == []
    assert fast.ok and slow.ok and (fast.backend, slow.backend) == ("compiled", "python"), (fast.message, slow.message)
    assert abs(fast.nsteps - slow.nsteps) <= 0.02 * slow.nsteps, (fast.nsteps, slow.nsteps)
    assert np.max(np.abs(fast.q - slow.q)) < 1e-7
    shaft = fast.coordinate_names.index("q_shaft")
    for run in (fast, slow):  # the drive row q_shaft - 2 pi t and its rate, held by the projection
        assert np.max(np.abs(run.q[:, shaft] - 2 * np.pi * run.t)) < 1e-12
        assert np.max(np.abs(run.qd[:, shaft] - 2 * np.pi)) < 1e-12
    scale = np.max(np.abs(slow.drive_forces))
    assert np.max(np.abs(fast.drive_forces - slow.drive_forces)) < 1e-5 * scale
