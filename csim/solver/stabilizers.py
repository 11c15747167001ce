"""Constraint stabilizers: the right-hand side gamma* of the acceleration-level constraint.

Every formulation solves ``Phi_q qdd = gamma*``; a stabilizer is the single place where
gamma* is chosen (``stabilization.method`` in a case file):

``none``
    gamma* = gamma = -(Phi_q qd)_q qd: Phi and dPhi/dt are free to drift.
``baumgarte``
    Phi'' + 2 d w Phi' + w^2 Phi = 0, so gamma* = gamma - 2 d w Phi' - w^2 Phi.
``sliding_mode``
    s = Phi' + Lambda Phi with s' = -K s - k sw(s), so
    gamma* = gamma - Lambda Phi' - K s - k sw(s), where sw is sgn or a smooth replacement.
``projection``
    gamma* = gamma, and the state is projected onto Phi = 0, Phi_q qd = 0 after every step.

Two methods change what is integrated, not gamma*; their classes here hold the settings and
the system that does the work is named by ``system``:

``minimal``
    coordinate partitioning: only the independent coordinates are integrated, the
    dependent ones are solved from Phi = 0 at every evaluation
    (:class:`csim.solver.partitioned.PartitionedSystem`).
``ggl``
    the stabilized index-2 DAE of Gear, Gupta and Leimkuhler, solved by Radau IIA for DAEs
    (:class:`csim.solver.ggl.GGLSystem`).

Gains are scalars (the same for every constraint) or one value per constraint, in 1/s.
"""
from __future__ import annotations

import inspect

import numpy as np

from csim.errors import SimulationFailure
from csim.solver.newton import at_round_off


class Stabilizer:
    """Maps (gamma, Phi, dPhi/dt) to gamma*.

    Subclasses implement :meth:`gamma_star`; ``name`` is the registry key.
    """

    name = "abstract"
    #: which system integrates the method: "constrained", "partitioned" or "ggl"
    system = "constrained"
    #: the integrators that can run the method (None: every one)
    integrators: tuple[str, ...] | None = None

    def gamma_star(self, gamma: np.ndarray, phi: np.ndarray, phi_dot: np.ndarray) -> np.ndarray:
        """gamma* (r,) from gamma (r,), Phi (r,) and dPhi/dt = Phi_q qd (r,)."""
        raise NotImplementedError


class NoStabilization(Stabilizer):
    """gamma* = gamma: the acceleration-level constraint alone."""

    name = "none"

    def gamma_star(self, gamma, phi, phi_dot):
        return gamma


class Baumgarte(Stabilizer):
    """Baumgarte's damped oscillator on the constraints.

    Parameters
    ----------
    d : float or array (r,)
        Damping ratio, 0 < d (1 = critical damping, the fastest decay without overshoot).
    w : float or array (r,)
        Natural frequency [1/s]; Phi decays like exp(-d w t).
    """

    name = "baumgarte"

    def __init__(self, d=1.0, w=10.0):
        self.d = np.asarray(d, dtype=float)
        self.w = np.asarray(w, dtype=float)

    def gamma_star(self, gamma, phi, phi_dot):
        # Phi'' = gamma* - gamma + ... : Phi'' + 2 d w Phi' + w^2 Phi = 0
        return gamma - 2.0 * self.d * self.w * phi_dot - self.w**2 * phi


def _sat(s, eps):
    return np.clip(s / eps, -1.0, 1.0)


#: name -> (function sw(s, width), name of its width parameter); sw approximates sgn(s)
SWITCHING_FUNCTIONS = {
    "sgn": (lambda s, p: np.sign(s), None),
    "sat": (_sat, "eps"),  # sat(s / eps)
    "tanh": (lambda s, c: np.tanh(c * s), "c"),  # tanh(c s)
    "atan": (lambda s, c: 2.0 / np.pi * np.arctan(c * s), "c"),  # (2/pi) arctan(c s)
    "sqrt": (lambda s, eps: s / np.sqrt(s * s + eps * eps), "eps"),  # s / sqrt(s^2 + eps^2)
}


class SlidingMode(Stabilizer):
    """The paper's sliding-mode stabilization.

    Parameters
    ----------
    Lambda : float or array (r,)
        Slope of the sliding surface s = Phi' + Lambda Phi [1/s]; on s = 0, Phi decays like
        exp(-Lambda t).
    K : float or array (r,)
        Linear reaching gain [1/s]: s decays like exp(-K t) away from s = 0.
    k : float or array (r,)
        Switching gain [unit of Phi / s^2]: drives s to zero in finite time.
    switching : {"sgn", "sat", "tanh", "atan", "sqrt"}
        The switching function: sgn itself or one of its smooth replacements.
    eps : float
        Boundary-layer width of ``sat`` and ``sqrt`` [unit of Phi / s].
    c : float
        Steepness of ``tanh`` and ``atan`` [s / unit of Phi].
    """

    name = "sliding_mode"

    def __init__(self, Lambda=10.0, K=10.0, k=1e-3, switching="tanh", eps=1e-6, c=1e6):
        self.Lambda = np.asarray(Lambda, dtype=float)
        self.K = np.asarray(K, dtype=float)
        self.k = np.asarray(k, dtype=float)
        fn, width = SWITCHING_FUNCTIONS[switching]
        self.switching = switching
        self.width = {"eps": eps, "c": c, None: None}[width]
        self._sw = fn

    def sliding_variable(self, phi, phi_dot):
        """s = Phi' + Lambda Phi."""
        return phi_dot + self.Lambda * phi

    def gamma_star(self, gamma, phi, phi_dot):
        s = self.sliding_variable(phi, phi_dot)
        # s' = Phi'' + Lambda Phi' = -K s - k sw(s)
        return gamma - self.Lambda * phi_dot - self.K * s - self.k * self._sw(s, self.width)


class Projection(Stabilizer):
    """Coordinate projection after every accepted step (gamma* = gamma during the step).

    Positions by Gauss-Newton on Phi(q) = 0 with the metric W (identity or M),

        q <- q - W^-1 Phi_q^T (Phi_q W^-1 Phi_q^T)^-1 Phi(q),

    until max |Phi| <= ``projection_tol``; then velocities onto Phi_q qd = 0,

        qd <- qd - W^-1 Phi_q^T (Phi_q W^-1 Phi_q^T)^-1 Phi_q qd.

    The mass-weighted metric changes the state least in kinetic-energy norm.

    Parameters
    ----------
    projection_metric : {"minimum_norm", "mass"}
    projection_tol : float
        Convergence of the position iteration on max |Phi| [unit of Phi].
    projection_max_iter : int
    """

    name = "projection"
    METRICS = ("minimum_norm", "mass")

    def __init__(self, projection_metric="mass", projection_tol=1e-13, projection_max_iter=10):
        if projection_metric not in self.METRICS:
            raise ValueError(f"projection_metric must be one of {', '.join(self.METRICS)}")
        self.metric = projection_metric
        self.tol = float(projection_tol)
        self.max_iter = int(projection_max_iter)

    def gamma_star(self, gamma, phi, phi_dot):
        return gamma

    def _correction(self, phi_q, W_inv, residual):
        # W^-1 Phi_q^T (Phi_q W^-1 Phi_q^T)^-1 residual
        WJt = phi_q.T if W_inv is None else W_inv @ phi_q.T
        return WJt @ np.linalg.solve(phi_q @ WJt, residual)

    def project(self, model, par, q, qd):
        """Projected (q, qd); raises SimulationFailure when Gauss-Newton does not converge."""
        W_inv = np.linalg.inv(model.mass(q, par)) if self.metric == "mass" else None
        q = q.copy()
        for _ in range(self.max_iter + 1):
            phi = model.phi(q, par)
            if np.max(np.abs(phi)) <= self.tol:
                break
            try:
                dq = self._correction(model.phi_q(q, par), W_inv, phi)
            except np.linalg.LinAlgError:
                raise SimulationFailure("projection: singular constraint Jacobian") from None
            q -= dq
            if at_round_off(dq, q):  # |Phi| cannot go lower: its round-off grows with |q|
                break
        else:
            raise SimulationFailure(f"projection: Gauss-Newton did not reach max |Phi| <= {self.tol:g} in "
                                    f"{self.max_iter} iterations (max |Phi| = {np.max(np.abs(phi)):.3e})")
        phi_q = model.phi_q(q, par)
        qd = qd - self._correction(phi_q, W_inv, phi_q @ qd)
        return q, qd


class Minimal(Stabilizer):
    """Minimal coordinates by coordinate partitioning (Wehage and Haug).

    The independent coordinates u and their rates are integrated; at every evaluation the
    dependent coordinates v are solved from Phi(u, v) = 0 by Newton-Raphson and their rates
    from Phi_v vd = -Phi_u ud, so the constraints hold to the Newton tolerance by
    construction. The partition is chosen by pivoted QR and chosen again (the integration
    restarts) when cond(Phi_v) exceeds ``minimal_max_condition``.

    Parameters
    ----------
    minimal_tol : float
        Newton tolerance on max |Phi| [unit of Phi].
    minimal_max_iter : int
        Newton iteration limit per evaluation.
    minimal_max_condition : float
        Look for a better partition when ||Phi_q||_1 ||Phi_v^-1||_1 exceeds this (the
        factor by which errors in u are amplified in v, about). The default 20 is above
        the quick-return mechanism's worst value with the crank independent (11.9), so the
        crank stays independent there, and switches a Cartesian pendulum's independent
        coordinate when |y| falls below about L / 20.
    """

    name = "minimal"
    system = "partitioned"

    def __init__(self, minimal_tol=1e-13, minimal_max_iter=20, minimal_max_condition=20.0):
        self.tol = float(minimal_tol)
        self.max_iter = int(minimal_max_iter)
        self.max_condition = float(minimal_max_condition)

    def gamma_star(self, gamma, phi, phi_dot):
        return gamma


class GGL(Stabilizer):
    """The stabilized index-2 formulation of Gear, Gupta and Leimkuhler.

        q' = v - Phi_q^T mu,   M v' = p - Phi_q^T lambda,   0 = Phi(q),   0 = Phi_q v

    Both the position and the velocity constraints are equations of the DAE, solved at
    every stage of the implicit Radau IIA integrator: no drift and no post-step
    correction. mu vanishes on the exact solution.

    Parameters
    ----------
    ggl_tol : float
        Largest residual of Phi and Phi_q v accepted at the end of a step [unit of Phi,
        and per second].
    """

    name = "ggl"
    system = "ggl"
    integrators = ("Radau",)  # the DAE integrators of csim.solver.integrators

    def __init__(self, ggl_tol=1e-12):
        self.tol = float(ggl_tol)

    def gamma_star(self, gamma, phi, phi_dot):
        return gamma


#: name -> class; each class is built from the validated ``stabilization`` section
STABILIZERS: dict[str, type[Stabilizer]] = {
    cls.name: cls for cls in (NoStabilization, Baumgarte, SlidingMode, Projection, GGL, Minimal)
}


def make_stabilizer(name: str, settings: dict | None = None) -> Stabilizer:
    """Build the stabilizer registered as ``name`` from its case-file ``settings``.

    ``settings`` may hold the gains of every method; each method takes only its own.
    """
    try:
        cls = STABILIZERS[name]
    except KeyError:
        raise KeyError(f"unknown stabilization method {name!r}; valid names: {', '.join(STABILIZERS)}") from None
    accepted = inspect.signature(cls.__init__).parameters
    return cls(**{k: v for k, v in (settings or {}).items() if k in accepted})
