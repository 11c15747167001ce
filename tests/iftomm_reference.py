"""Exact motions of IFToMM benchmark problems A01 and A02, independent of csim.

Both reduce to one degree of freedom with a closed-form or scalar-ODE solution:

- A01, a point mass m on a massless link L released at rest from the horizontal:
  theta (from the downward vertical) obeys theta'' = -(g / L) sin theta; with k = sin(theta0 / 2),
  sin(theta / 2) = k sn(K(k) - sqrt(g / L) t, k) (Jacobi's elliptic sn, modulus k).
- A02, N four-bars kept in the parallelogram: every crank turns by the same angle theta, the
  couplers translate. T = 1/2 ((N + 1) / 3 + N) theta'^2 and V = g ((N + 1) / 2 + N) sin theta
  (1 m, 1 kg uniform rods), so theta'' = -g c / I cos theta with I = (N + 1) / 3 + N,
  c = (N + 1) / 2 + N; from theta = pi / 2, theta' = -1 rad/s (B0 at +1 m/s along x).
"""
from __future__ import annotations

import numpy as np
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
