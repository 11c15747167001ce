"""Tsitouras' 5(4) pair (csim.solver.tsit5, csim.physics.tableaus): its order, its
interpolant's, a run of the quick-return against DOP853 (independent coefficients, one order
of the pair each), and the compiled steps of Tsit5 and RK45 against scipy's machinery."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS

from csim.case import load_case
from csim.pipeline import run_case
from csim.solver.tsit5 import Tsit5


def _fun(t, y):
    """y' = -2 t y^2, y(0) = 1: y = 1 / (1 + t^2) (and a linear oscillator beside it)."""
    return np.array([-2 * t * y[0] ** 2, y[2], -y[1]])


def _exact(t):
    return np.array([1 / (1 + t * t), np.sin(t), np.cos(t)])


def _fixed_steps(h, t_end=2.0):
    """Final error and the largest midpoint error of the interpolant, with steps of h."""
    solver = Tsit5(_fun, 0.0, _exact(0.0), t_end, rtol=1e3, atol=1e3, first_step=h, max_step=h)
    mid = 0.0
    while solver.status == "running":
        solver.step()
        dense = solver.dense_output()
        t_mid = 0.5 * (solver.t_old + solver.t)
        mid = max(mid, float(np.max(np.abs(dense(t_mid) - _exact(t_mid)))))
        assert np.allclose(dense(solver.t), solver.y, rtol=0, atol=1e-13)  # the interpolant ends at the step
    return float(np.max(np.abs(solver.y - _exact(solver.t)))), mid


def test_fifth_order_convergence_and_a_fourth_order_interpolant():
    """Global error O(h^5) (measured slopes 5.35, 5.20 towards 5); the interpolant's error at
    mid-step O(h^5) locally, as a 4th-order interpolant's is (measured 5.08, 5.02)."""
    errors = [_fixed_steps(h) for h in (0.05, 0.025, 0.0125)]
    final = np.log2([errors[i][0] / errors[i + 1][0] for i in range(2)])
    mid = np.log2([errors[i][1] / errors[i + 1][1] for i in range(2)])
    assert np.all((final > 4.8) & (final < 5.45)), final
    assert np.all((mid > 4.6) & (mid < 5.4)), mid


def test_quick_return_with_tsit5_agrees_with_dop853():
    sets = ["simulation.t_end=2", "simulation.rtol=1e-10", "simulation.atol=1e-10"]
    ref = run_case(load_case(CONFIGS / "quick_return.yaml", sets))
    tsit5 = run_case(load_case(CONFIGS / "quick_return.yaml", [*sets, "simulation.integrator=Tsit5"]))
    assert tsit5.ok, tsit5.message
    assert tsit5.backend == "compiled"
    assert np.max(np.abs(tsit5.q - ref.q)) < 1e-7
    assert tsit5.nfev > ref.nfev  # a 5th-order pair takes more evaluations at 1e-10 than DOP853


@pytest.mark.parametrize("attr", ["A", "B", "C", "E", "P"])
def test_the_tableau_has_scipys_shapes(attr):
    shapes = {"A": (6, 6), "B": (6,), "C": (6,), "E": (7,), "P": (7, 4)}
    assert getattr(Tsit5, attr).shape == shapes[attr]


def test_the_rk45_tableau_is_scipys():
    from scipy.integrate import RK45

    from csim.physics import tableaus

    for attr in ("A", "B", "C", "E", "P"):
        assert np.array_equal(getattr(tableaus, f"RK45_{attr}"), getattr(RK45, attr)), attr
    assert RK45.error_estimator_order == Tsit5.error_estimator_order == tableaus.ERROR_ESTIMATOR_ORDER


@pytest.mark.parametrize("integrator, stabilization", [("Tsit5", "none"), ("RK45", "none"), ("Tsit5", "projection")])
def test_both_backends_take_the_same_steps(integrator, stabilization):
    """The quick-return with its cutting-force events over 1.5 s: the same steps, evaluations
    and events on the compiled backend as with scipy's machinery on the Python path, the states
    equal to round-off (as DOP853's, tests/test_fast.py)."""
    sets = ["simulation.t_end=1.5", "simulation.rtol=1e-9", "simulation.atol=1e-9",
            f"simulation.integrator={integrator}", f"stabilization.method={stabilization}"]
    fast = run_case(load_case(CONFIGS / "quick_return.yaml", [*sets, "simulation.backend=compiled"]))
    slow = run_case(load_case(CONFIGS / "quick_return.yaml", [*sets, "simulation.backend=python"]))
    assert (fast.backend, slow.backend) == ("compiled", "python")
    assert fast.ok and slow.ok, (fast.message, slow.message)
    assert (fast.nfev, fast.nsteps) == (slow.nfev, slow.nsteps) and fast.nsteps > 300
    assert len(fast.event_times) == len(slow.event_times) > 5 and fast.event_labels == slow.event_labels
    np.testing.assert_allclose(fast.event_times, slow.event_times, rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-9)
