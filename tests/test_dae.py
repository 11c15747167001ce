"""RadauDAE: scipy's Radau on ODEs, accuracy on index-1 and index-2 DAEs, constraint
accuracy of the GGL pendulum, failures and option checks."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import Radau, solve_ivp

from csim.solver.dae import RadauDAE

G = 9.81
THETA0 = 0.3  # initial angle of the pendulum from the downward vertical [rad]
T_END = 10.0
DIFF = np.array([True, True, True, True, False, False])


MAX_STEPS = 10_000  # far above every run here: a broken solver fails instead of crawling


def run(solver):
    """Step to the end; returns the accepted times, states and the last message."""
    ts, ys, msg = [solver.t], [solver.y.copy()], None
    while solver.status == "running":
        assert len(ts) < MAX_STEPS, f"more than {MAX_STEPS} steps by t = {solver.t}"
        msg = solver.step()
        if solver.status != "failed":
            ts.append(solver.t)
            ys.append(solver.y.copy())
    return np.array(ts), np.array(ys), msg


# --- ODEs: the same algorithm as scipy's Radau --------------------------------------------

def decay(t, y):
    return -y


def oscillator(t, y):
    return np.array([y[1], -y[0]])


def prothero_robinson(t, y):
    # stiff and non-autonomous: y' = -1000 (y - cos t) - sin t,  y = cos t
    return -1000.0 * (y - np.cos(t)) - np.sin(t)


@pytest.mark.parametrize("fun, y0, t_end, exact", [
    (decay, [1.0], 5.0, lambda t: np.exp(-t)),
    (oscillator, [1.0, 0.0], 2 * np.pi, lambda t: np.cos(t)),
    (prothero_robinson, [1.0], 5.0, lambda t: np.cos(t)),
])
@pytest.mark.parametrize("tol", [1e-4, 1e-7, 1e-9])
def test_ode_matches_exact_solution_and_scipy_radau(fun, y0, t_end, exact, tol):
    n = len(y0)
    ours = RadauDAE(fun, 0.0, y0, t_end, np.ones(n, bool), rtol=tol, atol=tol)
    ts, ys, _ = run(ours)
    assert ours.status == "finished" and ts[-1] == t_end
    assert abs(ys[-1, 0] - exact(t_end)) < 10 * tol

    ref = Radau(fun, 0.0, y0, t_end, rtol=tol, atol=tol)
    ts_ref, ys_ref, _ = run(ref)
    assert abs(len(ts) - len(ts_ref)) <= 0.2 * len(ts_ref)
    # nfev here also counts the n evaluations of each finite-difference Jacobian
    assert abs((ours.nfev - n * ours.njev) - ref.nfev) <= 0.2 * ref.nfev
    np.testing.assert_allclose(ys[-1], ys_ref[-1], rtol=1e-8, atol=1e-12)


def test_ode_dense_output_is_accurate_between_steps():
    s = RadauDAE(oscillator, 0.0, [1.0, 0.0], 10.0, np.ones(2, bool), rtol=1e-8, atol=1e-8)
    worst = 0.0
    while s.status == "running":
        assert s.nfev < 20 * MAX_STEPS
        s.step()
        t_mid = np.linspace(s.t_old, s.t, 5)[1:-1]
        y_mid = s.dense_output()(t_mid)  # (n, 3)
        assert y_mid.shape == (2, 3) and s.dense_output()(t_mid[0]).shape == (2,)
        worst = max(worst, np.max(np.abs(y_mid[0] - np.cos(t_mid))))
    assert worst < 1e-6


def test_copied_constants_are_scipys():
    scipy_radau = pytest.importorskip("scipy.integrate._ivp.radau")
    from csim.solver import dae

    for name in ("C", "E", "T", "TI", "P", "MU_REAL", "MU_COMPLEX"):
        np.testing.assert_array_equal(getattr(dae, name), getattr(scipy_radau, name), err_msg=name)


# --- index 1 -------------------------------------------------------------------------------

def index1(t, y):
    # y' = -z,  0 = z - y   ->   y = z = exp(-t)
    return np.array([-y[1], y[1] - y[0]])


@pytest.mark.parametrize("index2", [None, np.array([False, False])])
@pytest.mark.parametrize("tol", [1e-5, 1e-9])
def test_index1_dae_is_accurate(index2, tol):
    s = RadauDAE(index1, 0.0, [1.0, 1.0], 5.0, np.array([True, False]), rtol=tol, atol=tol, index2=index2)
    ts, ys, _ = run(s)
    assert s.status == "finished"
    err = np.abs(ys - np.exp(-ts)[:, None])
    assert err.max() < 10 * tol
    # the algebraic equation holds at every step
    assert np.max(np.abs(ys[:, 1] - ys[:, 0])) <= 1e-12


def nonautonomous(t, y):
    # y' = z,  0 = z - cos(t)   ->   y = sin(t), z = cos(t)
    return np.array([y[1], y[1] - np.cos(t)])


@pytest.mark.parametrize("tol", [1e-5, 1e-9])
def test_nonautonomous_index1_dae_is_accurate(tol):
    s = RadauDAE(nonautonomous, 0.0, [0.0, 1.0], 5.0, np.array([True, False]), rtol=tol, atol=tol,
                 index2=np.array([False, False]))
    ts, ys, _ = run(s)
    assert s.status == "finished"
    assert np.max(np.abs(ys[:, 0] - np.sin(ts))) < 10 * tol
    assert np.max(np.abs(ys[:, 1] - np.cos(ts))) <= 1e-12


def test_usable_from_solve_ivp():
    def fun(t, y):  # a broken solver must fail here, not crawl
        calls.append(t)
        assert len(calls) < 20 * MAX_STEPS
        return index1(t, y)

    calls = []
    sol = solve_ivp(fun, (0.0, 2.0), [1.0, 1.0], method=RadauDAE, differential=np.array([True, False]),
                    rtol=1e-8, atol=1e-8, dense_output=True)
    assert sol.success
    np.testing.assert_allclose(sol.sol(1.3), np.exp(-1.3), rtol=1e-6)


# --- index 2: the GGL pendulum -------------------------------------------------------------

def pendulum(t, s):
    """GGL form of the unit pendulum, Phi = (x^2 + y^2 - 1)/2, Phi_q = [x, y], m = L = 1.

    q' = v - Phi_q^T mu,  v' = -Phi_q^T lam + (0, -g),  0 = Phi(q),  0 = Phi_q v.
    """
    x, y, vx, vy, mu, lam = s
    return np.array([vx - x * mu, vy - y * mu, -x * lam, -y * lam - G,
                     0.5 * (x * x + y * y - 1.0), x * vx + y * vy])


def pendulum_jac(t, s):
    x, y, vx, vy, mu, lam = s
    return np.array([
        [-mu, 0, 1, 0, -x, 0],
        [0, -mu, 0, 1, -y, 0],
        [-lam, 0, 0, 0, 0, -x],
        [0, -lam, 0, 0, 0, -y],
        [x, y, 0, 0, 0, 0],
        [vx, vy, x, y, 0, 0],
    ], dtype=float)


def consistent_start():
    # at rest at THETA0: mu = 0; lam from d/dt(Phi_q v) = v.v + q.v' = v.v - lam |q|^2 - g y = 0
    x, y = np.sin(THETA0), -np.cos(THETA0)
    lam = (0.0 - G * y) / (x * x + y * y)
    return np.array([x, y, 0.0, 0.0, 0.0, lam])


def ref_angle(reference, t):
    return reference(t)[0]


def angle(states):
    states = np.atleast_2d(states)
    return np.arctan2(states[:, 0], -states[:, 1])


@pytest.fixture(scope="module")
def reference():
    """theta'' = -g sin(theta) in the minimal coordinate, DOP853 at 1e-12."""
    sol = solve_ivp(lambda t, u: [u[1], -G * np.sin(u[0])], (0.0, T_END), [THETA0, 0.0],
                    method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    return sol.sol


def test_pendulum_start_is_consistent():
    s0 = consistent_start()
    f = pendulum(0.0, s0)
    q, v, v_dot = s0[:2], s0[2:4], f[2:4]
    assert np.all(f[4:] == 0)  # Phi = 0, Phi_q v = 0
    assert abs(v @ v + q @ v_dot) < 1e-14  # d/dt (Phi_q v) = 0
    assert np.all(f[:2] == 0)  # q' = v - Phi_q^T mu = 0


@pytest.fixture(scope="module")
def pendulum_run():
    """10 s at rtol = atol = 1e-8 with the finite-difference Jacobian, checked every step."""
    s = RadauDAE(pendulum, 0.0, consistent_start(), T_END, DIFF, rtol=1e-8, atol=1e-8)
    ts, ys, t_mid, y_mid = [0.0], [s.y.copy()], [], []
    while s.status == "running":
        assert len(ts) < MAX_STEPS, f"more than {MAX_STEPS} steps by t = {s.t}"
        s.step()
        ts.append(s.t)
        ys.append(s.y.copy())
        t_in = np.linspace(s.t_old, s.t, 4)[1:-1]
        t_mid.extend(t_in)
        y_mid.extend(s.dense_output()(t_in).T)
    return s, np.array(ts), np.array(ys), np.array(t_mid), np.array(y_mid)


def test_ggl_pendulum_holds_both_constraints_at_every_step(pendulum_run):
    s, ts, ys, _, _ = pendulum_run
    assert s.status == "finished" and ts[-1] == T_END
    # about 850 steps; the plain (index-1) scale on mu, lam would take about 3500
    assert len(ts) < 1500
    x, y, vx, vy = ys[:, :4].T
    phi = 0.5 * (x * x + y * y - 1.0)
    phi_v = x * vx + y * vy
    assert np.max(np.abs(phi)) <= 1e-12  # algebraic_tol, no projection
    assert np.max(np.abs(phi_v)) <= 1e-12


def test_ggl_pendulum_motion_matches_minimal_coordinates(pendulum_run, reference):
    s, ts, ys, t_mid, y_mid = pendulum_run
    assert np.max(np.abs(angle(ys) - ref_angle(reference, ts))) < 1e-8
    # the dense output between steps: the collocation polynomial, order 3 inside the step
    assert np.max(np.abs(angle(y_mid) - ref_angle(reference, t_mid))) < 1e-7


def test_ggl_pendulum_multipliers(pendulum_run, reference):
    s, ts, ys, _, _ = pendulum_run
    mu, lam = ys[:, 4], ys[:, 5]
    # mu is zero in the exact solution; it is an index-2 variable controlled with the
    # scale (atol + rtol |mu|)/h, so it carries the O(h^3) collocation error (~1e-6 here)
    assert np.max(np.abs(mu)) < 1e-5
    # lam = tension = g cos(theta) + theta'^2
    theta, theta_dot = reference(ts)
    np.testing.assert_allclose(lam, G * np.cos(theta) + theta_dot**2, atol=1e-4)  # measured 6e-6


def pendulum_with_jac(tol, t_end=T_END, **options):
    """The pendulum with its analytic Jacobian, to the end."""
    s = RadauDAE(pendulum, 0.0, consistent_start(), t_end, DIFF, rtol=tol, atol=tol, jac=pendulum_jac, **options)
    ts, ys, _ = run(s)
    assert s.status == "finished"
    return s, ts, ys


def test_ggl_pendulum_converges_as_the_tolerance_tightens(reference):
    errors, mus = [], []
    for tol in (1e-6, 1e-9):
        s, ts, ys = pendulum_with_jac(tol, t_end=5.0)
        errors.append(np.max(np.abs(angle(ys) - ref_angle(reference, ts))))
        mus.append(np.max(np.abs(ys[:, 4])))
    assert errors[0] < 1e-6
    assert errors[1] < errors[0] / 300
    assert mus[1] < mus[0] / 30


def test_constraint_polishing_is_what_holds_phi():
    # at rtol 1e-6 the plain Newton test stops with |Phi| ~ 1e-9; algebraic_tol drives it down
    loose, _, ys_loose = pendulum_with_jac(1e-6, t_end=3.0, algebraic_tol=1e300)
    tight, _, ys_tight = pendulum_with_jac(1e-6, t_end=3.0)
    phi = lambda ys: np.max(np.abs(0.5 * (ys[:, 0] ** 2 + ys[:, 1] ** 2 - 1.0)))  # noqa: E731
    assert phi(ys_loose) > 1e-10
    assert phi(ys_tight) <= 1e-12
    assert tight.nfev < 2 * loose.nfev


# --- failures and options ------------------------------------------------------------------

def test_algebraic_equation_without_solution_fails_cleanly():
    # y' = z,  0 = z^2 + t - 1: z = sqrt(1 - t) ceases to exist at t = 1
    s = RadauDAE(lambda t, y: np.array([y[1], y[1] ** 2 + t - 1.0]), 0.0, [0.0, 1.0], 2.0,
                 np.array([True, False]), rtol=1e-6, atol=1e-6)
    _, _, msg = run(s)
    assert s.status == "failed"
    assert "Newton iteration did not converge" in msg or msg == s.TOO_SMALL_STEP
    assert 0.99 < s.t < 1.0 + 1e-9


def test_singular_iteration_matrix_is_named():
    # the algebraic row does not involve z: (MU/h D - J) is singular for every h
    s = RadauDAE(lambda t, y: np.array([-y[0], y[0] - y[0]]), 0.0, [1.0, 0.0], 1.0, np.array([True, False]))
    _, _, msg = run(s)
    assert s.status == "failed"
    assert msg.startswith("Newton iteration did not converge at t = 0; singular iteration matrix")


def test_non_finite_right_hand_side_shrinks_then_fails():
    def fun(t, y):
        return np.array([-y[1], y[1] - np.sqrt(0.5 - t) if t <= 0.5 else np.nan])

    s = RadauDAE(fun, 0.0, [0.0, np.sqrt(0.5)], 1.0, np.array([True, False]), rtol=1e-6, atol=1e-6)
    _, _, msg = run(s)
    assert s.status == "failed"
    assert "non-finite right-hand side" in msg
    assert 0.49 < s.t <= 0.5


def test_inconsistent_start_fails_with_a_hint():
    y0 = consistent_start()
    y0[:2] *= 1.001  # |q| = 1.001: Phi = 1e-3
    s = RadauDAE(pendulum, 0.0, y0, 1.0, DIFF, rtol=1e-8, atol=1e-8)
    _, _, msg = run(s)
    assert s.status == "failed" and s.t == 0.0
    assert "Is the initial state consistent" in msg and "max |F_alg(t0, y0)| = 0.001" in msg


@pytest.mark.parametrize("options, message", [
    (dict(differential=np.array([1, 0])), "`differential` must be a boolean array of shape \\(2,\\)"),
    (dict(differential=np.array([True])), "`differential` must be a boolean array of shape \\(2,\\)"),
    (dict(algebraic_tol=0.0), "`algebraic_tol` must be positive"),
    (dict(algebraic_tol=np.nan), "`algebraic_tol` must be positive"),
    (dict(index2=np.array([True, True])), "`index2` may be True only on algebraic rows"),
    (dict(index2=np.array([0, 1])), "`index2` must be a boolean array"),
    (dict(rtol=-1.0), "`rtol` must be a positive scalar"),
    (dict(atol=-1.0), "`atol` must be non-negative"),
    (dict(atol=[1e-6, 1e-6, 1e-6]), "`atol` must be a scalar or an array of shape \\(2,\\)"),
    (dict(max_step=0.0), "`max_step` must be positive"),
    (dict(first_step=-1.0), "`first_step` must be positive"),
    (dict(first_step=5.0), "`first_step` exceeds bounds"),
    (dict(jac=lambda t, y: np.eye(3)), "`jac` is expected to have shape \\(2, 2\\)"),
])
def test_bad_options_are_rejected(options, message):
    kwargs = dict(differential=np.array([True, False]))
    kwargs.update(options)
    with pytest.raises(ValueError, match=message):
        RadauDAE(index1, 0.0, [1.0, 1.0], 1.0, **kwargs)


@pytest.mark.parametrize("tol", [1e-8, 1e-10, 1e-11])
def test_moving_start_at_tight_tolerances_with_the_difference_jacobian(tol):
    # mu starts at 0: a difference step of sqrt(eps) atol did not change F at all, the
    # Jacobian's mu columns came out zero and the iteration matrix singular for every h
    # (this failed at t = 0 for tol <= 1e-10 before the algebraic threshold floor)
    theta, w = 0.3, 2.0
    x, y = np.sin(theta), -np.cos(theta)
    vx, vy = w * np.cos(theta), w * np.sin(theta)  # tangential, |v| = w
    lam = vx * vx + vy * vy - G * y  # d/dt (Phi_q v) = v.v - lam |q|^2 - g y = 0, |q| = 1
    s = RadauDAE(pendulum, 0.0, np.array([x, y, vx, vy, 0.0, lam]), 1.0, DIFF, rtol=tol, atol=tol)
    J = s.jac(0.0, s.y, s.f)
    np.testing.assert_allclose(J[:, 4:], pendulum_jac(0.0, s.y)[:, 4:], rtol=1e-5, atol=1e-5)
    while s.status == "running":
        s.step()
    assert s.status == "finished"
    assert abs((s.y[:2] @ s.y[:2] - 1) / 2) < 1e-10


# --- a coordinate that starts at 0 ---------------------------------------------------------

PIVOT = np.array([0.3, 0.2])  # pivot of an offset pendulum: x = 0 is not a special point of it


def offset_pendulum(t, s):
    """The GGL pendulum of :func:`pendulum` hanging from PIVOT instead of the origin."""
    x, y, vx, vy, mu, lam = s
    X, Y = x - PIVOT[0], y - PIVOT[1]
    return np.array([vx - X * mu, vy - Y * mu, -X * lam, -Y * lam - G, 0.5 * (X * X + Y * Y - 1.0),
                     X * vx + Y * vy])


def offset_pendulum_jac(t, s):
    x, y, vx, vy, mu, lam = s
    X, Y = x - PIVOT[0], y - PIVOT[1]
    return np.array([[-mu, 0, 1, 0, -X, 0], [0, -mu, 0, 1, -Y, 0], [-lam, 0, 0, 0, 0, -X],
                     [0, -lam, 0, 0, 0, -Y], [X, Y, 0, 0, 0, 0], [vx, vy, X, Y, 0, 0]], dtype=float)


@pytest.mark.parametrize("tol", [1e-10, 1e-12])
def test_a_coordinate_at_zero_gets_an_accurate_jacobian_column(tol):
    # x starts at exactly 0 and is added to the pivot's -0.3: a difference step of
    # sqrt(eps) atol (1.5e-22 at atol = 1e-12) vanished in x - 0.3, the column came out as
    # round-off, and the first step failed ("iteration diverged") at every step size
    X, Y, w = -PIVOT[0], -np.sqrt(1 - PIVOT[0] ** 2), 2.0
    vx, vy = -Y * w, X * w  # tangential, |v| = w
    lam = vx * vx + vy * vy - G * Y  # d/dt (Phi_q v) = v.v - lam |q - pivot|^2 - g Y = 0
    s = RadauDAE(offset_pendulum, 0.0, np.array([0.0, Y + PIVOT[1], vx, vy, 0.0, lam]), 1.0, DIFF, rtol=tol,
                 atol=tol)
    J, J_exact = s.jac(0.0, s.y, s.f), offset_pendulum_jac(0.0, s.y)
    np.testing.assert_allclose(J, J_exact, rtol=0, atol=1e-3 * np.abs(J_exact).max())  # measured 4e-4 / 15
    ts, ys, msg = run(s)
    assert s.status == "finished", msg
    X_end, Y_end = ys[-1, 0] - PIVOT[0], ys[-1, 1] - PIVOT[1]
    assert abs((X_end**2 + Y_end**2 - 1) / 2) < 1e-12
    # the energy of the swing is kept: 1/2 |v|^2 + g y
    energy = 0.5 * (ys[:, 2] ** 2 + ys[:, 3] ** 2) + G * ys[:, 1]
    assert np.max(np.abs(energy - energy[0])) < 1e3 * tol


def test_a_variable_f_does_not_depend_on_keeps_a_finite_difference_step():
    # z enters no row: num_jac multiplied its step by 10 at every Jacobian (inf after ~300)
    s = RadauDAE(lambda t, y: np.array([-y[0], 0.0 * y[1]]), 0.0, [1.0, 0.0], 1.0, np.array([True, True]),
                 rtol=1e-6, atol=1e-6)
    for _ in range(400):
        s.jac(s.t, s.y, s.f)
    assert np.all(np.isfinite(s.jac_factor)) and s.jac_factor.max() <= 0.1
