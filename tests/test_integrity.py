"""Whether a run's motion can be trusted (csim.solver.integrity): removed equations, singular
crossings, branch changes; on synthetic samples and on the IFToMM cases."""
from __future__ import annotations

import h5py
import numpy as np
import pytest
from conftest import CONFIGS, simulated_file

from csim.solver.integrity import ConstraintWatch, bounded_minimum, check_integrity, hermite, relative_sigma


def _two_link_watch():
    """A point (x, y) on the unit circle, written twice: x^2 + y^2 - 1 (kept) and 2 (x^2 + y^2 - 1)
    (removed, dependent), plus x - y + 0 * ... nothing else: rank 1."""
    def phi(q):
        c = q[0] ** 2 + q[1] ** 2 - 1.0
        return np.array([c, 2.0 * c])

    def phi_q(q):
        return np.array([[2 * q[0], 2 * q[1]], [4 * q[0], 4 * q[1]]])

    return ConstraintWatch(phi=phi, phi_q=phi_q, labels=["circle", "circle twice"], kept=np.array([0]),
                           removed=np.array([1]), rank=1)


def test_a_removed_equation_that_comes_apart_fails_the_run_and_is_named():
    watch = _two_link_watch()
    t = np.linspace(0.0, 1.0, 11)
    angle = t
    q = np.column_stack((np.cos(angle), np.sin(angle)))
    qd = np.column_stack((-np.sin(angle), np.cos(angle)))
    qdd = -q
    ok = check_integrity(watch, t, q, qd, qdd, ["x", "y"])
    assert ok.failure is None and ok.removed_names == ["circle twice"]
    assert np.max(np.abs(ok.removed_phi)) < 1e-12
    # a watch whose removed row is not a multiple of the kept one: (x - 1)^2 + y^2 - 1 away from the start
    broken = ConstraintWatch(phi=lambda x: np.array([x[0] ** 2 + x[1] ** 2 - 1.0, x[1]]),
                             phi_q=lambda x: np.array([[2 * x[0], 2 * x[1]], [0.0, 1.0]]),
                             labels=["circle", "on the x axis"], kept=np.array([0]), removed=np.array([1]), rank=1)
    bad = check_integrity(broken, t, q, qd, qdd, ["x", "y"])
    kind, message = bad.failure
    assert kind == "drift" and "on the x axis" in message and "removed as dependent" in message


def test_relative_sigma_and_hermite():
    assert relative_sigma(np.diag([2.0, 1.0]), 2) == pytest.approx(0.5)
    assert relative_sigma(np.array([[1.0, 0.0], [2.0, 0.0]]), 2) == pytest.approx(0.0, abs=1e-15)
    # the cubic Hermite interpolant reproduces a cubic exactly
    f, df = (lambda s: s**3 - 2 * s), (lambda s: 3 * s**2 - 2)
    a, b = 0.3, 0.8
    for tau in (0.0, 0.25, 0.5, 1.0):
        assert hermite(f(a), df(a), f(b), df(b), b - a, tau) == pytest.approx(f(a + tau * (b - a)))


def test_a_velocity_jump_across_a_singular_crossing_is_a_branch_change():
    """Rank 1 everywhere but at x = 0 for the Jacobian [[x, 0]] of the 'constraint' x^2/2 - c."""
    watch = ConstraintWatch(phi=lambda q: np.array([0.0]), phi_q=lambda q: np.array([[q[0], 0.0]]),
                            labels=["c"], kept=np.array([0]), removed=np.zeros(0, int), rank=1)
    t = np.linspace(0.0, 2.0, 21)
    x = t - 1.05  # crosses 0 at t = 1.05, between two samples
    q = np.column_stack((x, np.zeros_like(t)))
    qd = np.column_stack((np.ones_like(t), np.zeros_like(t)))
    smooth = check_integrity(watch, t, q, qd, np.zeros_like(q), ["x", "y"])
    assert smooth.failure is None
    assert smooth.singular_times == pytest.approx([1.05], abs=1e-4)
    assert "singular configuration" in smooth.warnings[0]
    qd_jump = qd.copy()
    qd_jump[t > 1.05, 0] = -1.0  # turned back at the crossing: not what the accelerations say
    jumped = check_integrity(watch, t, q, qd_jump, np.zeros_like(q), ["x", "y"])
    assert jumped.failure[0] == "branch" and "x's velocity jumped" in jumped.failure[1]


def test_n_four_bar_crossings_are_in_the_result_file(tmp_path_factory):
    """A02 with N = 2: every link horizontal twice a turn; projection keeps the parallelogram."""
    path = simulated_file(tmp_path_factory, "iftomm/a02_n_four_bar_2.yaml", "a02.h5",
                          "stabilization.method=projection", "simulation.integrator=DOP853", "simulation.t_end=3")
    with h5py.File(path) as fh:
        assert fh.attrs["status"] == "success"
        times = fh["integrity/singular_times"][()]
        warnings = list(fh["integrity"].attrs["warnings"])
        q = fh["q"][()]
    assert times.size >= 2 and any("singular configuration" in str(w) for w in warnings)
    # the cranks still turn together (the parallelogram branch)
    assert np.max(np.abs(q[:, 0] - q[:, 2])) < 1e-6


def test_n_four_bar_branch_change_fails_without_stabilization(tmp_path_factory):
    """The unstabilized run used to report success while crank 2 stopped (2 m error)."""
    path = simulated_file(tmp_path_factory, "iftomm/a02_n_four_bar_2.yaml", "a02_none.h5",
                          "stabilization.method=none", "simulation.integrator=DOP853", "simulation.t_end=4")
    with h5py.File(path) as fh:
        status, failure, message = (str(fh.attrs[k]) for k in ("status", "failure", "message"))
        q = fh["q"][()]
    turned_together = np.max(np.abs(q[:, 0] - q[:, 3])) < 1e-3
    assert turned_together or (status == "failed" and failure == "branch" and "assembly branch" in message)


def test_bricard_minimal_holds_the_removed_equation(tmp_path_factory):
    path = simulated_file(tmp_path_factory, "iftomm/a04_bricard.yaml", "a04_minimal.h5",
                          "stabilization.method=minimal", "simulation.t_end=2")
    with h5py.File(path) as fh:
        assert fh.attrs["status"] == "success"
        removed = fh["integrity/removed_phi"]
        names = [n.decode() if isinstance(n, bytes) else str(n) for n in fh["integrity/removed"][()]]
        assert names == ["joint j0 x: (r_jm - r_ik).e_x"]
        assert removed.attrs["units"] == "m"
        assert np.nanmax(np.abs(removed[()])) < 1e-9
    assert (CONFIGS / "iftomm" / "a04_bricard.yaml").is_file()


@pytest.mark.parametrize(("f", "bracket"), [
    (lambda x: (x - 0.3) ** 2, (0.0, 1.0)),             # a parabola: parabolic steps, 6 evaluations
    (lambda x: abs(x - 0.3), (0.0, 1.0)),               # a V (a singular value about a loss of rank)
    (lambda x: float(np.sin(x)), (3.0, 6.0)),
    (lambda x: x, (0.0, 1.0)),                          # the minimum at an end of the bracket
    (lambda x: float(np.cos(3 * x)) + 0.1 * x, (0.0, 4.0)),  # several local minima
])
def test_bounded_minimum_takes_scipys_steps(f, bracket):
    # the same method as scipy's minimize_scalar(method="bounded"), which csim no longer imports
    # for it (0.4 s of a run): the same minimiser within the tolerance, in as many evaluations
    # (scipy takes sqrt(2.2e-16) for sqrt(eps): the last bits of x may differ)
    from scipy.optimize import minimize_scalar

    calls = []
    x, fx = bounded_minimum(lambda u: calls.append(u) or f(u), *bracket, xatol=1e-7)
    reference = minimize_scalar(f, bounds=bracket, method="bounded", options=dict(xatol=1e-7))
    assert abs(x - reference.x) < 1e-7 and fx == f(x) and len(calls) == reference.nfev
    assert bracket[0] <= min(calls) and max(calls) <= bracket[1]
