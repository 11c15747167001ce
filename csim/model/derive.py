"""Derivation of the equations of motion from energies and constraint functions.

Lagrange's equations of the first kind in redundant coordinates,

    M(q) qdd + Phi_q^T lambda = Q - C(q, qd) qd - h(q),

with every term derived here from T(q, qd), V(q), Phi(q) and the load coordinates s_k(q):

    M      = d^2 T / dqd dqd                       (Hessian of T in the velocities)
    C qd   = (d(M qd)/dq) qd - dT/dq              (from d/dt dT/dqd - dT/dq)
    h      = dV/dq
    Phi_q  = dPhi/dq
    gamma  = -(d(Phi_q qd)/dq) qd                 (Phi_q qdd = gamma on the manifold)
    B      = [ds_1/dq, ..., ds_k/dq]              (Q = B u, virtual work of the loads)
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from csim.model.definition import MechanismDefinition
from csim.model.light import full_definition


@dataclass
class DerivedModel:
    """Symbolic terms of the equations of motion (sympy matrices, column vectors).

    Shapes: ``mass`` (m, m), ``velocity_terms`` (m, 1), ``gravity`` (m, 1),
    ``phi`` (r, 1), ``phi_q`` (r, m), ``gamma`` (r, 1), ``load_matrix`` (m, k),
    ``load_coordinates`` (k, 1), ``observables`` (o, 1), ``observable_jacobian`` (o, m),
    ``points`` (d P, 1) as x0, y0, x1, y1, ... (d = ``point_dim``: 2, or 3 for a spatial
    drawing, with z0, z1, ... between)
    """

    definition: MechanismDefinition
    mass: sp.Matrix
    velocity_terms: sp.Matrix
    gravity: sp.Matrix
    phi: sp.Matrix
    phi_q: sp.Matrix
    gamma: sp.Matrix
    load_coordinates: sp.Matrix
    load_matrix: sp.Matrix
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    observables: sp.Matrix
    observable_jacobian: sp.Matrix
    points: sp.Matrix
    point_dim: int = 2


#: expressions with more operations than this are left as they are: trigsimp's cost grows
#: steeply with size (a spatial loop's gamma took more than ten minutes), and the code
#: generator's common-subexpression elimination handles large expressions anyway
SIMPLIFY_MAX_OPS = 300


def _simplify(expr: sp.Expr) -> sp.Expr:
    """Cheap simplification that collapses sin^2 + cos^2 and products of angle sums."""
    if sp.count_ops(expr) > SIMPLIFY_MAX_OPS:
        return expr
    return sp.trigsimp(sp.expand(expr))


def derive(definition: MechanismDefinition) -> DerivedModel:
    """Derive all terms of the equations of motion of ``definition``.

    Raises
    ------
    ValueError
        If T is not a quadratic form in the velocities (the mass matrix depends on qd).
    """
    definition = full_definition(definition)
    q = sp.Matrix(definition.coordinates)
    qd = sp.Matrix(definition.velocities)
    T = sp.expand(definition.kinetic_energy)
    V = sp.expand(definition.potential_energy)

    # M = d^2 T / dqd^2
    M = sp.hessian(T, list(qd)).applyfunc(_simplify)
    if any(M_ij.has(*qd) for M_ij in M):
        raise ValueError(f"{definition.name}: kinetic energy is not quadratic in the velocities")
    # C qd = (d(M qd)/dq) qd - dT/dq
    Mqd = M * qd
    Cqd = (Mqd.jacobian(q) * qd - sp.Matrix([T]).jacobian(q).T).applyfunc(_simplify)
    # h = dV/dq
    h = sp.Matrix([V]).jacobian(q).T.applyfunc(_simplify)
    # Phi_q = dPhi/dq;  gamma = -(d(Phi_q qd)/dq) qd
    Phi = sp.Matrix(definition.constraints)
    Phi_q = Phi.jacobian(q)
    gamma = (-(Phi_q * qd).jacobian(q) * qd).applyfunc(_simplify)
    # B = ds/dq^T
    if definition.loads:
        s = sp.Matrix([load.coordinate for load in definition.loads])
        B = s.jacobian(q).T
    else:
        s = sp.zeros(0, 1)
        B = sp.zeros(len(q), 0)
    if definition.observables:
        obs = sp.Matrix([o.expression for o in definition.observables])
        obs_q = obs.jacobian(q)
    else:
        obs = sp.zeros(0, 1)
        obs_q = sp.zeros(0, len(q))
    pts, dims = [], {2}
    if definition.drawing is not None and definition.drawing.points:
        dims = {len(p) for p in definition.drawing.points.values()}
        if dims not in ({2}, {3}):
            raise ValueError(f"{definition.name}: drawing points must all be (x, y) or all (x, y, z)")
        for point in definition.drawing.points.values():
            pts += list(point)
    return DerivedModel(
        definition=definition,
        mass=M,
        velocity_terms=Cqd,
        gravity=h,
        phi=Phi,
        phi_q=Phi_q,
        gamma=gamma,
        load_coordinates=s,
        load_matrix=B,
        kinetic_energy=T,
        potential_energy=V,
        observables=obs,
        observable_jacobian=obs_q,
        points=sp.Matrix(pts) if pts else sp.zeros(0, 1),
        point_dim=dims.pop(),
    )
