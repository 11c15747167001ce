"""Equations of motion assembled from per-body kinematics held in named intermediates.

A mechanism built link by link (:mod:`csim.linkage.recursive`) hands :func:`csim.model.derive.derive`
a :class:`RecursiveTerms` instead of having its whole-mechanism energies differentiated: every
link's rotation, position, velocity, bias acceleration and Jacobian columns are named
intermediate symbols, each defined from its parent's (``intermediates``, in order of
definition), and the terms of the equations of motion are short sums over the bodies in
these symbols. For a body b with mass m_b, inertia I_b about its centre of mass (body
axes), centre-of-mass Jacobian J_b (global, d r_c / dq), angular Jacobian G_b (body axes,
d omega / dqd), angular velocity w_b, and the parts of the accelerations free of qdd,
a_b = Jdot_b qd and wd_b = Gdot_b qd:

    M    = sum_b  m_b J_b^T J_b + G_b^T I_b G_b                 (T = 1/2 qd^T M qd)
    C qd = sum_b  m_b J_b^T a_b + G_b^T (I_b wd_b + w_b x I_b w_b)
    T    = sum_b  1/2 m_b |J_b qd|^2 + 1/2 w_b . I_b w_b

(Lagrange's d/dt dT/dqd - dT/dq = M qdd + C qd written with the body Jacobians, i.e.
Newton-Euler projected on the coordinates.) The constraint terms Phi, Phi_q and
gamma = -(d(Phi_q qd)/dq) qd come by the chain rule over the same intermediates. The code
generators (:mod:`csim.model.codegen`, :mod:`csim.fast.codegen`) emit the intermediates a
function needs as assignments before its common-subexpression elimination, so that
nothing is expanded into whole-mechanism expressions.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp


class Intermediates:
    """Named intermediate symbols and their defining expressions, in order of definition.

    Parameters
    ----------
    prefix : str
        Symbol names are ``prefix`` + a counter; the prefix starts with ``_`` so that it
        cannot clash with a parameter or coordinate name (those start with a letter).
    """

    def __init__(self, prefix: str = "_v"):
        self.prefix = prefix
        self.items: list[tuple[sp.Symbol, sp.Expr]] = []
        self._known: dict[sp.Expr, sp.Symbol] = {}

    def name(self, expr) -> sp.Expr:
        """A symbol for ``expr``, or ``expr`` itself when it is a number or a symbol (+-).

        An expression named before (or its negative) gets the same symbol (or its negative).
        """
        expr = sp.sympify(expr)
        if expr.is_Number or expr.is_Symbol or (expr.is_Mul and len(expr.args) == 2 and expr.args[0] == -1
                                                  and expr.args[1].is_Symbol):
            return expr
        if expr in self._known:
            return self._known[expr]
        negative = -expr
        if negative in self._known:
            return -self._known[negative]
        sym = sp.Symbol(f"{self.prefix}{len(self.items)}", real=True)
        self.items.append((sym, expr))
        self._known[expr] = sym
        return sym

    def matrix(self, matrix: sp.Matrix) -> sp.Matrix:
        """:meth:`name` on every entry."""
        return matrix.applyfunc(self.name)


@dataclass
class BodyTerms:
    """The kinematics of one body with mass, in intermediate symbols.

    Attributes
    ----------
    mass : sympy expression [kg]
    inertia : sympy Matrix (3, 3) [kg m^2], about the centre of mass, body axes
    jv : dict coordinate index -> Matrix (3, 1)
        Nonzero columns of J = d r_c / dq (global axes) [m per unit of q].
    jw : dict coordinate index -> Matrix (3, 1)
        Nonzero columns of G = d omega / dqd (body axes) [rad/s per unit of qd].
    v : Matrix (3, 1)
        Centre-of-mass velocity J qd [m/s].
    a : Matrix (3, 1)
        Its acceleration with qdd = 0, Jdot qd [m/s^2].
    w : Matrix (3, 1)
        Angular velocity G qd, body axes [rad/s].
    wd : Matrix (3, 1)
        Its rate with qdd = 0, Gdot qd, body axes [rad/s^2].
    """

    mass: sp.Expr
    inertia: sp.Matrix
    jv: dict[int, sp.Matrix]
    jw: dict[int, sp.Matrix]
    v: sp.Matrix
    a: sp.Matrix
    w: sp.Matrix
    wd: sp.Matrix


@dataclass
class RecursiveTerms:
    """What :func:`csim.model.derive.derive` needs of a mechanism built link by link.

    Attributes
    ----------
    intermediates : Intermediates
    bodies : list of BodyTerms
    phi : list of sympy expressions (r,)
    phi_q : list of dict coordinate index -> expression (r,)
        The nonzero entries of each row of Phi_q.
    gamma : list of sympy expressions (r,)
        -(d(Phi_q qd)/dq) qd.
    """

    intermediates: Intermediates
    bodies: list[BodyTerms]
    phi: list[sp.Expr] = field(default_factory=list)
    phi_q: list[dict[int, sp.Expr]] = field(default_factory=list)
    gamma: list[sp.Expr] = field(default_factory=list)


def _dot(a, b) -> sp.Expr:
    return sp.Add(*[x * y for x, y in zip(a, b)])


def assemble(terms: RecursiveTerms, m: int) -> tuple[sp.Matrix, sp.Matrix, sp.Expr]:
    """M (m, m), C qd (m, 1) and T of the bodies (see the module docstring).

    Products shared by many entries (I w, w x I w, I G columns, I wd) are named as further
    intermediates.
    """
    pool = terms.intermediates
    M_terms: dict[tuple[int, int], list] = {}
    C_terms: dict[int, list] = {}
    T_terms = []
    for b in terms.bodies:
        mass, inertia = b.mass, b.inertia
        # translation: m J^T J, m J^T a, 1/2 m |v|^2
        cols = sorted(b.jv)
        for x, i in enumerate(cols):
            for j in cols[x:]:
                M_terms.setdefault((i, j), []).append(mass * _dot(b.jv[i], b.jv[j]))
            C_terms.setdefault(i, []).append(mass * _dot(b.jv[i], b.a))
        T_terms.append(mass * _dot(b.v, b.v) / 2)
        if not b.jw or inertia.is_zero_matrix:
            continue
        # rotation: G^T I G, G^T (I wd + w x I w), 1/2 w . I w
        Iw = pool.matrix(inertia * b.w)
        euler = pool.matrix(inertia * b.wd + b.w.cross(Iw))
        cols = sorted(b.jw)
        IG = {j: pool.matrix(inertia * b.jw[j]) for j in cols}
        for x, i in enumerate(cols):
            for j in cols[x:]:
                M_terms.setdefault((i, j), []).append(_dot(b.jw[i], IG[j]))
            C_terms.setdefault(i, []).append(_dot(b.jw[i], euler))
        T_terms.append(_dot(b.w, Iw) / 2)
    M = sp.zeros(m, m)
    for (i, j), parts in M_terms.items():
        M[i, j] = M[j, i] = sp.Add(*parts)
    Cqd = sp.zeros(m, 1)
    for i, parts in C_terms.items():
        Cqd[i] = sp.Add(*parts)
    return M, Cqd, sp.Add(*T_terms)


def needed(exprs, intermediates: list[tuple[sp.Symbol, sp.Expr]]) -> list[tuple[sp.Symbol, sp.Expr]]:
    """The intermediates that ``exprs`` use, directly or through others, in order of definition."""
    if not intermediates:
        return []
    index = {sym: k for k, (sym, _) in enumerate(intermediates)}
    want = set()
    stack = [s for e in exprs for s in sp.sympify(e).free_symbols if s in index]
    while stack:
        sym = stack.pop()
        if sym in want:
            continue
        want.add(sym)
        stack += [s for s in intermediates[index[sym]][1].free_symbols if s in index and s not in want]
    return [item for item in intermediates if item[0] in want]


def common_subexpressions(exprs, intermediates, prefix: str = "_x") -> tuple[list, list]:
    """``sympy.cse`` of a function's outputs: (temporaries, reduced outputs).

    Without named intermediates: one CSE over all outputs ("basic" optimizations). With
    them, the outputs assembled from intermediates (sums of products of symbols, no
    function calls) are left as they are: the intermediates already share what CSE would
    find, and CSE of thousands of them costs more than the rest of the code generation;
    the others (observables, points, loads: expressions of the coordinates) get one CSE
    without the "basic" pre- and post-processing.
    """
    exprs = list(exprs)
    symbols = sp.numbered_symbols(prefix)
    if not intermediates:
        return sp.cse(exprs, symbols=symbols, optimizations="basic") if exprs else ([], [])
    whole = [k for k, e in enumerate(exprs) if sp.sympify(e).has(sp.Function)]
    if not whole:
        return [], exprs
    # no "basic" pre-processing: its factor_terms costs most of the code generation of deep
    # observables (a 12-bar loop's points), for a few negations
    temps, reduced = sp.cse([exprs[k] for k in whole], symbols=symbols)
    out = list(exprs)
    for k, e in zip(whole, reduced):
        out[k] = e
    return temps, out


def sparse_jacobian(exprs, q) -> sp.Matrix:
    """d exprs / dq, (len(exprs), len(q)), differentiating each entry only by the coordinates
    it contains (the same matrix as ``Matrix.jacobian``, without its many zero derivatives)."""
    exprs = [sp.sympify(e) for e in exprs]
    J = sp.zeros(len(exprs), len(q))
    for i, e in enumerate(exprs):
        fs = e.free_symbols
        for j, qj in enumerate(q):
            if qj in fs:
                J[i, j] = sp.diff(e, qj)
    return J


def gradient(expr, q) -> sp.Matrix:
    """d expr / dq as a column (len(q), 1), term by term: each term of a sum is differentiated
    only by the coordinates it contains (a long chain's V has a term per link)."""
    parts: dict[int, list] = {}
    index = {qj: j for j, qj in enumerate(q)}
    for term in sp.Add.make_args(sp.sympify(expr)):
        for qj in term.free_symbols:
            if qj in index:
                parts.setdefault(index[qj], []).append(sp.diff(term, qj))
    out = sp.zeros(len(q), 1)
    for j, terms in parts.items():
        out[j] = sp.Add(*terms)
    return out

