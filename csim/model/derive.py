"""Derivation of the equations of motion from energies and constraint functions.

Lagrange's equations of the first kind in redundant coordinates,

    M(q) qdd + Phi_q^T lambda = Q - C(q, qd) qd - h(q),

with every term derived here from T(q, qd), V(q), Phi(q) and the load coordinates s_k(q):

    M      = d^2 T / dqd dqd                       (Hessian of T in the velocities)
    C qd   = (d(M qd)/dq) qd - dT/dq              (from d/dt dT/dqd - dT/dq)
    h      = dV/dq
    Phi_q  = dPhi/dq
    gamma  = -(d(Phi_q qd)/dq) qd                 (Phi_q qdd = gamma on the manifold)
    S      = [ds_1/dq, ..., ds_k/dq]              (ds/dt = S^T qd, watched by the switching laws)
    B      = [b_1, ..., b_k],  b_k = ds_k/dq unless the load gives its direction
                                                  (Q = B u, virtual power of the loads)
    f      = [f_1(q, qd, t), ..., f_k]            (load laws; u_k = magnitude * active * f_k)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from csim.model.definition import MechanismDefinition
from csim.model.light import full_definition
from csim.model.recursive import sparse_jacobian


@dataclass
class DerivedModel:
    """Symbolic terms of the equations of motion (sympy matrices, column vectors).

    Shapes: ``mass`` (m, m), ``velocity_terms`` (m, 1), ``gravity`` (m, 1),
    ``phi`` (r, 1), ``phi_q`` (r, m), ``gamma`` (r, 1), ``load_matrix`` (m, k),
    ``load_coordinates`` (k, 1), ``load_jacobian`` (m, k) = ds/dq^T, ``load_law`` (k, 1)
    (of q, qd and the time t), ``observables`` (o, 1), ``observable_jacobian`` (o, m),
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
    load_jacobian: sp.Matrix
    load_law: sp.Matrix
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    observables: sp.Matrix
    observable_jacobian: sp.Matrix
    points: sp.Matrix
    point_dim: int = 2
    #: (symbol, expression) in order of definition: named intermediates that the terms
    #: above may use (a mechanism built link by link, :mod:`csim.model.recursive`); the code
    #: generators emit the ones a function needs before its body
    intermediates: list = field(default_factory=list)
    #: dPhi/dt (r, 1) of rows that depend on time explicitly (drives, :func:`with_drive_rows`); None: none do
    phi_t: sp.Matrix | None = None


#: expressions with more operations than this are left as they are: trigsimp's cost grows
#: steeply with size (a spatial loop's gamma took more than ten minutes), and the code
#: generator's common-subexpression elimination handles large expressions anyway
SIMPLIFY_MAX_OPS = 300


def _simplify(expr: sp.Expr) -> sp.Expr:
    """Cheap simplification that collapses sin^2 + cos^2 and products of angle sums."""
    if sp.count_ops(expr) > SIMPLIFY_MAX_OPS:
        return expr
    return sp.trigsimp(sp.expand(expr))


#: derivations made in this process, by definition key: the Python model source and the
#: compiled model functions are generated from one derivation, not two
_DERIVED: dict[str, DerivedModel] = {}


def derive(definition: MechanismDefinition) -> DerivedModel:
    """Derive all terms of the equations of motion of ``definition`` (once per process and definition).

    Raises
    ------
    ValueError
        If T is not a quadratic form in the velocities (the mass matrix depends on qd).
    """
    from csim.model.cache import definition_key

    key = definition_key(definition)
    if key not in _DERIVED:
        _DERIVED[key] = _derive(definition)
    return _DERIVED[key]


def _derive(definition: MechanismDefinition) -> DerivedModel:
    """:func:`derive`, every time."""
    definition = full_definition(definition)
    if getattr(definition, "recursive", None) is not None:
        return _derive_recursive(definition)
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
    Phi = sp.Matrix(definition.constraints) if definition.constraints else sp.zeros(0, 1)  # a tree: no constraints
    Phi_q = Phi.jacobian(q)
    gamma = (-(Phi_q * qd).jacobian(q) * qd).applyfunc(_simplify)
    return _model(definition, M, Cqd, h, Phi, Phi_q, gamma, T, V)


def _derive_recursive(definition: MechanismDefinition) -> DerivedModel:
    """:func:`derive` of a mechanism built link by link (:mod:`csim.model.recursive`): M, C qd
    and T from the bodies' Jacobians and bias accelerations, Phi, Phi_q and gamma by the chain
    rule over the named intermediates; h = dV/dq, the loads, observables and points from the
    definition's expressions as for any mechanism (no simplification: none pays at this size)."""
    from csim.model.recursive import assemble, gradient

    terms = definition.recursive()
    if len(terms.phi) != len(definition.constraints):  # the definition's constraints were changed since
        raise ValueError(f"{definition.name}: {len(terms.phi)} constraint equations link by link, "
                         f"{len(definition.constraints)} in the definition; expected the same equations")
    q = sp.Matrix(definition.coordinates)
    m = len(q)
    M, Cqd, T = assemble(terms, m)
    V = definition.potential_energy
    # h = dV/dq
    h = gradient(V, list(q))
    r = len(terms.phi)
    Phi = sp.Matrix(terms.phi) if r else sp.zeros(0, 1)
    Phi_q = sp.zeros(r, m)
    for i, row in enumerate(terms.phi_q):
        for j, value in row.items():
            Phi_q[i, j] = value
    gamma = sp.Matrix(terms.gamma) if r else sp.zeros(0, 1)
    model = _model(definition, M, Cqd, h, Phi, Phi_q, gamma, T, V)
    model.intermediates = terms.intermediates.items
    return model


def _model(definition, M, Cqd, h, Phi, Phi_q, gamma, T, V) -> DerivedModel:
    """The :class:`DerivedModel` with the loads, observables and drawing points of ``definition``."""
    q = sp.Matrix(definition.coordinates)
    s, S, B, f = _loads(definition, q)
    if definition.observables:
        obs = sp.Matrix([o.expression for o in definition.observables])
        obs_q = sparse_jacobian(list(obs), list(q))  # = obs.jacobian(q), without the zero derivatives
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
        load_jacobian=S,
        load_law=f,
        kinetic_energy=T,
        potential_energy=V,
        observables=obs,
        observable_jacobian=obs_q,
        points=sp.Matrix(pts) if pts else sp.zeros(0, 1),
        point_dim=dims.pop(),
    )


def _loads(definition: MechanismDefinition, q: sp.Matrix) -> tuple[sp.Matrix, sp.Matrix, sp.Matrix, sp.Matrix]:
    """Load coordinates s (k, 1), S = ds/dq^T (m, k), directions B (m, k), laws f (k, 1)."""
    loads = definition.loads
    if not loads:
        return sp.zeros(0, 1), sp.zeros(len(q), 0), sp.zeros(len(q), 0), sp.zeros(0, 1)
    s = sp.Matrix([load.coordinate for load in loads])
    # S = ds/dq^T: the rates the switching laws watch, ds/dt = S^T qd
    S = sparse_jacobian(list(s), list(q)).T
    # B: b_k = ds_k/dq, or the load's own direction (virtual power u_k b_k . qd)
    columns = [S[:, k] if load.direction is None else sp.Matrix(list(load.direction)) for k, load in enumerate(loads)]
    for load, column in zip(loads, columns):
        if column.shape != (len(q), 1):
            raise ValueError(f"{definition.name}: load {load.name!r} has a direction of {column.shape[0]} entries; "
                             f"expected one per coordinate ({len(q)})")
    B = sp.Matrix.hstack(*columns)
    # f: u_k = magnitude * active * f_k(q, qd, t)
    f = sp.Matrix([sp.Integer(1) if load.law is None else sp.sympify(load.law) for load in loads])
    return s, S, B, f


def drive_rates(exprs: list, t: sp.Symbol) -> tuple[list, list]:
    """The first and second time derivatives of drives f_j(t) (of t and the parameters), powers combined:
    the derivative of w t^n reads n w t^(n - 1), not sympy's n w t^n / t, which is 0/0 at t = 0 for n = 1
    (helper-28). The Python path's drives (:meth:`csim.linkage.model.Linkage.drive_rows`, lambdified by
    :func:`csim.linkage.plan.drive_function`) and the compiled drive rows (:func:`with_drive_rows`) both
    take them from here."""
    first = [sp.powsimp(sp.diff(e, t)) for e in exprs]
    return first, [sp.powsimp(sp.diff(e, t)) for e in first]


def with_drive_rows(derived: DerivedModel, driven: list[int], drives: list[sp.Expr]) -> DerivedModel:
    """``derived`` with each drive q_j = f_j(t) appended as a rheonomic constraint row.

    The row Phi_d = q_j - f_j(t) has Phi_d,q = e_j^T, Phi_d,t = -f_j'(t) and, from
    gamma = -(Phi_q qd)_q qd - 2 Phi_qt qd - Phi_tt, gamma_d = f_j''(t): the rows
    :class:`csim.solver.driven.DrivenSystem` stacks numerically on the Python path, here for the
    compiled kernels (whose model functions take t). The mechanism's own rows do not depend on t.

    Parameters
    ----------
    derived : DerivedModel
        The mechanism's derivation (r rows).
    driven : list of int
        The driven coordinates' indices (d,).
    drives : list of sympy expressions
        f_j of the time symbol ``t`` and the mechanism's parameters (d,).

    Returns
    -------
    DerivedModel
        With r + d rows in ``phi``, ``phi_q``, ``gamma`` and ``phi_t``.
    """
    import dataclasses

    t = sp.Symbol("t", real=True)
    q = list(derived.definition.coordinates)
    r, m = derived.phi.shape[0], len(q)
    rows = sp.zeros(len(driven), m)
    for i, j in enumerate(driven):
        rows[i, j] = 1
    f = [e.subs({s: t for s in e.free_symbols if s.name == "t"}) for e in map(sp.sympify, drives)]
    first, second = drive_rates(f, t)
    return dataclasses.replace(
        derived,
        phi=sp.Matrix(list(derived.phi) + [q[j] - fj for j, fj in zip(driven, f)]),
        phi_q=derived.phi_q.col_join(rows) if r else rows,
        gamma=sp.Matrix(list(derived.gamma) + second),
        phi_t=sp.Matrix([0] * r + [-fd for fd in first]),
    )
