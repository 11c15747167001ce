"""The symbolic half of the joint reactions (:mod:`csim.linkage.reactions`): the expressions
whose numeric functions the reactions evaluate, derived by sympy only where those functions
are not in the cache (:func:`csim.linkage.lambdacache.cached_lambdify`).

Each ``*_terms`` function returns what :func:`~csim.linkage.lambdacache.cached_lambdify`
lambdifies: the argument lists and a flat list of expressions. ``linkage`` is the symbolic
:class:`csim.linkage.model.Linkage`, ``definition`` its :class:`~csim.model.definition.MechanismDefinition`.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from csim.linkage.forces import Geometry, JointCoordinate, build_forces
from csim.linkage.frames import Frames
from csim.linkage.joints import JOINT_TYPES, CutGeometry
from csim.linkage.tables import Coupling


def _skew(w: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def entries(matrices) -> list:
    """The entries of sympy matrices, one flat list (each matrix row by row)."""
    return [e for M in matrices for e in M]


def wrench_terms(joint_type: str) -> tuple[list, list]:
    """The derivatives of a joint type's cut equations with respect to a virtual motion of
    frame jm (:func:`csim.linkage.reactions.wrench_jacobian`): arguments (r_ik, A_ik, r_jm,
    A_jm) and the (6, n_eq) entries row by row."""
    n = len(JOINT_TYPES[joint_type].cut_equations)
    r_ik, r_jm = sp.Matrix(sp.symbols("rik0:3")), sp.Matrix(sp.symbols("rjm0:3"))
    A_ik, A_jm = sp.Matrix(3, 3, sp.symbols("Aik0:9")), sp.Matrix(3, 3, sp.symbols("Ajm0:9"))
    eps = sp.Symbol("eps")
    dr, dth = sp.Matrix(sp.symbols("dr0:3")), sp.Matrix(sp.symbols("dth0:3"))
    moved = CutGeometry(r_ik, r_jm + eps * dr, A_ik, (sp.eye(3) + eps * _skew(dth)) * A_jm)
    columns = []
    for eq in JOINT_TYPES[joint_type].cut_equations:
        rate = sp.expand(sp.diff(eq.expression(moved), eps).subs(eps, 0))  # linear in dr, dth
        columns.append([rate.coeff(s) for s in (*dr, *dth)])
    return [list(r_ik), list(A_ik), list(r_jm), list(A_jm)], [columns[e][k] for k in range(6) for e in range(n)]


def frame_terms(linkage, definition, frames: list[tuple[int, int]]) -> tuple[list, list]:
    """The joint frames (i, k) in ``frames``, each 4 x 4, in (q, parameters)."""
    return ([list(definition.coordinates), list(definition.parameter_symbols)],
            entries(linkage.frames.joint_frame(*f) for f in frames))


def kinematics_terms(linkage, definition, links: list[int]) -> tuple[list, list]:
    """What :func:`csim.linkage.reactions.kinematics` evaluates of each link in ``links``, in
    (q, qd, qdd, parameters): m, I, r_C, a_C, A, omega, alpha (a_C = J qdd + d(J qd)/dq qd,
    alpha = d(omega)/dqd qdd + d(omega)/dq qd), then gravity."""
    from csim.linkage.model import link_angular_velocities

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
    return [q, qd, qdd, list(definition.parameter_symbols)], entries(rows)


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
        The links beyond it (:func:`csim.linkage.topology.subtree`).
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


def element_terms(linkage, definition, raw_forces, coupling: Coupling, below: set[int], driven: list[str],
                  n_loads: int) -> tuple[list, list]:
    """What the force elements and the drives ``driven`` of the tree joint ``coupling`` do on
    the subtree ``below`` it, released (:class:`ReleasedGeometry`), in (q, qd, parameters):
    dV/deps (6), B_eps (6, k) and D_eps (6, d) at eps = 0, each row by row
    (:func:`csim.linkage.reactions.element_terms`).

    Raises
    ------
    RuntimeError
        Where the force elements built on the released geometry are not the model's ``n_loads``.
    """
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
            entries([sp.Matrix(dV), sp.Matrix(6, len(B), lambda i, k: B[k][i]),
                     sp.Matrix(6, len(D), lambda i, k: D[k][i])]))
