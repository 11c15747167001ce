"""Reactions of the cut joints, from the Lagrange multipliers.

The equations of motion are M qdd + Phi_q^T lambda = Q - C qd - h, so the constraints act
on the mechanism with the generalized force -Phi_q^T lambda, whose virtual work is
delta W = -lambda^T delta Phi. A cut joint (i, k)-(j, m) transmits a wrench: a force F and
a moment M (about the origin r_jm of frame jm) that link i exerts on link j, and -F, -M on
link i. Moving link j alone by a virtual translation delta r of its point at r_jm and a
virtual rotation delta theta (A_jm -> (E + [delta theta]x) A_jm), its work is
F . delta r + M . delta theta = -sum_e lambda_e delta Phi_e, so

    F = -sum_e lambda_e dPhi_e/d r_jm,      M = -sum_e lambda_e dPhi_e/d theta_j,

with the derivatives taken by sympy from the very functions csim builds for the joint
(:data:`csim.linkage.joints.JOINT_TYPES`, :class:`~csim.linkage.joints.CutGeometry`),
at symbolic poses of the two frames: no equation is transcribed here. At an assembled
configuration this gives, e.g., for an R joint F = -(lambda_x, lambda_y, lambda_z) and
M = lambda_4 x_ik - lambda_5 y_ik.

Only the kept equations have multipliers. A reaction component whose equation was removed
is reported as 0 and named in :attr:`JointReaction.undetermined`:

- identically zero equations (the out-of-plane ones of a planar mechanism): the planar
  model carries no such reaction (f_z, m_x, m_y of a planar R joint);
- dependent equations (an overconstrained loop such as Bricard's): the reactions are
  statically indeterminate, and the values reported are the one solution with the removed
  multipliers at 0.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

from csim.linkage.constraints import KEPT, ZERO
from csim.linkage.forces import Geometry, JointCoordinate, build_forces
from csim.linkage.frames import Frames
from csim.linkage.joints import JOINT_TYPES, CutGeometry
from csim.linkage.lambdacache import cached_lambdify
from csim.linkage.tables import Coupling
from csim.result import JointReaction

#: units of the recorded reactions
FORCE_UNIT, TORQUE_UNIT = "N", "N m"


def _skew(w: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


@functools.cache
def wrench_jacobian(joint_type: str):
    """The derivatives of a joint type's cut equations with respect to a virtual motion of frame jm.

    Parameters
    ----------
    joint_type : str
        A type letter of :data:`JOINT_TYPES`.

    Returns
    -------
    callable (r_ik (3,), A_ik (3, 3), r_jm (3,), A_jm (3, 3)) -> ndarray (6, n_eq)
        Column e holds dPhi_e/d r_jm [1 for position equations, 1/m for direction ones]
        (rows 0-2) and dPhi_e/d theta_j [m or 1 per rad] (rows 3-5), in global axes, for
        the type's equations in their order.
    """
    r_ik, r_jm = sp.Matrix(sp.symbols("rik0:3")), sp.Matrix(sp.symbols("rjm0:3"))
    A_ik, A_jm = sp.Matrix(3, 3, sp.symbols("Aik0:9")), sp.Matrix(3, 3, sp.symbols("Ajm0:9"))
    eps = sp.Symbol("eps")
    dr, dth = sp.Matrix(sp.symbols("dr0:3")), sp.Matrix(sp.symbols("dth0:3"))
    moved = CutGeometry(r_ik, r_jm + eps * dr, A_ik, (sp.eye(3) + eps * _skew(dth)) * A_jm)
    columns = []
    for eq in JOINT_TYPES[joint_type].cut_equations:
        rate = sp.expand(sp.diff(eq.expression(moved), eps).subs(eps, 0))  # linear in dr, dth
        columns.append([rate.coeff(s) for s in (*dr, *dth)])
    entries = [columns[e][k] for k in range(6) for e in range(len(columns))]  # (6, n_eq) row-major
    f = sp.lambdify([list(r_ik), list(A_ik), list(r_jm), list(A_jm)], entries, "numpy")
    n = len(columns)

    def jacobian(ri, Ai, rj, Aj):
        """At N poses: ri, rj (N, 3), Ai, Aj (N, 3, 3) -> (N, 6, n_eq); or at one pose (6, n_eq)."""
        ri, rj = np.asarray(ri, dtype=float), np.asarray(rj, dtype=float)
        one = ri.ndim == 1
        ri, rj = np.atleast_2d(ri), np.atleast_2d(rj)
        Ai, Aj = np.reshape(Ai, (-1, 9)), np.reshape(Aj, (-1, 9))
        values = f(list(ri.T), list(Ai.T), list(rj.T), list(Aj.T))  # constant entries come back as scalars
        out = np.stack([np.broadcast_to(np.asarray(v, dtype=float), ri.shape[:1]) for v in values], axis=1)
        out = out.reshape(ri.shape[0], 6, n)
        return out[0] if one else out

    return jacobian


def _removed(equations) -> list[str]:
    """The reaction unknowns of removed equations, and why."""
    out = []
    for eq in equations:
        if eq.status == KEPT:
            continue
        why = ("not carried by this (planar) model: its equation holds identically" if eq.status == ZERO else
               "statically indeterminate: its equation is dependent and was removed; reported with the "
               "removed multiplier at 0")
        out.append(f"{eq.reaction}: {why}")
    return out


def _frame_functions(linkage, definition):
    """(q, par) -> {coupling number: (T_ik (4, 4), T_jm (4, 4))} for every cut joint (kept on
    the linkage: lambdifying the frames takes longer than evaluating them)."""
    cached = getattr(linkage, "_reaction_frames", None)
    if cached is not None:
        return cached
    cuts = linkage.topology.cut_joints

    def make():
        return ([list(definition.coordinates), list(definition.parameter_symbols)],
                [m for c in cuts for m in (linkage.frames.joint_frame(c.i, c.k), linkage.frames.joint_frame(c.j, c.m))])

    f = cached_lambdify(linkage.cache_key, "cut_frames", make)

    def frames(q, par):
        values = f(list(q), list(par))
        return {c.number: (np.asarray(values[2 * n], dtype=float), np.asarray(values[2 * n + 1], dtype=float))
                for n, c in enumerate(cuts)}

    linkage._reaction_frames = frames
    return frames


def joint_reactions(linkage, definition, par: np.ndarray, q: np.ndarray, lam: np.ndarray) -> list[JointReaction]:
    """The reactions of every cut joint at the recorded samples.

    Parameters
    ----------
    linkage : csim.linkage.model.Linkage
    definition : MechanismDefinition
        The linkage's model (its coordinates and parameter symbols; its constraints are the
        kept equations, in the order of ``lam``'s columns).
    par : ndarray (n_par,)
        Parameter values, in the order of ``definition.parameters``.
    q : ndarray (N, m)
        Coordinates [rad or m].
    lam : ndarray (N, r)
        Multipliers of the kept equations, or of every non-trivial one (an overconstrained
        linkage's run records them all); NaN where a sample could not be evaluated.

    Returns
    -------
    list of JointReaction
        One per cut joint, in the order of ``linkage.topology.cut_joints``.
    """
    kept = linkage.reduction.kept
    if lam.shape[1] != len(kept):
        kept = [eq for eq in linkage.reduction.equations if eq.status != ZERO]
    column = {id(eq): n for n, eq in enumerate(kept)}
    frames = _frame_functions(linkage, definition)
    cuts = linkage.topology.cut_joints
    equations = {c.number: [eq for eq in linkage.reduction.equations if eq.coupling.number == c.number]
                 for c in cuts}
    N = q.shape[0]
    values = {c.number: np.full((4, N, 3), np.nan) for c in cuts}  # F, M global; F, M in frame ik
    rows = np.flatnonzero(np.all(np.isfinite(q), axis=1))
    if not cuts or not rows.size:
        return [_cut_reaction(linkage, c, values[c.number], equations[c.number]) for c in cuts]
    # the cut joints' frames at the evaluated samples: (n, C, 4, 4) each
    at = [frames(q[s], par) for s in rows]
    T_ik = np.array([[a[c.number][0] for c in cuts] for a in at], dtype=float)
    T_jm = np.array([[a[c.number][1] for c in cuts] for a in at], dtype=float)
    for n, c in enumerate(cuts):
        # the multipliers of the joint's equations (0 for a removed one): (n, n_eq)
        lam_eq = np.column_stack([lam[rows, column[id(eq)]] if id(eq) in column else np.zeros(rows.size)
                                  for eq in equations[c.number]] or [np.zeros((rows.size, 0))])
        ri, Ai, rj, Aj = T_ik[:, n, :3, 3], T_ik[:, n, :3, :3], T_jm[:, n, :3, 3], T_jm[:, n, :3, :3]
        wrench = -np.einsum("ske,se->sk", wrench_jacobian(c.type)(ri, Ai, rj, Aj), lam_eq)  # (n, 6)
        F, M = wrench[:, :3], wrench[:, 3:]
        v = values[c.number]
        v[0, rows], v[1, rows] = F, M
        v[2, rows], v[3, rows] = np.einsum("sji,sj->si", Ai, F), np.einsum("sji,sj->si", Ai, M)  # A_ik^T F, A_ik^T M
    return [_cut_reaction(linkage, c, values[c.number], equations[c.number]) for c in cuts]


def _cut_reaction(linkage, c, v: np.ndarray, equations) -> JointReaction:
    """The JointReaction of cut joint c from its values (4, N, 3): F, M global; F, M in frame ik."""
    name = str(c.name or c.number)
    label = f"joint {name} ({c.type}, {linkage.tables.link_label(c.i)} on {linkage.tables.link_label(c.j)})"
    return JointReaction(name, label, v[0], v[1], v[2], v[3], _removed(equations))


# ---------------------------------------------------------------------------------------
# tree joints: Newton-Euler of the subtree beyond the joint, with the joint released
# ---------------------------------------------------------------------------------------
def subtree(topology, child: int) -> set[int]:
    """The links beyond a tree joint: ``child`` and every link reached from it away from link 0."""
    below = {child}
    for link in topology.order:
        edge = topology.edges.get(link)
        if edge is not None and edge.parent in below:
            below.add(link)
    return below


def _kinematics(linkage, definition):
    """(links, kinematics): the L links with mass, and (q, qd, qdd, par) -> ((m (L,), I (L, 3, 3),
    r_C (L, 3), a_C (L, 3), A (L, 3, 3), omega (L, 3), alpha (L, 3)), g (3,)): each link's mass
    [kg] and inertia about the centre of mass in its axes [kg m^2], the centre of mass and its
    acceleration in global axes [m, m/s^2], the link's axes, its angular velocity and
    acceleration in its own axes [rad/s, rad/s^2]; and gravity [m/s^2].
    a_C = J qdd + d(J qd)/dq qd and alpha = d(omega)/dqd qdd + d(omega)/dq qd, by sympy."""
    cached = getattr(linkage, "_reaction_kinematics", None)
    if cached is not None:
        return cached
    from csim.linkage.model import link_angular_velocities

    links = [n for n, link in sorted(linkage.tables.links.items()) if n != 0 and link.has_mass]

    def make():
        q, qd = list(definition.coordinates), list(definition.velocities)
        qdd = [sp.Symbol(f"{s}_ddot", real=True) for s in q]
        omega = link_angular_velocities(linkage.topology, linkage.frames)
        rows = []
        for n in links:
            T = linkage.frames.links[n]
            r_c = (T * sp.Matrix([*linkage.tables.links[n].com, 1]))[:3, 0]
            v_c = r_c.jacobian(q) * sp.Matrix(qd)
            a_c = v_c.jacobian(qd) * sp.Matrix(qdd) + v_c.jacobian(q) * sp.Matrix(qd)
            w = omega[n]
            alpha = w.jacobian(qd) * sp.Matrix(qdd) + w.jacobian(q) * sp.Matrix(qd)
            link = linkage.tables.links[n]
            rows += [sp.Matrix([link.mass]), sp.Matrix(link.inertia), r_c, a_c, T[:3, :3], w, alpha]
        rows.append(sp.Matrix(linkage.tables.gravity))
        return [q, qd, qdd, list(definition.parameter_symbols)], rows

    f = cached_lambdify(linkage.cache_key, "kinematics", make)
    shapes = [(), (3, 3), (3,), (3,), (3, 3), (3,), (3,)]

    def kinematics(qv, qdv, qddv, par):
        values = f(list(qv), list(qdv), list(qddv), list(par))
        L = len(links)
        stacked = tuple(np.array([values[7 * i + k] for i in range(L)], dtype=float).reshape(L, *shape)
                        for k, shape in enumerate(shapes))
        return stacked, np.asarray(values[-1], dtype=float).ravel()

    linkage._reaction_kinematics = links, kinematics
    return links, kinematics


#: the six virtual motions of a released subtree: translations along, rotations about global x, y, z
EPS = sp.symbols("eps_tx eps_ty eps_tz eps_rx eps_ry eps_rz", real=True)
EPS_DOT = sp.symbols("eps_tx_dot eps_ty_dot eps_tz_dot eps_rx_dot eps_ry_dot eps_rz_dot", real=True)


@dataclass
class ReleasedGeometry(Geometry):
    """A link-coupling geometry with the subtree beyond one tree joint given a virtual rigid
    motion eps (6) about the joint's point r_J: p -> p + tau + rho x (p - r_J), to first order
    in eps (only derivatives at eps = 0 are taken). The force elements built on it
    (:func:`csim.linkage.forces.build_forces`) have potentials and directions in (q, eps).
    Build it with :meth:`released`.

    Attributes
    ----------
    released : Coupling
        The tree joint.
    below : frozenset of int
        The links beyond it (:func:`subtree`).
    base : Frames
        The mechanism's own transforms (``frames`` holds the moved ones).
    """

    released: Coupling | None = None
    below: frozenset = frozenset()
    base: Frames | None = None

    @classmethod
    def released_at(cls, linkage, coupling: Coupling, below: set[int]) -> ReleasedGeometry:
        """The geometry of ``linkage`` with the links ``below`` the tree joint ``coupling`` moved by eps."""
        frames = linkage.frames
        r_J = frames.joint_frame(coupling.j, coupling.m)[:3, 3]
        tau, rho = sp.Matrix(EPS[:3]), sp.Matrix(EPS[3:])
        D = sp.eye(4)  # [[E + [rho]x, tau - [rho]x r_J], [0, 1]]
        D[:3, :3] += _skew(rho)
        D[:3, 3] = tau - _skew(rho) * r_J
        links = {n: (D * T if n in below else T) for n, T in frames.links.items()}
        moved = Frames(local=frames.local, joints=frames.joints, relative=frames.relative, links=links)
        return cls(linkage.tables, linkage.topology, moved, released=coupling, below=frozenset(below), base=frames)

    @property
    def q(self):
        return [v.symbol for v in self.topology.variables] + list(EPS)

    # The reactions take the elements' potentials and their directions along eps only, with
    # the load values the run recorded: the rates in the laws and the directions along q
    # (sympy derivatives of long expressions, most of a run's reaction work) are not needed.
    def rate(self, expr: sp.Expr) -> sp.Expr:
        """A stand-in for d expr/dt (the laws are not evaluated here)."""
        return sp.Dummy("rate")

    def gradient(self, expr: sp.Expr) -> list[sp.Expr]:
        """d expr/d(q, eps) with the q entries left 0 (only the eps rows are read)."""
        m = len(self.topology.variables)
        return [sp.Integer(0)] * m + [sp.diff(expr, e) for e in EPS]

    @property
    def qd(self):
        return [v.velocity for v in self.topology.variables] + list(EPS_DOT)

    def omega(self, link):
        w = super().omega(link)  # the tree's own, from the joint rates
        if link not in self.below:
            return w
        return w + self.base.links[link][:3, :3].T * sp.Matrix(EPS_DOT[3:])

    def joint(self, path, raw, problems, unit=None):
        found = super().joint(path, raw, problems, unit)
        c = self.released
        own = [v.symbol for v in self.topology.variables_of(c)]
        if found is None or found.value not in own:
            return found
        # the released joint's own variable: q plus the change eps makes in the relative
        # motion of its two frames (the joint type's measure)
        slot = own.index(found.value)
        measure = JOINT_TYPES[c.type].measure

        def measured(frames):
            g = CutGeometry.from_transforms(frames.joint_frame(c.i, c.k), frames.joint_frame(c.j, c.m))
            return measure(g, lambda e: e)[slot]

        return JointCoordinate(found.value + measured(self.frames) - measured(self.base), found.unit, found.label)


def _element_terms(linkage, definition, raw_forces, coupling, below: set[int]):
    """What the force elements and the joint's drives do on the released subtree:
    (q, qd, par) -> (dV/deps (6,), B_eps (6, k), D_eps (6, d)) at eps = 0, or None when there
    are neither. V is the elements' potential, B_eps the eps rows of the loads' generalized
    directions (in the order of ``definition.loads``), D_eps those of the joint's driven
    variables (in the order of ``linkage.drive``)."""
    own = {v.name for v in linkage.topology.variables_of(coupling)}
    driven = [name for name in linkage.drive if name in own]
    if not raw_forces and not driven:
        return None
    n_loads = len(definition.loads)

    def make():  # the symbolic work (cached: csim.linkage.lambdacache)
        geo = ReleasedGeometry.released_at(linkage, coupling, below)
        problems: list[str] = []
        part = build_forces(raw_forces, geo, problems)  # checked once already, by the model's build
        if problems or len(part.loads) != n_loads:
            raise RuntimeError(f"the force elements rebuilt for the reaction of {coupling.label} differ from the "
                               f"model's: {'; '.join(problems) or 'another number of loads'}")
        at_zero = {e: 0 for e in (*EPS, *EPS_DOT)}
        m = len(definition.coordinates)

        def eps_rows(expr_or_direction) -> list:
            direction = (geo.gradient(expr_or_direction) if not isinstance(expr_or_direction, list)
                         else expr_or_direction)
            return [sp.sympify(d).xreplace(at_zero) for d in direction[m:]]

        dV = [sp.diff(part.potential, e).xreplace(at_zero) for e in EPS]
        B = [eps_rows(ld.direction if ld.direction is not None else ld.coordinate) for ld in part.loads]
        D = [eps_rows(geo.joint("drive", name, problems).value) for name in driven]
        return ([list(definition.coordinates), list(definition.velocities), list(definition.parameter_symbols)],
                [sp.Matrix(dV), sp.Matrix(6, len(B), lambda i, k: B[k][i]),
                 sp.Matrix(6, len(D), lambda i, k: D[k][i])])

    f = cached_lambdify(linkage.cache_key, f"elements_{coupling.number}", make)
    columns = [list(linkage.drive).index(name) for name in driven]

    def terms(q, qd, par):
        dv, b, d = (np.asarray(x, dtype=float) for x in f(list(q), list(qd), list(par)))
        return dv.ravel(), b.reshape(6, n_loads), d.reshape(6, len(driven)), columns

    return terms


def _tree_frames(linkage, definition):
    """(q, par) -> {coupling number: T_jm (4, 4), T_ik (4, 4)} of every tree joint."""
    tree = linkage.topology.tree_joints

    def make():
        return ([list(definition.coordinates), list(definition.parameter_symbols)],
                [m for c in tree for m in (linkage.frames.joint_frame(c.j, c.m), linkage.frames.joint_frame(c.i, c.k))])

    f = cached_lambdify(linkage.cache_key, "tree_frames", make)

    def frames(q, par):
        values = f(list(q), list(par))
        return {c.number: (np.asarray(values[2 * n], dtype=float), np.asarray(values[2 * n + 1], dtype=float))
                for n, c in enumerate(tree)}

    return frames


def _inertial_wrenches(at, g: np.ndarray, r_0: np.ndarray) -> np.ndarray:
    """[m (a_C - g); (r_C - r_0) x m (a_C - g) + A (I alpha + omega x I omega)] (L, 6) of each
    link with mass, about the point r_0 [N, N m, global axes] (``at`` from :func:`_kinematics`)."""
    m, inertia, r_c, a_c, A, w, alpha = at
    f = m[:, None] * (a_c - g)
    i_w = np.einsum("lij,lj->li", inertia, w)
    spin = np.einsum("lij,lj->li", A, np.einsum("lij,lj->li", inertia, alpha) + np.cross(w, i_w))
    return np.concatenate((f, np.cross(r_c - r_0, f) + spin), axis=1)


def _cut_wrenches(forces: np.ndarray, torques: np.ndarray, cut_at, cuts, r_0: np.ndarray) -> np.ndarray:
    """The wrench each cut joint's link i exerts on its link j (C, 6), about the point r_0
    [N, N m]: [F; M + (r_jm - r_0) x F], from its force F and moment M about r_jm (C, 3 each)
    and the cut joints' frames ``cut_at`` at the same sample."""
    r_jm = np.array([cut_at[c.number][1][:3, 3] for c in cuts])
    return np.concatenate((forces, torques + np.cross(r_jm - r_0, forces)), axis=1)


def _subtree_sums(weights: np.ndarray, wrenches: np.ndarray) -> np.ndarray:
    """weights (T, L) @ wrenches (L, 6), with the terms of zero weight left out rather than
    multiplied by 0 (a non-finite wrench of a link or cut joint outside a subtree leaves that
    subtree's sum finite, as a sum over its own members would)."""
    return np.where(weights[:, :, None] != 0, weights[:, :, None] * wrenches[None], 0.0).sum(axis=1)


#: what a planar model does not carry at a tree joint (out-of-plane components, reported as 0)
PLANAR_UNDETERMINED = ["force along the plane's normal, moments about in-plane axes: not carried by this (planar) "
                       "model: the motion is in its plane"]


def tree_reactions(linkage, definition, raw_forces, par, run, cut_reactions) -> list[JointReaction]:
    """The reactions of every tree joint at the recorded samples, by Newton-Euler of the
    subtree beyond the joint with the joint released (see :class:`ReleasedGeometry`).

    The wrench W (force F, moment M about the origin of frame jm) that link i exerts on
    link j, from the virtual work of a rigid virtual motion eps of the subtree S beyond the
    joint: W_S = sum_S [m (a_C - g); (r_C - r_J) x m (a_C - g) + A (I alpha + omega x I omega)]
    + dV/deps - B_eps u - D_eps tau - (cut-joint wrenches on S), with the elements' potential
    V, their loads u, the joint's drive forces tau and the cut joints' reactions; W = W_S when
    link j is in S, -W_S otherwise. Components along the joint's free directions vanish up to
    round-off (they are the joint's equation of motion); a planar model's out-of-plane
    components are reported as 0 and named in ``undetermined``.

    Parameters
    ----------
    linkage : Linkage
    definition : MechanismDefinition
        Its model (coordinates, velocities, parameter symbols, loads).
    raw_forces : list or None
        ``mechanism.forces`` as written.
    par : ndarray (n_par,)
    run : mapping
        ``q``, ``qd``, ``qdd`` (N, m), ``loads`` (N, k), ``drive_forces`` (N, d) or None.
    cut_reactions : list of JointReaction
        Of ``linkage.topology.cut_joints``, in their order.

    Returns
    -------
    list of JointReaction, one per tree joint in table order
    """
    topology = linkage.topology
    if not topology.tree_joints:
        return []
    links, kinematics = _kinematics(linkage, definition)
    frames = _tree_frames(linkage, definition)
    cut_frames = _frame_functions(linkage, definition) if topology.cut_joints else (lambda q, p: {})
    normal = _plane_normal(linkage, definition, par, run["q"])
    q, qd, qdd, u = run["q"], run["qd"], run["qdd"], run["loads"]
    tau = run.get("drive_forces")
    cuts, tree = topology.cut_joints, topology.tree_joints
    # which links (columns) each tree joint's subtree holds, and the sign with which each cut
    # joint's wrench (i on j) acts on it: +1 with j beyond the joint, -1 with i, 0 both or neither
    beyond = np.zeros((len(tree), len(links)))
    on_subtree = np.zeros((len(tree), len(cuts)))
    outward = np.ones(len(tree))  # W = W_S with link j in S, -W_S otherwise
    terms = []
    for a, c in enumerate(tree):
        below = subtree(topology, next(n for n, e in topology.edges.items() if e.coupling is c))
        beyond[a] = [n in below for n in links]
        on_subtree[a] = [(cut.j in below) - (cut.i in below) for cut in cuts]
        outward[a] = 1.0 if c.j in below else -1.0
        terms.append(_element_terms(linkage, definition, raw_forces, c, below))
    if cuts:  # the cut joints' reactions, (N, C, 3) each
        cut_F = np.stack([reaction.force_global for reaction in cut_reactions], axis=1)
        cut_M = np.stack([reaction.torque_global for reaction in cut_reactions], axis=1)
    N = q.shape[0]
    values = np.full((len(tree), 4, N, 3), np.nan)  # per joint: F, M global; in frame ik
    for s in range(N):
        if not (np.all(np.isfinite(q[s])) and np.all(np.isfinite(qdd[s]))):
            continue
        at, g = kinematics(q[s], qd[s], qdd[s], par)
        tree_at = frames(q[s], par)
        r_J = np.array([tree_at[c.number][0][:3, 3] for c in tree])
        r_0 = r_J.mean(axis=0)  # moments about a point of the mechanism: no round-off of far coordinates
        # W_S about r_0: the subtree's inertial wrench less the cut joints' on it
        W = _subtree_sums(beyond, _inertial_wrenches(at, g, r_0))
        if cuts:
            W -= _subtree_sums(on_subtree, _cut_wrenches(cut_F[s], cut_M[s], cut_frames(q[s], par), cuts, r_0))
        W[:, 3:] -= np.cross(r_J - r_0, W[:, :3])  # the moment about each joint's point r_J
        for a, fn in enumerate(terms):
            if fn is not None:
                dV, B, D, columns = fn(q[s], qd[s], par)
                W[a] += dV - B @ u[s]
                if columns:
                    W[a] -= D @ tau[s][columns]
        W *= outward[:, None]
        F, M = W[:, :3], W[:, 3:]
        if normal is not None:  # the planar model's components only
            F, M = F - np.outer(F @ normal, normal), np.outer(M @ normal, normal)
        A = np.array([tree_at[c.number][1][:3, :3] for c in tree])
        values[:, :, s] = np.stack((F, M, np.einsum("aji,aj->ai", A, F), np.einsum("aji,aj->ai", A, M)), axis=1)
    out = []
    for a, c in enumerate(tree):
        name = str(c.name or c.number)
        label = (f"joint {name} ({c.type}, {linkage.tables.link_label(c.i)} on {linkage.tables.link_label(c.j)}; "
                 f"tree joint: Newton-Euler of the links beyond it)")
        out.append(JointReaction(name, label, *values[a],
                                 list(PLANAR_UNDETERMINED) if normal is not None else []))
    return out


def _plane_normal(linkage, definition, par, q) -> np.ndarray | None:
    """The normal of a planar mechanism's plane (None: spatial), from the z axis of a joint
    frame whose axis is the normal (an R joint's), at the first recorded sample."""
    if not linkage.planar or not q.shape[0]:
        return None
    c = next((c for c in linkage.tables.couplings if JOINT_TYPES[c.type].planar_axis == "normal"), None)
    if c is None:
        return None
    T = sp.lambdify([list(definition.coordinates), list(definition.parameter_symbols)],
                    linkage.frames.joint_frame(c.i, c.k), "numpy")
    z = np.asarray(T(list(q[0]), list(par)), dtype=float)[:3, 2]
    return z / np.linalg.norm(z)
