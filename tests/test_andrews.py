"""Andrews' squeezing mechanism against the IVP test set's problem "andrews" (Mazzia and Magherini).

The reference equations below are the test set's hand-written ones (its subroutine F:
mass matrix, force vector, constraints, constraint Jacobian) and its consistent initial
values and reference solution at t = 0.03 s; csim derives its own from T, V and Phi(q).
"""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS

from csim.case import load_case
from csim.pipeline import build_system, initial_state, run_case

# --- the test set's data and equations (independent of csim/mechanisms/andrews.py) ---------
m1, m2, m3, m4, m5, m6, m7 = .04325, .00365, .02373, .00706, .07050, .00706, .05498
i1, i2, i3, i4, i5, i6, i7 = 2.194e-6, 4.410e-7, 5.255e-6, 5.667e-7, 1.169e-5, 5.667e-7, 1.912e-5
xa, ya, xb, yb, xc, yc = -.06934, -.00227, -.03635, .03273, .014, .072
d, da, e, ea, rr, ra = 28e-3, 115e-4, 2e-2, 1421e-5, 7e-3, 92e-5
ss, sa, sb, sc, sd = 35e-3, 1874e-5, 1043e-5, 18e-3, 2e-2
ta, tb, u, ua, ub = 2308e-5, 916e-5, 4e-2, 1228e-5, 449e-5
zf, zt, fa, mom, c0, l0 = 2e-2, 4e-2, 1421e-5, 33e-3, 4530.0, 7785e-5

#: consistent initial positions (at rest), accelerations and multipliers (test set, INITIAL)
Q0 = np.array([-0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
               0.222668390165885884674473185609, 0.487364979543842550225598953530,
               -0.222668390165885884674473185609, 1.23054744454982119249735015568])
QDD0 = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415, 0, 0, 0, 0, 0])
LAMBDA0 = np.array([98.5668703962410896057654982170, -6.12268834425566265503114393122, 0, 0, 0, 0])
#: reference solution at t = 0.03 s (test set, SOLN): positions [rad], velocities [rad/s]
Q_END = np.array([0.1581077119629904e2, -0.1575637105984298e2, 0.4082224013073101e-1, -0.5347301163226948,
                  0.5244099658805304, 0.5347301163226948, 0.1048080741042263e1])
QD_END = np.array([0.1139920302151208e4, -0.1424379294994111e4, 0.1103291221937134e2, 0.1929337464421385e2,
                   0.5735699284790808, -0.1929337464421385e2, 0.3231791658026955])


def mass_matrix(q):
    """The test set's M(q) (7, 7) [kg m^2]."""
    _, th, _, ph, _, om, _ = q
    M = np.zeros((7, 7))
    M[0, 0] = m1 * ra**2 + m2 * (rr**2 - 2 * da * rr * np.cos(th) + da**2) + i1 + i2
    M[1, 0] = M[0, 1] = m2 * (da**2 - da * rr * np.cos(th)) + i2
    M[1, 1] = m2 * da**2 + i2
    M[2, 2] = m3 * (sa**2 + sb**2) + i3
    M[3, 3] = m4 * (e - ea)**2 + i4
    M[4, 3] = M[3, 4] = m4 * ((e - ea)**2 + zt * (e - ea) * np.sin(ph)) + i4
    M[4, 4] = m4 * (zt**2 + 2 * zt * (e - ea) * np.sin(ph) + (e - ea)**2) + m5 * (ta**2 + tb**2) + i4 + i5
    M[5, 5] = m6 * (zf - fa)**2 + i6
    M[6, 5] = M[5, 6] = m6 * ((zf - fa)**2 - u * (zf - fa) * np.sin(om)) + i6
    M[6, 6] = m6 * ((zf - fa)**2 - 2 * u * (zf - fa) * np.sin(om) + u**2) + m7 * (ua**2 + ub**2) + i6 + i7
    return M


def spring_point(q):
    """D = (xd, yd) [m], the spring's end on the triangle."""
    ga = q[2]
    return np.array([sd * np.cos(ga) + sc * np.sin(ga) + xb, sd * np.sin(ga) - sc * np.cos(ga) + yb])


def forces(q, qd):
    """The test set's ff(q, qd) (7,): torque, spring and velocity terms, M qdd = ff - G^T lambda."""
    _, th, ga, ph, _, om, _ = q
    bep, thp, _, php, dep, omp, epp = qd
    xd, yd = spring_point(q)
    lang = np.hypot(xd - xc, yd - yc)
    force = -c0 * (lang - l0) / lang
    fx, fy = force * (xd - xc), force * (yd - yc)
    return np.array([
        mom - m2 * da * rr * thp * (thp + 2 * bep) * np.sin(th),
        m2 * da * rr * bep**2 * np.sin(th),
        fx * (sc * np.cos(ga) - sd * np.sin(ga)) + fy * (sd * np.cos(ga) + sc * np.sin(ga)),
        m4 * zt * (e - ea) * dep**2 * np.cos(ph),
        -m4 * zt * (e - ea) * php * (php + 2 * dep) * np.cos(ph),
        -m6 * u * (zf - fa) * epp**2 * np.cos(om),
        m6 * u * (zf - fa) * omp * (omp + 2 * epp) * np.cos(om)])


def constraints(q):
    """The test set's g(q) (6,) [m]."""
    be, th, ga, ph, de, om, ep = q
    base = np.array([rr * np.cos(be) - d * np.cos(be + th), rr * np.sin(be) - d * np.sin(be + th)])
    return np.array([
        base[0] - ss * np.sin(ga) - xb, base[1] + ss * np.cos(ga) - yb,
        base[0] - e * np.sin(ph + de) - zt * np.cos(de) - xa, base[1] + e * np.cos(ph + de) - zt * np.sin(de) - ya,
        base[0] - zf * np.cos(om + ep) - u * np.sin(ep) - xa, base[1] - zf * np.sin(om + ep) + u * np.cos(ep) - ya])


def constraint_jacobian(q):
    """The test set's G(q) = dg/dq (6, 7) [m/rad]."""
    be, th, ga, ph, de, om, ep = q
    G = np.zeros((6, 7))
    G[0::2, 0] = -rr * np.sin(be) + d * np.sin(be + th)
    G[0::2, 1] = d * np.sin(be + th)
    G[1::2, 0] = rr * np.cos(be) - d * np.cos(be + th)
    G[1::2, 1] = -d * np.cos(be + th)
    G[0, 2], G[1, 2] = -ss * np.cos(ga), -ss * np.sin(ga)
    G[2, 3], G[2, 4] = -e * np.cos(ph + de), -e * np.cos(ph + de) + zt * np.sin(de)
    G[3, 3], G[3, 4] = -e * np.sin(ph + de), -e * np.sin(ph + de) - zt * np.cos(de)
    G[4, 5], G[4, 6] = zf * np.sin(om + ep), zf * np.sin(om + ep) - u * np.cos(ep)
    G[5, 5], G[5, 6] = -zf * np.cos(om + ep), -zf * np.cos(om + ep) - u * np.sin(ep)
    return G


def spring_energy(q):
    """1/2 c0 (l - l0)^2 [J]."""
    xd, yd = spring_point(q)
    return 0.5 * c0 * (np.hypot(xd - xc, yd - yc) - l0) ** 2


PYTHON = ["simulation.backend=python"]


@pytest.fixture(scope="module")
def system():
    """csim's system of configs/andrews.yaml (the model derived once per test session)."""
    return build_system(load_case(CONFIGS / "andrews.yaml", PYTHON))


def test_derived_equations_are_the_test_sets(system):
    model, par = system.model, system.par
    rng = np.random.default_rng(15)
    for _ in range(5):
        q, qd = rng.uniform(-np.pi, np.pi, 7), rng.uniform(-200, 200, 7)
        M = mass_matrix(q)
        np.testing.assert_allclose(model.mass(q, par), M, rtol=0, atol=1e-14 * np.abs(M).max())
        # p = B u - C qd - h, with the torque u = mom
        p = model.load_matrix(q, par) @ [mom] - model.velocity_terms(q, qd, par) - model.gravity(q, par)
        f = forces(q, qd)
        np.testing.assert_allclose(p, f, rtol=0, atol=1e-12 * np.abs(f).max())
        np.testing.assert_allclose(model.phi(q, par), constraints(q), rtol=0, atol=1e-15)
        np.testing.assert_allclose(model.phi_q(q, par), constraint_jacobian(q), rtol=0, atol=1e-15)
        # gamma = -(G qd)_q qd, here from a central difference of G along qd
        h = 1e-6
        Gdot = (constraint_jacobian(q + h * qd) - constraint_jacobian(q - h * qd)) / (2 * h)
        np.testing.assert_allclose(model.gamma(q, qd, par), -Gdot @ qd, rtol=0, atol=1e-6 * np.abs(Gdot @ qd).max())


def test_the_start_is_the_test_sets_consistent_state(system):
    case = load_case(CONFIGS / "andrews.yaml", PYTHON)
    y0 = initial_state(case, system)
    q0, qd0 = y0[:7], y0[7:14]
    np.testing.assert_allclose(q0, Q0, rtol=0, atol=1e-15)  # Newton from the guess, beta given
    assert np.all(qd0 == 0)
    ev = system.evaluate(0.0, y0, np.zeros(0, bool))
    np.testing.assert_allclose(ev.qdd, QDD0, rtol=1e-12, atol=1e-8)
    np.testing.assert_allclose(ev.lam, LAMBDA0, rtol=1e-12, atol=1e-10)


@pytest.fixture(scope="module")
def projection_run(system):
    """configs/andrews.yaml as it is (projection, DOP853 at rtol = atol = 1e-10), Python path."""
    return run_case(load_case(CONFIGS / "andrews.yaml", PYTHON))


def test_projection_agrees_with_the_published_reference(projection_run):
    res = projection_run
    assert res.ok, res.message
    assert res.t[-1] == pytest.approx(0.03, abs=1e-15)
    # measured 1.6e-9 rad (|beta| = 15.8) and 6.2e-7 rad/s (|Theta'| = 1424, 5.6e-8 relative)
    np.testing.assert_allclose(res.q[-1], Q_END, rtol=0, atol=1e-8)
    np.testing.assert_allclose(res.qd[-1], QD_END, rtol=1e-9, atol=1e-6)
    assert res.max_phi < 1e-12 and res.max_phi_dot < 1e-12


def test_the_work_of_the_torque_is_the_change_of_the_energy(projection_run):
    # T and V here from the test set's M and spring, W = mom (beta - beta0) for a constant torque
    res = projection_run
    T = np.array([0.5 * qd @ mass_matrix(q) @ qd for q, qd in zip(res.q, res.qd)])
    V = np.array([spring_energy(q) for q in res.q])
    W = mom * (res.q[:, 0] - res.q[0, 0])
    balance = T + V - V[0] - W
    assert np.max(np.abs(balance)) < 1e-9 * np.max(np.abs(W))  # measured 3.4e-11 relative
    # csim's own record of the same balance
    np.testing.assert_allclose(res.kinetic, T, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(res.work[:, 0], W, rtol=1e-8, atol=1e-12)


def test_the_declared_figures_are_drawn_from_a_result_file(tmp_path_factory):
    from conftest import simulated_file

    from csim.plot import RUN_FIGURES, plot_file
    from csim.plot.series import series_names
    from csim.plot.source import load_run

    path = simulated_file(tmp_path_factory, "andrews.yaml", "andrews.h5", *PYTHON, "simulation.t_end=0.005")
    run = load_run(path)
    valid = set(series_names(run))
    names = [f.name for f in run.definition.figures]
    assert names == ["crank", "configurations"] and not set(names) & set(RUN_FIGURES)
    for figure in run.definition.figures:
        for panel in figure.panels:
            assert all(name in valid for name in panel.series), (figure.name, panel.series)
    report = plot_file(path, tmp_path_factory.mktemp("plots"), only=names)
    assert sorted(p.name for p in report.written) == ["configurations.png", "crank.png"]
