"""The ODE integrated by csim: a mechanism with its loads, formulation and stabilizer.

State vector y (2 m + k,) = [q (m), qd (m), W (k)], where W_k is the work done so far by
load k (a quadrature state, integrated with the motion so that the energy balance
T + V - (T0 + V0) = sum W_k can be checked to the integrator's accuracy).

    dq/dt = qd
    dqd/dt = qdd  from  M qdd + Phi_q^T lambda = B u - C qd - h,  Phi_q qdd = gamma*
    dW_k/dt = u_k (B^T qd)_k       (the power of load k; B^T qd = ds/dt unless it has a direction)

with u = magnitude * active * f(q, qd, t) (:meth:`csim.load_laws.LoadSet.values`).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from csim.load_laws import LoadSet
from csim.model.numeric import NumericModel
from csim.physics.kkt import constraint_rates, generalized_forces
from csim.physics.linalg import as_core
from csim.physics.loads import load_rates
from csim.solver.formulations import Formulation

if TYPE_CHECKING:
    from csim.solver.methods.base import Method


@dataclass
class Evaluation:
    """Everything csim records at one instant (shapes for m coordinates, r constraints, k loads)."""

    qdd: np.ndarray  # (m,)
    lam: np.ndarray  # (r,)
    phi: np.ndarray  # (r,)
    phi_dot: np.ndarray  # (r,) = Phi_q qd
    u: np.ndarray  # (k,) load values
    Q: np.ndarray  # (m,) generalized applied forces B u
    kinetic: float
    potential: float


class ConstrainedSystem:
    """Right-hand side of the constrained equations of motion.

    The driver (:mod:`csim.solver.simulate`) integrates the system's own state y and
    records the full state [q, qd, W] from :meth:`output_state`. Here the two are the
    same; :class:`csim.solver.partitioned.PartitionedSystem` integrates fewer states and
    :class:`csim.solver.ggl_system.GGLSystem` more (a DAE, with ``differential`` set).

    Parameters
    ----------
    model : NumericModel
    par : ndarray (n_par,)
        Parameter values.
    loads : LoadSet
    formulation : Formulation
    stabilizer : csim.solver.methods.base.Method
        The stabilization method.
    """

    def __init__(self, model: NumericModel, par: np.ndarray, loads: LoadSet,
                 formulation: Formulation, stabilizer: Method):
        self.model = model
        self.par = np.asarray(par, dtype=float)
        self.loads = loads
        self.formulation = formulation
        self.stabilizer = stabilizer
        self.m = model.n_coordinates
        self.r = model.n_constraints
        #: constraints recorded at the samples: every equation of an overconstrained linkage
        #: (csim.solver.redundant.RedundantModel chooses r of them as it moves)
        self.r_recorded = getattr(model, "n_recorded", self.r)
        self.k = model.n_loads

    #: None for an ODE; for a DAE, a bool array (n_state,), True on differential rows
    differential = None

    @property
    def n_state(self) -> int:
        return 2 * self.m + self.k

    @property
    def work_slice(self) -> slice:
        """Where the work states W sit in the integrated state."""
        return slice(2 * self.m, 2 * self.m + self.k)

    def split(self, y):
        """(q, qd, W) views of a full state vector [q, qd, W]."""
        m = self.m
        return y[:m], y[m:2 * m], y[2 * m:2 * m + self.k]

    def to_full(self, y: np.ndarray) -> np.ndarray:
        """The full state [q, qd, W] (2 m + k,) of an integrated state y."""
        return y

    def start(self, y_full: np.ndarray) -> np.ndarray:
        """The integrated state to start from (at t = 0), given a full initial state [q0, qd0, W0]."""
        return self.project(0.0, y_full) if self.projects else np.array(y_full, dtype=float)

    def output_state(self, t: float, y: np.ndarray) -> np.ndarray:
        """The full state recorded for an integrated state y at time t (projected, for projection)."""
        return self.project(t, y) if self.projects else np.array(self.to_full(y))

    def failure_method(self, code: int) -> Method:
        """The method whose settings the message of a failure with status ``code`` quotes
        (:func:`csim.solver.failures.failure_message`): the stabilizer."""
        return self.stabilizer

    def dae_options(self) -> dict | None:
        """Options of a DAE integrator for this system (None: it is an ODE)."""
        return None

    def after_step(self, t: float, y: np.ndarray) -> tuple[np.ndarray, str]:
        """What the driver does after an accepted step ending in state y.

        Returns the state to go on from and how: ``"keep"`` (y unchanged), ``"swap"``
        (hand the new state to the running integrator) or ``"restart"`` (start the
        integrator afresh from it).
        """
        if self.projects:
            return self.project(t, y), "swap"
        return y, "keep"

    def restart(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """The state to restart from at a switching event: y at the event, ``mode`` the new conditions.

        By default the state after a step (projected, for projection); a system whose
        state holds quantities that depend on the loads (GGL's multipliers) makes them
        consistent with the new mode here.
        """
        return self.after_step(t, y)[0]

    def max_phi(self, y: np.ndarray) -> float:
        """max |Phi(q)| at an integrated state y [unit of Phi]."""
        q, _, _ = self.split(self.to_full(y))
        return float(np.max(np.abs(self.model.phi(q, self.par)), initial=0.0))

    def mode_at(self, y: np.ndarray) -> np.ndarray:
        """The load-law conditions (n_switches,) bool that hold at state y."""
        if self.loads.n_switches == 0:  # no law switches: nothing to evaluate (once per right-hand side)
            return np.zeros(0, dtype=bool)
        return self.loads.mode(self.switching(y))

    def switching(self, y: np.ndarray) -> np.ndarray:
        """Switching functions of the load laws at state y (n_switches,)."""
        q, qd, _ = self.split(self.to_full(y))
        s = self.model.load_coordinates(q, self.par)
        return self.loads.switching(s, self._load_rates(self.model.load_jacobian(q, self.par), qd))

    def load_values(self, t: float, q: np.ndarray, qd: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """u (k,) = magnitude * active * f(q, qd, t): the loads at time t [s] in ``mode``."""
        return self.loads.values(mode, self.model.load_law(q, qd, t, self.par))

    def _load_rates(self, B, qd):
        """B^T qd (k,): ds/dt for B = S, the loads' power per unit value for B their directions."""
        sdot = np.empty(self.k)
        load_rates(as_core(B), as_core(qd), sdot, self.m, self.k)
        return sdot

    def _solve(self, q, qd, u):
        """qdd, lambda and the pieces of the balance at (q, qd) with loads u."""
        M, phi_q, p, phi, phi_dot, gamma_star, Q, B = self._terms(q, qd, u)
        qdd, lam = self.formulation.solve(M, phi_q, p, gamma_star)
        return qdd, lam, phi, phi_dot, Q, B

    def _terms(self, q, qd, u):
        """What the formulation solves at (q, qd) with loads u: M (m, m), Phi_q (r, m), p = B u - C qd - h
        (m,), and Phi, Phi_q qd, gamma* (r,) each, Q = B u (m,), B (m, k)."""
        model, par = self.model, self.par
        M = model.mass(q, par)
        phi_q = model.phi_q(q, par)
        B = model.load_matrix(q, par)
        Q = B @ u
        p = np.empty(self.m)  # p = B u - C qd - h
        generalized_forces(as_core(B), u, as_core(model.velocity_terms(q, qd, par)), as_core(model.gravity(q, par)), p,
                           self.m, self.k)
        phi = model.phi(q, par)
        phi_dot = np.empty(self.r)  # dPhi/dt = Phi_q qd
        constraint_rates(as_core(phi_q), as_core(qd), phi_dot, self.r, self.m)
        gamma_star = self.stabilizer.gamma_star(model.gamma(q, qd, par), phi, phi_dot)
        return M, phi_q, p, phi, phi_dot, gamma_star, Q, B

    def rhs(self, t: float, y: np.ndarray, mode: np.ndarray) -> np.ndarray:
        """dy/dt (n_state,) with the load laws held in ``mode`` (n_switches,) bool."""
        q, qd, _ = self.split(y)
        u = self.load_values(t, q, qd, mode)
        qdd, _, _, _, _, B = self._solve(q, qd, u)
        # dW/dt = u * (B^T qd)
        return np.concatenate((qd, qdd, u * self._load_rates(B, qd)))

    def rhs_unlocated(self, t: float, y: np.ndarray) -> np.ndarray:
        """dy/dt with the load laws evaluated at the state itself (discontinuous in y)."""
        return self.rhs(t, y, self.mode_at(y))

    @property
    def projects(self) -> bool:
        """Whether the method projects the state after every step."""
        return self.stabilizer.projects

    def project(self, t: float, y: np.ndarray) -> np.ndarray:
        """The state with (q, qd) projected onto the constraint manifold at time t (a new array)."""
        q, qd, _ = self.split(y)
        q, qd = self.stabilizer.project(self.model, self.par, q, qd, t=t)
        return np.concatenate((q, qd, y[2 * self.m:]))

    def recorded(self, q: np.ndarray, qd: np.ndarray, lam: np.ndarray, phi: np.ndarray,
                 phi_dot: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, Phi_q qd, multipliers) as a result records them (``r_recorded`` each) from the integrated
        equations' (``r`` each): for a :class:`csim.solver.redundant.RedundantModel`, the full set's
        residuals and its minimum-norm multipliers; else as they are."""
        if hasattr(self.model, "recorded"):
            return self.model.recorded(q, qd, lam)
        return phi, phi_dot, lam

    def evaluate(self, t: float, y: np.ndarray, mode: np.ndarray) -> Evaluation:
        """All recorded quantities at one instant, from a full state y = [q, qd, W]."""
        q, qd, _ = self.split(y)
        u = self.load_values(t, q, qd, mode)
        qdd, lam, phi, phi_dot, Q, _ = self._solve(q, qd, u)
        phi, phi_dot, lam = self.recorded(q, qd, lam, phi, phi_dot)
        return Evaluation(
            qdd=qdd, lam=lam, phi=phi, phi_dot=phi_dot, u=u, Q=Q,
            kinetic=self.model.kinetic_energy(q, qd, self.par),
            potential=self.model.potential_energy(q, self.par),
        )
