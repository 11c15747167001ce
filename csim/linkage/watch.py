"""The numeric functions of a linkage's cut-joint equations: Phi, its sparse Jacobian and
gamma, and the constraint watch built of them (:class:`csim.solver.integrity.ConstraintWatch`).

Their source is filed in the cache (:func:`csim.linkage.lambdacache.cached_lambdify`), and
read back with names and numbers only: sympy is imported, and the expressions asked for,
only where a function is derived (a cold cache, or none). The expressions come from
:mod:`csim.linkage.constraints`; a warm run gets the rest from the linkage's plan
(:class:`csim.linkage.plan.LinkagePlan`).
"""
from __future__ import annotations

import functools
from collections.abc import Callable, Sequence

import numpy as np

from csim.linkage.lambdacache import cached_lambdify
from csim.linkage.plan import DEPENDENT, KEPT, ZERO, EquationRecord


def numeric_constraints(r: int, n: int, values: list, key: str, symbolic: Callable[[], tuple]):
    """phi(q) (r,) and phi_q(q) (r, n) as numpy functions at the parameter ``values`` (their
    source filed in the cache under ``key``, :func:`csim.linkage.lambdacache.cached_lambdify`;
    "": derived here).

    Parameters
    ----------
    r, n : int
        The number of equations and of joint variables.
    values : list of float
        The parameter values, in the order of the symbols ``symbolic`` gives.
    key : str
        The cache key ("": not cached).
    symbolic : callable () -> (exprs, q_syms, p_syms)
        The r expressions, the n joint variables' symbols and the parameters' symbols, asked
        for only where a function is derived.
    """
    symbolic = functools.cache(symbolic)
    derived: dict = {}

    def nonzero():
        # only the nonzero entries of Phi_q are generated (a long chain's is mostly zeros); their
        # rows and columns are a function of their own (no arguments), cached as the entries are
        if not derived:
            from csim.model.recursive import sparse_jacobian

            exprs, q_syms, _ = symbolic()
            jac = sparse_jacobian(exprs, q_syms)
            derived["jac"], derived["at"] = jac, [(i, j) for i in range(r) for j in range(n) if jac[i, j] != 0]
        return derived["jac"], derived["at"]

    def make_phi():
        import sympy as sp

        exprs, q_syms, p_syms = symbolic()
        return [q_syms, p_syms], sp.Matrix(list(exprs)) if r else sp.zeros(0, 1)

    def make_jac():
        _, q_syms, p_syms = symbolic()
        return [q_syms, p_syms], [nonzero()[0][i, j] for i, j in nonzero()[1]]

    f = cached_lambdify(key, "watch_phi", make_phi)
    pattern = cached_lambdify(key, "watch_pattern", lambda: ([], [[i for i, _ in nonzero()[1]],
                                                                  [j for _, j in nonzero()[1]]]))
    g = cached_lambdify(key, "watch_jac", make_jac)
    rows, cols = (np.asarray(ix, dtype=int) for ix in pattern())

    def phi(q):
        return np.asarray(f(list(q), values), dtype=float).reshape(r)

    def phi_q(q):
        out = np.zeros((r, n))
        out[rows, cols] = np.asarray(g(list(q), values), dtype=float)
        return out

    return phi, phi_q


def numeric_gamma(r: int, values: list, key: str, symbolic: Callable[[], tuple]):
    """gamma(q, qd) (r,) = -(d(Phi_q qd)/dq) qd of r expressions, as a numpy function at the
    parameter ``values`` (filed under ``key`` as :func:`numeric_constraints`'s; ``symbolic``
    () -> (exprs, q_syms, qd_syms, p_syms), asked for only where it is derived)."""
    if not r:
        return lambda q, qd: np.zeros(0)

    def make():
        import sympy as sp

        from csim.model.recursive import sparse_jacobian

        exprs, q_syms, qd_syms, p_syms = symbolic()
        qd_vec = sp.Matrix(qd_syms)
        rate = sparse_jacobian(exprs, q_syms) * qd_vec  # Phi_q qd
        return [q_syms, qd_syms, p_syms], -(sparse_jacobian(list(rate), q_syms) * qd_vec)

    f = cached_lambdify(key, "watch_gamma", make)

    def gamma_removed(q, qd):
        return np.asarray(f(list(q), list(qd), values), dtype=float).reshape(r)

    return gamma_removed


class _Expressions(Sequence):
    """The expressions of equations, read only where indexed (a function read back from the
    cache needs their count alone, and an unread expression stays pickled:
    :class:`csim.model.deferred.DeferredFields`)."""

    def __init__(self, equations: list):
        self._equations = equations

    def __len__(self) -> int:
        return len(self._equations)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [e.expression for e in self._equations[index]]
        return self._equations[index].expression


def constraint_watch(equations: list[EquationRecord], n: int, rank: int, values: list, key: str,
                     symbolic: Callable[[], tuple]):
    """Every non-trivial cut-joint equation as a :class:`csim.solver.integrity.ConstraintWatch`:
    the kept ones (the model's Phi, in its order) and the ones removed as dependent, with
    gamma of the removed ones (derived here: the model derives the kept ones').

    Parameters
    ----------
    equations : list of EquationRecord
        Every generated equation with its status (:attr:`csim.linkage.plan.LinkagePlan.equations`).
    n : int
        The number of joint variables.
    rank : int
        The generic rank of the non-trivial equations' Jacobian.
    values : list of float
        The parameter values, in the order of the symbols ``symbolic`` gives.
    key : str
        The linkage's :attr:`~csim.linkage.model.Linkage.build_key`, which the equations'
        status depends on: the numeric functions are filed under it ("": derived here).
    symbolic : callable () -> (equations, variables, p_syms)
        The symbolic :class:`~csim.linkage.constraints.Equation` of each record (in the same
        order), the :class:`~csim.linkage.topology.JointVariable` list and the parameters'
        symbols, asked for only where a function is derived.
    """
    from csim.solver.integrity import ConstraintWatch

    symbolic = functools.cache(symbolic)
    live = [i for i, e in enumerate(equations) if e.status != ZERO]
    removed = [i for i in live if equations[i].status == DEPENDENT]

    def pick(rows):
        full, variables, p_syms = symbolic()
        return _Expressions([full[i] for i in rows]), [v.symbol for v in variables], \
            [v.velocity for v in variables], p_syms

    def phi_terms():
        exprs, q_syms, _, p_syms = pick(live)
        return exprs, q_syms, p_syms

    phi, phi_q = numeric_constraints(len(live), n, values, key, phi_terms)
    gamma_removed = numeric_gamma(len(removed), values, key, lambda: pick(removed))
    return ConstraintWatch(phi=phi, phi_q=phi_q, labels=[equations[i].label for i in live],
                           kept=np.array([k for k, i in enumerate(live) if equations[i].status == KEPT], dtype=int),
                           removed=np.array([k for k, i in enumerate(live) if equations[i].status == DEPENDENT],
                                            dtype=int),
                           rank=rank, gamma_removed=gamma_removed, units=[equations[i].unit for i in live])
