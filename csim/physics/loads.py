"""Switched load laws (:mod:`csim.load_laws`) as arrays: switching functions, mode, load values.

A load set with n_sw switching functions is packed (by :class:`csim.load_laws.LoadSet`) into

``sw_load`` (n_sw,) int
    the load each function belongs to;
``sw_kind`` (n_sw,) int
    :data:`LOWER` s - lo, :data:`UPPER` hi - s, :data:`RISING` ds/dt, :data:`FALLING` -ds/dt;
``sw_value`` (n_sw,) float
    lo or hi (0 for the velocity conditions).

Each function is positive where its condition holds; load k takes its magnitude times its
law f_k(q, qd, t) while every condition of load k holds (the *mode*), and 0 otherwise.
"""
from __future__ import annotations

from csim.physics.jit import inline_kernel, kernel

LOWER, UPPER, RISING, FALLING = range(4)


@inline_kernel
def load_rates(B, qd, sdot, m, k):
    """ds/dt = B^T qd into sdot (k,), from the load matrix B = ds/dq^T (m * k, row-major) and qd (m,)."""
    for kk in range(k):
        v = 0.0
        for i in range(m):
            v += B[i * k + kk] * qd[i]
        sdot[kk] = v


@kernel
def switching_functions(s, sdot, sw_load, sw_kind, sw_value, g):
    """The switching functions g (n_sw,) at load coordinates s (k,) and rates sdot (k,)."""
    for j in range(g.size):
        kk = sw_load[j]
        kind = sw_kind[j]
        if kind == LOWER:
            g[j] = s[kk] - sw_value[j]
        elif kind == UPPER:
            g[j] = sw_value[j] - s[kk]
        elif kind == RISING:
            g[j] = sdot[kk]
        else:
            g[j] = -sdot[kk]


@kernel
def mode_of(g, mode):
    """The conditions that hold where the switching functions are g: mode[j] = g[j] > 0."""
    for j in range(g.size):
        mode[j] = g[j] > 0.0


@inline_kernel
def load_values(magnitudes, mode, sw_load, law, u):
    """u (k,): magnitude * law while all the load's conditions hold in ``mode`` (n_sw,) bool, else 0.

    ``law`` (k,) is the value of each load's law f_k(q, qd, t) (1 for a switched constant).
    """
    for kk in range(u.size):
        u[kk] = magnitudes[kk] * law[kk]
    for j in range(mode.size):
        if not mode[j]:
            u[sw_load[j]] = 0.0
