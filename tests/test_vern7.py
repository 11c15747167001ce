"""Verner's 7(6) pair (csim.solver.vern7, csim.physics.tableaus): the order of its solution,
of its embedded solution and of its interpolant under step refinement on a nonlinear problem
with a known solution, and a run of the quick-return against DOP853 (independent
coefficients, a different order)."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS

from csim.case import load_case
from csim.physics import tableaus
from csim.pipeline import run_case
from csim.solver.vern7 import Vern7


def _fun(t, y):
    """The logistic u' = u (1 - u), v' = v cos t and w' = w^2 cos t, nonlinear and
    non-autonomous, with the closed forms of :func:`_exact`."""
    return np.array([y[0] * (1 - y[0]), y[1] * np.cos(t), y[2] ** 2 * np.cos(t)])


def _exact(t):
    return np.array([1 / (1 + 4 * np.exp(-t)), np.exp(np.sin(t)), 1 / (2 - np.sin(t))])


def _fixed_steps(h, t_end=4.0):
    """Final error, the largest interpolant error at x = 0.3 and 0.7 of each step, and the
    largest local error of the embedded solution, with steps of h."""
    solver = Vern7(_fun, 0.0, _exact(0.0), t_end, rtol=1e3, atol=1e3, first_step=h, max_step=h)
    dense_error, embedded = 0.0, 0.0
    while solver.status == "running":
        y_old = solver.y.copy()
        solver.step()
        h_step = solver.t - solver.t_old
        # the embedded solution y_hat = y_new - h K^T E, against the exact flow from y_old
        exact_flow = _exact(solver.t) - _exact(solver.t_old) + y_old
        y_hat = solver.y - h_step * solver.K.T @ solver.E
        if solver.t_old == 0.0:
            embedded = float(np.max(np.abs(y_hat - exact_flow)))
        dense = solver.dense_output()
        for x in (0.3, 0.7):
            t = solver.t_old + x * h_step
            dense_error = max(dense_error, float(np.max(np.abs(dense(t) - _exact(t)))))
        assert np.allclose(dense(solver.t), solver.y, rtol=0, atol=1e-12)  # the interpolant ends at the step
    return float(np.max(np.abs(solver.y - _exact(solver.t)))), dense_error, embedded


def test_seventh_order_solution_seventh_order_interpolant_and_sixth_order_embedding():
    """Global error O(h^7) (measured slopes 6.93, 7.00); the interpolant's error O(h^7) over
    the run, its local error O(h^8) plus the solution's (7.38, 6.71); the embedded solution's
    local error O(h^7), order 6 (7.24, 7.15)."""
    errors = np.array([_fixed_steps(h) for h in (0.2, 0.1, 0.05)])
    slopes = np.log2(errors[:-1] / errors[1:])
    final, dense, embedded = slopes.T
    assert np.all((final > 6.6) & (final < 7.5)), final
    assert np.all((dense > 6.4) & (dense < 7.8)), dense
    assert np.all((embedded > 6.7) & (embedded < 7.6)), embedded


def test_the_tableau_is_consistent():
    """Rows of A sum to the nodes; the interpolant ends at the step's solution (P summed over
    its powers is B, 0 for the extra stages) with the new point's slope (d/dx at x = 1 picks
    the new point's derivative alone)."""
    assert np.max(np.abs(tableaus.VERN7_A.sum(1) - tableaus.VERN7_C)) < 1e-13
    assert np.max(np.abs(tableaus.VERN7_A_EXTRA.sum(1) - tableaus.VERN7_C_EXTRA)) < 1e-13
    at_one = tableaus.VERN7_P.sum(1)
    assert np.max(np.abs(at_one - np.append(tableaus.VERN7_B, np.zeros(6)))) < 1e-12
    slope = tableaus.VERN7_P @ np.arange(1, 8)
    assert np.max(np.abs(slope - np.eye(16)[10])) < 1e-11


def test_the_kernels_buffers_hold_vern7s_stages_and_interpolant():
    """The compiled loop sizes K and F for DOP853 (16 stages, 7 interpolant rows); Vern7's ten
    stages, new point and five extra stages, and its 7 rows, must fit (numba checks no bounds)."""
    from scipy.integrate._ivp import dop853_coefficients as dop

    assert tableaus.VERN7_P.shape[0] == tableaus.VERN7_C.size + 1 + tableaus.VERN7_C_EXTRA.size <= dop.N_STAGES_EXTENDED
    assert tableaus.VERN7_P.shape[1] <= dop.INTERPOLATOR_POWER


def test_dense_output_costs_five_evaluations_only_when_asked():
    solver = Vern7(_fun, 0.0, _exact(0.0), 1.0, rtol=1e-8, atol=1e-8)
    solver.step()
    stepped = solver.nfev
    solver.dense_output()
    assert solver.nfev == stepped + 5


@pytest.mark.parametrize("stabilization", ["none", "projection"])
def test_quick_return_with_vern7_agrees_with_dop853(stabilization):
    sets = ["simulation.t_end=2", "simulation.rtol=1e-10", "simulation.atol=1e-10",
            f"stabilization.method={stabilization}"]
    ref = run_case(load_case(CONFIGS / "quick_return.yaml", sets))
    vern7 = run_case(load_case(CONFIGS / "quick_return.yaml", [*sets, "simulation.integrator=Vern7"]))
    assert vern7.ok, vern7.message
    assert np.max(np.abs(vern7.q - ref.q)) < 1e-7
    assert np.max(np.abs(np.subtract(vern7.event_times, ref.event_times))) < 1e-8


@pytest.mark.parametrize("stabilization", ["none", "projection"])
def test_both_backends_take_the_same_steps(stabilization):
    """The quick-return with its cutting-force events over 1.5 s: the same steps, evaluations
    (the interpolant's five extra stages included, evaluated for the same steps) and events on
    the compiled backend as with scipy's machinery on the Python path."""
    sets = ["simulation.t_end=1.5", "simulation.rtol=1e-9", "simulation.atol=1e-9", "simulation.integrator=Vern7",
            f"stabilization.method={stabilization}"]
    fast = run_case(load_case(CONFIGS / "quick_return.yaml", [*sets, "simulation.backend=compiled"]))
    slow = run_case(load_case(CONFIGS / "quick_return.yaml", [*sets, "simulation.backend=python"]))
    assert (fast.backend, slow.backend) == ("compiled", "python")
    assert fast.ok and slow.ok, (fast.message, slow.message)
    assert (fast.nfev, fast.nsteps) == (slow.nfev, slow.nsteps) and fast.nsteps > 100
    assert len(fast.event_times) == len(slow.event_times) > 5 and fast.event_labels == slow.event_labels
    np.testing.assert_allclose(fast.event_times, slow.event_times, rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-9)
