"""Reference motions of IFToMM benchmark problems A01, A02 and A05, independent of csim.

A01 and A02 reduce to one degree of freedom with a closed-form or scalar-ODE solution:

- A01, a point mass m on a massless link L released at rest from the horizontal:
  theta (from the downward vertical) obeys theta'' = -(g / L) sin theta; with k = sin(theta0 / 2),
  sin(theta / 2) = k sn(K(k) - sqrt(g / L) t, k) (Jacobi's elliptic sn, modulus k).
- A02, N four-bars kept in the parallelogram: every crank turns by the same angle theta, the
  couplers translate. T = 1/2 ((N + 1) / 3 + N) theta'^2 and V = g ((N + 1) / 2 + N) sin theta
  (1 m, 1 kg uniform rods), so theta'' = -g c / I cos theta with I = (N + 1) / 3 + N,
  c = (N + 1) / 2 + N; from theta = pi / 2, theta' = -1 rad/s (B0 at +1 m/s along x).

A05, the flyball governor with its shaft turned at a constant Omega, has three degrees of
freedom left, written here in the shaft's rotating frame (Lagrange's equations derived by
sympy from T and V, not from csim's link tables): the slider height s and the angles
theta_1, theta_2 of the rods below the horizontal. Each rod (with its point mass at the end)
is pinned at (+-e, 0, L) and swings in the shaft's x-z plane; its spring-damper joins its
middle to the slider at (+-e, 0, s). With the rod's angular velocity Omega z + theta' y,
T = sum 1/2 m |v|^2 + 1/2 omega.I omega, and the drive torque is d/dt (dT/dOmega).
"""
from __future__ import annotations

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.special import ellipj, ellipk

G = 9.81


def a01_point(t: np.ndarray, length: float = 1.0, g: float = G) -> np.ndarray:
    """P1 (N, 2) [m] of the A01 pendulum at times t (N,) [s], released at (L, 0)."""
    k = np.sin(np.pi / 4)
    m = k * k
    K = ellipk(m)
    u = np.mod(K - np.sqrt(g / length) * np.asarray(t, dtype=float), 4 * K)  # sn has period 4 K
    theta = 2 * np.arcsin(k * ellipj(u, m)[0])
    return length * np.column_stack((np.sin(theta), -np.cos(theta)))


def a02_crank(t: np.ndarray, n: int, g: float = G) -> tuple[np.ndarray, np.ndarray]:
    """The common crank angle theta (N,) [rad] and its rate [rad/s] of A02 with n four-bars."""
    inertia, moment = (n + 1) / 3 + n, (n + 1) / 2 + n
    t = np.asarray(t, dtype=float)
    sol = solve_ivp(lambda _, y: [y[1], -g * moment / inertia * np.cos(y[0])], (0.0, float(t[-1])),
                    [np.pi / 2, -1.0], t_eval=t, rtol=1e-13, atol=1e-13, method="DOP853")
    return sol.y[0], sol.y[1]


def a02_b0(t: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Position (N, 2) [m] and velocity (N, 2) [m/s] of B0, the top of the first crank."""
    theta, rate = a02_crank(t, n)
    c, s = np.cos(theta), np.sin(theta)
    return np.column_stack((c, s)), np.column_stack((-s * rate, c * rate))


#: A05's data (the IFToMM specification): lengths [m], density [kg/m^3], masses [kg], spring
A05 = dict(L=1.0, b=0.01, e=0.05, a=0.1, rho=3000.0, mp=5.0, K=8.0e5, C=4.0e4, l0=0.5, w=2 * np.pi, g=G)


def _a05_equations():
    """Lambdified M(x) (3, 3), f(x, v) (3,) with M xdd = f, and the drive torque tau(x, v, a),
    for x = [s, theta_1, theta_2] [m, rad, rad] in the shaft's rotating frame."""
    p = A05
    t = sp.Symbol("t")
    s, th1, th2, phi = (sp.Function(n)(t) for n in ("s", "th1", "th2", "phi"))
    L, e = p["L"], p["e"]
    mr = p["rho"] * L * p["b"] ** 2  # a rod (and the shaft) [kg]
    ms = p["rho"] * p["a"] ** 3  # the slider [kg]
    i_axial, i_cross = mr * p["b"] ** 2 / 6, mr * (L**2 + p["b"] ** 2) / 12  # a rod about its middle
    spin = phi.diff(t) * sp.Matrix([0, 0, 1])  # the shaft's angular velocity
    T, V, springs = sp.Rational(1, 2) * ms * s.diff(t) ** 2, ms * p["g"] * s, []
    for sign, th in ((1, th1), (-1, th2)):
        pin = sp.Matrix([sign * e, 0, L])
        u = sp.Matrix([sign * sp.cos(th), 0, -sp.sin(th)])  # along the rod, theta below the horizontal
        for mass, xi in ((mr, L / 2), (p["mp"], L)):  # the rod's middle, the point mass
            r = pin + xi * u
            v = r.diff(t) + spin.cross(r)  # velocity, in the rotating frame's axes
            T += sp.Rational(1, 2) * mass * v.dot(v)
            V += mass * p["g"] * r[2]
        # the rod's rotation about its middle, in its principal axes (x_b along the rod,
        # y_b the pin axis, about which theta increases)
        y_b = sp.Matrix([0, sign, 0])
        omega = spin + th.diff(t) * y_b
        T += sp.Rational(1, 2) * (i_axial * omega.dot(u) ** 2 + i_cross * (omega.dot(y_b) ** 2
                                                                         + omega.dot(u.cross(y_b)) ** 2))
        d = pin + (L / 2) * u - sp.Matrix([sign * e, 0, s])
        length = sp.sqrt(d.dot(d))
        V += sp.Rational(1, 2) * p["K"] * (length - p["l0"]) ** 2
        springs.append(length)
    q = [s, th1, th2]
    Lag = T - V
    # Lagrange's equations with the dampers' generalized force -C ldot dl/dq; the shaft's
    # equation gives the torque that holds phi'' = 0 (V, the springs and the dampers do
    # not depend on phi)
    residual = [sp.diff(Lag.diff(x.diff(t)), t) - Lag.diff(x) + sum(p["C"] * l.diff(t) * l.diff(x) for l in springs)
                for x in q]
    torque = sp.diff(T.diff(phi.diff(t)), t)
    xs, vs, accs = (sp.symbols(f"{k}0:3") for k in "xva")
    plain = {phi.diff(t, 2): 0, phi.diff(t): p["w"]}
    for i, x in enumerate(q):
        plain.update({x.diff(t, 2): accs[i], x.diff(t): vs[i]})
    plain.update({x: xs[i] for i, x in enumerate(q)})
    residual = [sp.expand(r.subs(plain)) for r in residual]
    M = sp.Matrix([[r.coeff(a) for a in accs] for r in residual])
    f = -(sp.Matrix(residual) - M * sp.Matrix(accs)).applyfunc(sp.expand)
    return (sp.lambdify([xs], M, "numpy"), sp.lambdify([xs, vs], f, "numpy"),
            sp.lambdify([xs, vs, accs], torque.subs(plain), "numpy"))


def a05_motion(t: np.ndarray, theta0: float = np.pi / 6, s0: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """The governor from rest in the rotating frame: states (N, 6) = [s, theta_1, theta_2 and
    their rates] [m, rad, rad/s...] and the drive torque (N,) [N m] at times t (N,) [s]."""
    mass, force, torque = _a05_equations()
    t = np.asarray(t, dtype=float)

    def rhs(_, y):
        return np.concatenate((y[3:], np.linalg.solve(mass(y[:3]), np.ravel(force(y[:3], y[3:])))))

    sol = solve_ivp(rhs, (0.0, float(t[-1])), [s0, theta0, theta0, 0.0, 0.0, 0.0], t_eval=t, method="Radau",
                    rtol=1e-12, atol=1e-12)
    y = sol.y.T
    tau = np.array([float(torque(x[:3], x[3:], rhs(0.0, x)[3:])) for x in y])
    return y, tau
