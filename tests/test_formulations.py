"""KKT and elimination: the same accelerations and multipliers, and their failure modes."""
from __future__ import annotations

import numpy as np
import pytest

from csim.errors import SimulationFailure
from csim.solver.formulations import KKT, Elimination, make_formulation


def random_problem(rng, m=5, r=2):
    A = rng.normal(size=(m, m))
    M = A @ A.T + m * np.eye(m)  # symmetric positive definite
    return M, rng.normal(size=(r, m)), rng.normal(size=m), rng.normal(size=r)


@pytest.mark.parametrize("seed", range(4))
def test_kkt_solution_satisfies_the_equations(seed):
    M, J, p, gamma = random_problem(np.random.default_rng(seed))
    qdd, lam = KKT().solve(M, J, p, gamma)
    np.testing.assert_allclose(M @ qdd + J.T @ lam, p, atol=1e-12)
    np.testing.assert_allclose(J @ qdd, gamma, atol=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_elimination_equals_kkt(seed):
    M, J, p, gamma = random_problem(np.random.default_rng(seed))
    qdd_k, lam_k = KKT().solve(M, J, p, gamma)
    qdd_e, lam_e = Elimination().solve(M, J, p, gamma)
    np.testing.assert_allclose(qdd_e, qdd_k, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(lam_e, lam_k, rtol=1e-10, atol=1e-12)


def test_the_chosen_partition_avoids_the_singular_block():
    # columns 0 and 1 are parallel: they cannot both be dependent
    J = np.array([[1.0, 2.0, 0.0], [1.0, 2.0, 1.0]])
    M, _, p, gamma = random_problem(np.random.default_rng(1), m=3, r=2)
    form = Elimination()
    form.solve(M, J, p, gamma)
    v = np.setdiff1d(np.arange(3), form.independent)
    assert np.linalg.cond(J[:, v]) < 10


def test_elimination_repartitions_when_the_dependent_block_turns_singular():
    M, _, p, gamma = random_problem(np.random.default_rng(0), m=3, r=2)
    form = Elimination()
    form.solve(M, np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]), p, gamma)  # an earlier configuration: u = q0
    assert form.repartitions == 0 and list(form.independent) == [0]
    J = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])  # Phi_v over (q1, q2) is singular
    qdd, lam = form.solve(M, J, p, gamma)
    assert form.repartitions == 1 and list(form.independent) == [2]
    qdd_k, lam_k = KKT().solve(M, J, p, gamma)
    np.testing.assert_allclose(qdd, qdd_k, atol=1e-12)


def test_fixed_partition_fails_loudly_on_a_singular_block():
    M, _, p, gamma = random_problem(np.random.default_rng(0), m=3, r=2)
    J = np.array([[1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
    with pytest.raises(SimulationFailure, match="formulation.independent"):
        Elimination(independent=[0]).solve(M, J, p, gamma)


def test_kkt_fails_loudly_on_a_rank_deficient_jacobian():
    M, _, p, _ = random_problem(np.random.default_rng(0), m=3, r=2)
    J = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0]])
    with pytest.raises(SimulationFailure, match="singular KKT"):
        KKT().solve(M, J, p, np.zeros(2))


def test_registry_lists_valid_names():
    with pytest.raises(KeyError, match="valid names: kkt, elimination"):
        make_formulation("lagrange")
