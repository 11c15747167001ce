"""Overconstrained linkages (csim.solver.redundant): the independent rows are chosen again as
the mechanism moves, so the KKT methods pass where the rows kept at the start lose rank."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS

from csim.case import load_case
from csim.fast.support import unsupported
from csim.pipeline import build_system, run_case

BRICARD = CONFIGS / "iftomm" / "a04_bricard.yaml"
#: past t = 0.894 s, where the four equations kept at the start lose rank
SHORT = ("simulation.t_end=2", "output.dt=0.02")


@pytest.fixture(scope="module")
def reference():
    case = load_case(BRICARD, ["stabilization.method=minimal", "simulation.rtol=1e-11", "simulation.atol=1e-11",
                               *SHORT])
    result = run_case(case)
    assert result.status == "success", result.message
    return result


@pytest.mark.parametrize("method", ["projection", "baumgarte"])
def test_kkt_methods_pass_where_the_kept_rows_lose_rank(method, reference):
    case = load_case(BRICARD, [f"stabilization.method={method}", "simulation.rtol=1e-10", "simulation.atol=1e-10",
                               *SHORT])
    system = build_system(case)
    assert system.model.n_constraints == 4 and system.r_recorded == 5
    result = run_case(case)
    assert result.status == "success", result.message
    assert np.max(np.abs(result.q - reference.q)) < 1e-5
    assert system.model.row_changes >= 0
    assert result.phi.shape[1] == 5 and result.lam.shape[1] == 5


@pytest.mark.parametrize("overrides", [("stabilization.method=none",), ("formulation.method=elimination",)])
def test_unstabilized_runs_are_right_or_fail_naming_the_equation(overrides):
    """The issue's case: these used to exit 0 with point P3 0.5-0.6 m off."""
    case = load_case(BRICARD, [*overrides, "simulation.t_end=10"])
    result = run_case(case)
    ref = run_case(load_case(BRICARD, ["stabilization.method=minimal", "simulation.rtol=1e-11",
                                       "simulation.atol=1e-11"]))
    if result.status == "success":
        n = result.t.size
        assert np.max(np.abs(result.q - ref.q[:n])) < 1e-3
    else:
        assert result.failure in ("drift", "branch") and "joint j0" in result.message, result.message


def test_an_overconstrained_linkage_runs_on_the_python_path_except_minimal():
    assert any("overconstrained" in r for r in unsupported(load_case(BRICARD, ["stabilization.method=projection"])))
    assert not unsupported(load_case(BRICARD, ["stabilization.method=minimal"]))


def test_the_recorded_multipliers_of_an_overconstrained_linkage_are_minimum_norm():
    """Bricard's five non-trivial closure equations (rank 4) at states off the manifold by an integration's
    error: the multipliers recorded for the full set give the chosen rows' constraint force and have no
    component along the left null vector of the full Jacobian. (lstsq at round-off kept the dependent
    singular value there, 1e-11 of the largest, and gave the chosen rows' multipliers with the other at 0.)"""
    case = load_case(CONFIGS / "iftomm" / "a04_bricard.yaml", ["stabilization.method=none", "simulation.t_end=0.2"])
    system = build_system(case)
    model = system.model
    result = run_case(case)
    rng = np.random.default_rng(7)
    for i in range(0, result.t.size, 5):
        q = result.q[i] + 1e-9 * rng.standard_normal(result.q.shape[1])  # off the manifold by 1e-9
        lam = rng.standard_normal(model.selected(q).size)
        J = model._jacobian(q)
        _, _, lam_all = model.recorded(q, result.qd[i], lam)
        np.testing.assert_allclose(J.T @ lam_all, J[model.selected(q)].T @ lam, atol=1e-10 * np.abs(lam).max())
        left_null = np.linalg.svd(J)[0][:, -1]  # J (5, m) of rank 4
        assert abs(left_null @ lam_all) < 1e-8 * np.linalg.norm(lam_all), (i, left_null @ lam_all)


def test_a_driven_overconstrained_linkage_is_not_pointed_to_minimal():
    """minimal does not take a dynamic drive (csim.solver.driven.driven_problems): the reason the compiled
    backend gives for a driven overconstrained linkage does not suggest it."""
    driven = unsupported(load_case(CONFIGS / "bricard.yaml", ["mechanism.drive_mode=dynamic"]))
    free = unsupported(load_case(CONFIGS / "iftomm" / "a04_bricard.yaml", ["stabilization.method=none"]))
    assert driven and not any("minimal" in reason for reason in driven), driven
    assert any("with 'minimal'" in reason for reason in free), free
