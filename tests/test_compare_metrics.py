"""``csim.compare.metrics`` and ``csim.compare.runs``: figures of merit from arrays (no simulation)."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from csim.compare.metrics import NAN, constraint_errors, motion_error, nanmax_abs
from csim.compare.runs import INTERRUPTED, Run, shorten

T = np.linspace(0.0, 1.0, 11)
Q_REF = np.column_stack([np.sin(T), np.cos(T)])


def test_nanmax_abs_ignores_nan():
    assert nanmax_abs([[1.0, -3.0], [NAN, 2.0]]) == 3.0
    assert math.isnan(nanmax_abs([])) and math.isnan(nanmax_abs([NAN, NAN]))


def test_constraint_errors():
    phi = np.array([[1e-3, -2e-3], [0.0, -5e-4]])
    phi_dot = np.array([[0.1, 0.0], [-0.3, 0.2]])
    assert constraint_errors(phi, phi_dot) == (2e-3, 5e-4, 0.3)
    max_phi, final_phi, max_phi_dot = constraint_errors(np.zeros((0, 2)), np.zeros((0, 2)))
    assert math.isnan(max_phi) and math.isnan(final_phi) and math.isnan(max_phi_dot)


def test_motion_error_is_the_largest_deviation_from_the_reference():
    q = Q_REF.copy()
    q[4, 1] += 3e-3  # the largest deviation, inside the run
    q[-1, 0] -= 1e-3  # the deviation at t_end
    error = motion_error(T, q, T, Q_REF)
    assert error.motion == pytest.approx(3e-3) and error.final == pytest.approx(1e-3)
    assert error.until == 1.0 and error.note == ""


def test_a_run_that_stopped_early_is_measured_until_it_stopped():
    q = Q_REF[:6] + 1e-4
    error = motion_error(T[:6], q, T, Q_REF)
    assert error.motion == pytest.approx(1e-4) and error.until == T[5] and math.isnan(error.final)
    assert error.note == "motion error over t <= 0.5 s only (the run stopped early)"


@pytest.mark.parametrize("t, q", [(T + 1e-3, Q_REF), (T, Q_REF[:, :1])], ids=["times", "coordinates"])
def test_runs_that_do_not_match_the_reference_are_not_measured(t, q):
    error = motion_error(t, q, T, Q_REF)
    assert math.isnan(error.motion) and math.isnan(error.final) and math.isnan(error.until)
    assert error.note == "output times differ from the reference's"


# --------------------------------------------------------------------------- Run


def result(q, t=T, status="success", message="reached t_end"):
    """What a Run reads of a Result."""
    phi = np.full((t.size, 1), 1e-6)
    return SimpleNamespace(t=t, q=q, phi=phi, phi_dot=2 * phi, status=status, message=message, wall_time=0.5,
                           nfev=120, nsteps=30)


def test_a_run_is_an_interrupted_failure_until_it_ran():
    run = Run("none", 1e-6)
    assert not run.ok and run.message == INTERRUPTED and math.isnan(run.wall_time)


def test_a_run_takes_the_figures_of_its_result_and_is_measured_against_the_reference():
    ref, run = Run("projection", 1e-12), Run("none", 1e-6)
    ref.set_result(result(Q_REF))
    run.set_result(result(Q_REF + 2e-5))
    run.measure_against(ref)
    assert run.ok and (run.nfev, run.nsteps, run.wall_time) == (120, 30, 0.5)
    assert (run.max_phi, run.final_phi, run.max_phi_dot) == (1e-6, 1e-6, 2e-6)
    assert run.motion_error == pytest.approx(2e-5) and run.final_error == pytest.approx(2e-5)
    assert run.error_until == 1.0 and run.error_note == ""


def test_a_failed_reference_leaves_the_errors_unavailable():
    ref, run = Run("projection", 1e-12), Run("none", 1e-6)
    ref.set_result(None, "RuntimeError: " + "x" * 200)
    run.set_result(result(Q_REF))
    run.measure_against(ref)
    assert math.isnan(run.motion_error) and math.isnan(run.final_error)
    assert run.error_note == f"no reference: the reference run failed ({shorten(ref.message)})"
    assert run.error_note.endswith("...)") and len(shorten(ref.message)) == 120


def test_a_run_without_samples_is_not_measured():
    ref, run = Run("projection", 1e-12), Run("none", 1e-6)
    ref.set_result(result(Q_REF))
    run.set_result(result(np.zeros((0, 2)), t=np.zeros(0), status="failed", message="blow-up"))
    run.measure_against(ref)
    assert math.isnan(run.final_phi) and math.isnan(run.motion_error) and run.error_note == "no samples to measure"
