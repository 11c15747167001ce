"""The index-3 augmented Lagrangian method with projections (csim.solver.ali3p,
csim.solver.methods.augmented_lagrangian): second order against the pendulum's own ODE,
Bricard's overconstrained loop against minimal coordinates, the case rules."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS, assert_bad_input, invoke
from scipy.integrate import solve_ivp

from csim.case import load_case
from csim.pipeline import run_case

AL = ("stabilization.method=augmented_lagrangian", "simulation.integrator=trapezoidal")


def _pendulum_angle(t_end: float) -> float:
    """theta(t_end) of theta'' = -(g / L) sin theta from theta = pi/6 at rest (the case's start)."""
    sol = solve_ivp(lambda t, y: [y[1], -9.81 * np.sin(y[0])], (0.0, t_end), [np.pi / 6, 0.0],
                    rtol=1e-12, atol=1e-12, method="DOP853")
    return float(sol.y[0, -1])


def _pendulum_error(step: float, t_end: float = 1.0) -> float:
    case = load_case(CONFIGS / "pendulum.yaml", [*AL, f"simulation.step={step}", f"simulation.t_end={t_end}",
                                                   "output.dt=0.1", "initial.q_offset.y=0.0"])
    result = run_case(case)
    assert result.status == "success", result.message
    x, y = result.q[-1]
    assert np.hypot(x, y) == pytest.approx(1.0, abs=1e-11)  # on the circle to the Newton tolerance
    return abs(np.arctan2(x, -y) - _pendulum_angle(t_end))


def test_trapezoidal_rule_is_second_order_on_the_pendulum():
    errors = [_pendulum_error(h) for h in (1e-2, 5e-3, 2.5e-3)]
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(orders - 2.0) < 0.15), (errors, orders)


def test_bricard_runs_on_every_equation_and_matches_minimal_coordinates():
    """Bricard's loop with its redundant equation: the augmented Lagrangian method keeps all five."""
    common = ("simulation.t_end=1", "output.dt=0.05")
    al = run_case(load_case(CONFIGS / "iftomm" / "a04_bricard.yaml", [*AL, "simulation.step=1e-3", *common]))
    ref = run_case(load_case(CONFIGS / "iftomm" / "a04_bricard.yaml",
                             ["stabilization.method=minimal", "simulation.rtol=1e-11", "simulation.atol=1e-11",
                              *common]))
    assert al.status == ref.status == "success", (al.message, ref.message)
    assert al.phi.shape[1] == 5  # every non-trivial equation is recorded, the dependent one too
    assert np.max(np.abs(al.phi)) < 1e-10
    assert np.max(np.abs(al.q - ref.q)) < 1e-4  # trapezoidal, h = 1 ms: O(h^2)
    assert al.energy_error_relative < 1e-4
    assert al.removed_names and np.max(np.abs(al.removed_phi)) < 1e-10
    assert al.nsteps == 1000 and al.nfev > al.nsteps  # Newton residuals: at least one per step


@pytest.mark.parametrize(("overrides", "words"), [
    (("stabilization.method=augmented_lagrangian",), ["simulation.integrator", "expected 'trapezoidal'"]),
    (("simulation.integrator=trapezoidal",), ["simulation.integrator", "augmented_lagrangian"]),
    ((*AL, "formulation.method=elimination"), ["formulation.method", "expected 'kkt'"]),
])
def test_combinations_that_cannot_work_are_refused(overrides, words):
    args = ["run", CONFIGS / "pendulum.yaml"]
    for o in overrides:
        args += ["--set", o]
    assert_bad_input(invoke(*args), *words)
