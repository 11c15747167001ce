"""Kinematics of a linkage link by link, in named intermediates, for the equations of motion.

Along the spanning tree, from the root, each link's global transform T_b = [R_b, p_b] is
defined from its parent's and the link-to-link transform across its tree joint
T_rel = [A, s] (:mod:`csim.linkage.frames`), which depends on that joint's variables only:

    R_b = R_p A,                p_b = p_p + R_p s
    dR_b/dq_j = dR_p/dq_j A     dp_b/dq_j = dp_p/dq_j + dR_p/dq_j s      (j an ancestor's)
    dR_b/dq_j = R_p dA/dq_j     dp_b/dq_j = R_p ds/dq_j                   (j its own)
    Rdot_b = Rdot_p A + R_p Adot,   Rdd_b = Rdd_p A + 2 Rdot_p Adot + R_p Add    (qdd = 0)

(the same for p), with Adot = sum_j dA/dq_j qd_j and Add = sum_jk d2A/dq_j dq_k qd_j qd_k
over the joint's own variables. The angular velocity in body axes follows the tree as in
:func:`csim.linkage.model.link_angular_velocities`: w_b = A^T w_p + w_own with
w_own = A^T w_rel linear in the joint's rates, and its rate with qdd = 0 is
wd_b = A^T wd_p + Adot^T w_p + sum_k dw_own/dq_k qd_k.

Every nontrivial entry is a named intermediate (:class:`csim.model.recursive.Intermediates`),
so each link costs a fixed number of short expressions per ancestor joint and the whole
model grows with the number of links times the depth of the tree.

A kept cut-joint equation Phi_i = f(X), X the entries of the two links' transforms
(:data:`csim.linkage.joints.JOINT_TYPES`), gets by the chain rule

    Phi_q[i, j] = sum_x df/dx dx/dq_j,
    gamma_i = -(sum_x df/dx xdd + sum_xy d2f/dx dy xdot ydot)       (xdd with qdd = 0).
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from csim.linkage.constraints import Equation
from csim.linkage.frames import Frames
from csim.linkage.joints import JOINT_TYPES, CutGeometry
from csim.linkage.tables import Tables
from csim.linkage.topology import Topology
from csim.linkage.transforms import simplify_entry
from csim.model.recursive import BodyTerms, Intermediates, RecursiveTerms


@dataclass
class LinkState:
    """One link's transform, its derivatives and rates, in intermediates (global axes but w, wd).

    ``dR``/``dp``: dict coordinate index -> (3, 3) / (3, 1), the nonzero columns d/dq_j.
    ``w``, ``wd``, ``G``: angular velocity, its qdd-free rate and d w / dqd columns (body axes).
    """

    R: sp.Matrix
    p: sp.Matrix
    dR: dict
    dp: dict
    Rd: sp.Matrix
    pd: sp.Matrix
    Rdd: sp.Matrix
    pdd: sp.Matrix
    w: sp.Matrix
    wd: sp.Matrix
    G: dict


def _mul(A: sp.Matrix, B: sp.Matrix) -> sp.Matrix:
    """A B for small matrices, entry by entry (sympy's general product converts to a domain
    matrix first, which costs more than these 3 x 3 products themselves)."""
    zero, one = sp.S.Zero, sp.S.One
    a, b = A.tolist(), B.tolist()

    def product(x, y):
        return y if x is one else x if y is one else x * y

    return sp.Matrix(A.rows, B.cols, [sp.Add(*[product(a[i][k], b[k][j]) for k in range(A.cols)
                                               if a[i][k] is not zero and b[k][j] is not zero])
                                      for i in range(A.rows) for j in range(B.cols)])


def _diff(A: sp.Matrix, x: sp.Symbol) -> sp.Matrix:
    """dA/dx entry by entry."""
    return A.applyfunc(lambda e: sp.diff(e, x) if x in e.free_symbols else sp.Integer(0))


def _root() -> LinkState:
    z3 = sp.zeros(3, 1)
    return LinkState(sp.eye(3), z3, {}, {}, sp.zeros(3, 3), z3, sp.zeros(3, 3), z3, z3, z3, {})


def _trig_names(exprs: list, pool: Intermediates) -> dict:
    """Each sine and cosine of the joint variables in ``exprs`` -> a named intermediate."""
    atoms = set()
    for e in exprs:
        atoms |= {a for a in sp.sympify(e).atoms(sp.sin, sp.cos) if a.free_symbols}
    return {a: pool.name(a) for a in sorted(atoms, key=sp.default_sort_key)}


class _Builder:
    def __init__(self, tables: Tables, topology: Topology, frames: Frames):
        self.tables, self.topology, self.frames = tables, topology, frames
        self.q = [v.symbol for v in topology.variables]
        self.qd = [v.velocity for v in topology.variables]
        self.index = {s: i for i, s in enumerate(self.q)}
        self.pool = Intermediates()
        self.states: dict[int, LinkState] = {0: _root()}

    def name(self, M: sp.Matrix) -> sp.Matrix:
        return self.pool.matrix(M)

    def link(self, child: int) -> None:
        """The state of ``child`` from its parent's (see the module docstring)."""
        edge = self.topology.edges[child]
        c = edge.coupling
        vs = self.topology.variables_of(c)
        q_own, qd_own = [v.symbol for v in vs], [v.velocity for v in vs]
        rel = self.frames.relative[child]
        A, s = rel[:3, :3], rel[:3, 3]
        # the angular velocity across the joint, in the child's axes (linear in its rates)
        w_joint = JOINT_TYPES[c.type].angular_velocity(q_own, qd_own)
        A_ik = self.frames.local[(c.i, c.k)][:3, :3]
        w_rel = A_ik * w_joint if edge.forward else -A * A_ik * w_joint
        w_own = _mul(A.T, w_rel).applyfunc(simplify_entry)
        # own derivatives, before the sines and cosines are named
        dA = {qj: _diff(A, qj) for qj in q_own}
        ds = {qj: _diff(s, qj) for qj in q_own}
        Ad = sum((dA[qj] * qdj for qj, qdj in zip(q_own, qd_own)), sp.zeros(3, 3))
        sd = sum((ds[qj] * qdj for qj, qdj in zip(q_own, qd_own)), sp.zeros(3, 1))
        Add = sum((_diff(Ad, qj) * qdj for qj, qdj in zip(q_own, qd_own)), sp.zeros(3, 3))
        sdd = sum((_diff(sd, qj) * qdj for qj, qdj in zip(q_own, qd_own)), sp.zeros(3, 1))
        G_own = {qj: _diff(w_own, qdj) for qj, qdj in zip(q_own, qd_own)}
        wd_own = sum((_diff(w_own, qj) * qdj for qj, qdj in zip(q_own, qd_own)), sp.zeros(3, 1))
        pieces = [A, s, Ad, sd, Add, sdd, w_own, wd_own, *dA.values(), *ds.values(), *G_own.values()]
        trig = _trig_names([e for P in pieces for e in P], self.pool)

        def own(P):
            return self.name(P.xreplace(trig))

        A, s, Ad, sd, Add, sdd, w_own, wd_own = (own(P) for P in (A, s, Ad, sd, Add, sdd, w_own, wd_own))
        par = self.states[edge.parent]
        name = self.name
        dR, dp, G = {}, {}, {}
        for j, dRp in par.dR.items():  # an ancestor's variable
            dR[j] = name(_mul(dRp, A))
            dp[j] = name(par.dp[j] + _mul(dRp, s))
        for qj in q_own:
            j = self.index[qj]
            dR[j] = name(_mul(par.R, own(dA[qj])))
            dp[j] = name(_mul(par.R, own(ds[qj])))
        for j, Gp in par.G.items():
            G[j] = name(_mul(A.T, Gp))
        for qj in q_own:
            G[self.index[qj]] = own(G_own[qj])
        R = name(_mul(par.R, A))
        p = name(par.p + _mul(par.R, s))
        Rd = name(_mul(par.Rd, A) + _mul(par.R, Ad))
        pd = name(par.pd + _mul(par.Rd, s) + _mul(par.R, sd))
        Rdd = name(_mul(par.Rdd, A) + 2 * _mul(par.Rd, Ad) + _mul(par.R, Add))
        pdd = name(par.pdd + _mul(par.Rdd, s) + 2 * _mul(par.Rd, sd) + _mul(par.R, sdd))
        w = name(_mul(A.T, par.w) + w_own)
        wd = name(_mul(A.T, par.wd) + _mul(Ad.T, par.w) + wd_own)
        self.states[child] = LinkState(R, p, dR, dp, Rd, pd, Rdd, pdd, w, wd, G)

    def body(self, number: int) -> BodyTerms:
        """The centre of mass r_c = p + R c of link ``number`` and its rates."""
        link, st = self.tables.links[number], self.states[number]
        com = sp.Matrix(link.com)
        name = self.name
        jv = {j: name(st.dp[j] + _mul(st.dR[j], com)) for j in st.dp}
        jv = {j: v for j, v in jv.items() if not v.is_zero_matrix}
        v = name(st.pd + _mul(st.Rd, com))
        a = name(st.pdd + _mul(st.Rdd, com))
        jw = {j: g for j, g in st.G.items() if not g.is_zero_matrix}
        return BodyTerms(link.mass, sp.Matrix(link.inertia), jv, jw, v, a, st.w, st.wd)

    def equation(self, eq: Equation) -> tuple[sp.Expr, dict[int, sp.Expr], sp.Expr]:
        """Phi_i, its row of Phi_q and gamma_i by the chain rule (see the module docstring)."""
        c = eq.coupling
        record = next(e for e in JOINT_TYPES[c.type].cut_equations if e.component == eq.component)
        X, values, dX, Xd, Xdd = [], [], [], [], []
        frames = []
        for link, index in ((c.i, c.k), (c.j, c.m)):
            st = self.states[link]
            Rs = sp.Matrix(3, 3, [sp.Symbol(f"_R{link}_{a}{b}", real=True) for a in range(3) for b in range(3)])
            ps = sp.Matrix([sp.Symbol(f"_p{link}_{a}", real=True) for a in range(3)])
            T = sp.eye(4)
            T[:3, :3], T[:3, 3] = Rs, ps
            frames.append(T * self.frames.local[(link, index)])
            X += list(Rs) + list(ps)
            values += list(st.R) + list(st.p)
            dX += [{j: st.dR[j][n] for j in st.dR} for n in range(9)] + [{j: st.dp[j][n] for j in st.dp}
                                                                        for n in range(3)]
            Xd += list(st.Rd) + list(st.pd)
            Xdd += list(st.Rdd) + list(st.pdd)
        f = sp.expand(record.expression(CutGeometry.from_transforms(*frames)))
        at = dict(zip(X, values))
        used = [k for k, x in enumerate(X) if f.has(x)]
        df = {k: sp.diff(f, X[k]) for k in used}
        grad = {k: self.pool.name(df[k].xreplace(at)) for k in used}
        row: dict[int, list] = {}
        for k in used:
            for j, dx in dX[k].items():
                if dx != 0:
                    row.setdefault(j, []).append(grad[k] * dx)
        phi_q = {j: sp.Add(*parts) for j, parts in sorted(row.items())}
        phi_q = {j: e for j, e in phi_q.items() if e != 0}
        acc = [grad[k] * Xdd[k] for k in used]
        for x, k in enumerate(used):
            for l in used[x:]:
                h = sp.diff(df[k], X[l]) if X[l] in df[k].free_symbols else 0
                if h != 0:
                    acc.append((1 if k == l else 2) * h.xreplace(at) * Xd[k] * Xd[l])
        return f.xreplace(at), phi_q, -sp.Add(*acc)


def recursive_terms(tables: Tables, topology: Topology, frames: Frames, kept: list[Equation]) -> RecursiveTerms:
    """The link-by-link kinematics of a linkage, its bodies and its kept constraint equations."""
    builder = _Builder(tables, topology, frames)
    for child in topology.order[1:]:
        builder.link(child)
    bodies = [builder.body(number) for number, link in sorted(tables.links.items())
              if number != 0 and link.has_mass]
    phi, phi_q, gamma = [], [], []
    for eq in kept:
        f, row, g = builder.equation(eq)
        phi.append(f)
        phi_q.append(row)
        gamma.append(g)
    return RecursiveTerms(builder.pool, bodies, phi, phi_q, gamma)
