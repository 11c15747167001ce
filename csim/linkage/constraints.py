"""Cut-joint constraint equations, the removal of trivial and dependent ones, DOF counts.

With r the global position of a joint-frame origin, x, y, z its global unit axes and
d = r_jm - r_ik, a cut joint (i, k)-(j, m) contributes (the brief's table):

======  ===============================================  =====================
joint   equations                                        reactions
======  ===============================================  =====================
R       d = 0 (global x, y, z); x_ik.z_jm = y_ik.z_jm = 0  force (3), moment m_x, m_y
P       x_ik.d = y_ik.d = 0; y_ik.z_jm = x_ik.z_jm =      force f_x, f_y, moment (3)
        x_ik.y_jm = 0 (A_ik = A_jm)
C       x_ik.d = y_ik.d = 0; y_ik.z_jm = x_ik.z_jm = 0    force f_x, f_y, moment m_x, m_y
U       d = 0; z_ik.z_jm = 0                             force (3), moment along z_ik x z_jm
S       d = 0                                            force (3)
======  ===============================================  =====================

z_ik = z_jm is written as its two independent components in frame ik (x_ik.z_jm and
y_ik.z_jm vanish), A_ik = A_jm as three; each holds near the assembled branch (z_jm = z_ik,
not -z_ik). Every equation has one reaction unknown, its multiplier.

Of these, equations that vanish identically (every out-of-plane one of a planar mechanism)
are removed: symbolically when sympy reduces them to 0, otherwise when they vanish at
random configurations with the case's parameter values. Of the rest, an independent set is
kept: the Jacobian's rank is taken at generic assembled configurations (the given one,
moved along the mechanism's free motion and projected back), and the rows are chosen by
QR with column pivoting of Phi_q^T there. An overconstrained mechanism (Bricard's 6R
linkage) loses its dependent rows this way.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import sympy as sp

from csim.errors import CaseError
from csim.linkage.frames import Frames
from csim.linkage.kinematics import residual_report, solve_positions
from csim.linkage.tables import Coupling, Tables
from csim.linkage.topology import JointVariable
from csim.linkage.transforms import simplify_entry

#: Reaction unknowns of each cut-joint type, in the joint frame ik (the brief's table).
REACTIONS = {
    "R": ["f_x", "f_y", "f_z", "m_x", "m_y"],
    "P": ["f_x", "f_y", "m_x", "m_y", "m_z"],
    "C": ["f_x", "f_y", "m_x", "m_y"],
    "U": ["f_x", "f_y", "f_z", "m"],
    "S": ["f_x", "f_y", "f_z"],
}

KEPT, ZERO, DEPENDENT = "kept", "identically zero", "dependent"


@dataclass
class Equation:
    """One cut-joint equation.

    Attributes
    ----------
    coupling : Coupling
    component : str
        Which component, e.g. ``"x: (r_jm - r_ik).e_x"`` or ``"x_ik . z_jm"``.
    reaction : str
        Its reaction unknown (the multiplier), e.g. ``"force along global x"``.
    expression : sympy expression
        Phi_i(q) [m for positions, 1 for directions].
    status : {"kept", "identically zero", "dependent"}
    """

    coupling: Coupling
    component: str
    reaction: str
    expression: sp.Expr
    status: str = KEPT

    @property
    def label(self) -> str:
        name = self.coupling.name or str(self.coupling.number)
        return f"joint {name} {self.component}"


def cut_joint_equations(coupling: Coupling, frames: Frames) -> list[Equation]:
    """The brief's equations of one cut joint, symbolic and simplified."""
    T_ik = frames.joint_frame(coupling.i, coupling.k)
    T_jm = frames.joint_frame(coupling.j, coupling.m)
    r_ik, r_jm = T_ik[:3, 3], T_jm[:3, 3]
    x_ik, y_ik, z_ik = (T_ik[:3, a] for a in range(3))
    y_jm, z_jm = T_jm[:3, 1], T_jm[:3, 2]
    d = r_jm - r_ik
    rows: list[tuple[str, str, sp.Expr]] = []
    if coupling.type in ("R", "U", "S"):
        rows += [(f"{a}: (r_jm - r_ik).e_{a}", f"force along global {a}", d[n]) for n, a in enumerate("xyz")]
    else:
        rows += [("x_ik . (r_jm - r_ik)", "force f_x along x_ik", x_ik.dot(d)),
                 ("y_ik . (r_jm - r_ik)", "force f_y along y_ik", y_ik.dot(d))]
    if coupling.type in ("R", "P", "C"):
        rows += [("y_ik . z_jm", "moment m_x about x_ik", y_ik.dot(z_jm)),
                 ("x_ik . z_jm", "moment m_y about y_ik", x_ik.dot(z_jm))]
    if coupling.type == "P":
        rows.append(("x_ik . y_jm", "moment m_z about z_ik", x_ik.dot(y_jm)))
    if coupling.type == "U":
        rows.append(("z_ik . z_jm", "moment m along z_ik x z_jm", z_ik.dot(z_jm)))
    return [Equation(coupling, comp, reaction, simplify_entry(expr)) for comp, reaction, expr in rows]


@dataclass
class Reduction:
    """The equations after removal, and what the rank says.

    Attributes
    ----------
    equations : list of Equation
        All generated equations, each with its status.
    generic_rank : int
        Rank of the Jacobian of the non-trivial equations at generic assembled configurations.
    rank_at_start : int
        Its rank at the given configuration (lower: a singular position).
    q_start : ndarray (n,)
        The assembled given configuration.
    samples : int
        Number of generic configurations the rank was taken at.
    notes : list of str
    """

    equations: list[Equation]
    generic_rank: int
    rank_at_start: int
    q_start: np.ndarray
    samples: int
    notes: list[str] = field(default_factory=list)

    @property
    def kept(self) -> list[Equation]:
        return [e for e in self.equations if e.status == KEPT]


def _numeric(exprs: list[sp.Expr], q_syms: list[sp.Symbol], parameters: dict[sp.Symbol, float]):
    """phi(q) (r,) and phi_q(q) (r, n) as numpy functions at the given parameter values."""
    r, n = len(exprs), len(q_syms)
    vec = sp.Matrix(exprs) if exprs else sp.zeros(0, 1)
    jac = vec.jacobian(q_syms) if exprs else sp.zeros(0, n)
    p_syms, p_vals = list(parameters), list(parameters.values())
    f = sp.lambdify([q_syms, p_syms], vec, "numpy", cse=True)
    g = sp.lambdify([q_syms, p_syms], jac, "numpy", cse=True)

    def phi(q):
        return np.asarray(f(list(q), p_vals), dtype=float).reshape(r)

    def phi_q(q):
        return np.asarray(g(list(q), p_vals), dtype=float).reshape(r, n)

    return phi, phi_q


def _rank(J: np.ndarray) -> int:
    if J.size == 0:
        return 0
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(s > 1e-9 * max(s[0], 1.0)))


def reduce_equations(equations: list[Equation], variables: list[JointVariable], tables: Tables,
                     start: dict[str, float], fixed: list[str], tol: float = 1e-12, max_iter: int = 50,
                     seed: int = 0) -> Reduction:
    """Remove identically satisfied and dependent equations (see the module docstring).

    Parameters
    ----------
    equations : list of Equation
    variables : list of JointVariable
    tables : Tables
        For the parameter values.
    start : dict name -> value
        Start configuration of the assembly (missing variables start at 0).
    fixed : list of str
        Variables held at their start values during the assembly (the drives, or the
        given independent coordinates).
    tol, max_iter : Newton settings of the assembly.
    seed : int
        Seed of the random configurations (the result does not depend on it, except in
        degenerate cases).

    Raises
    ------
    CaseError
        The mechanism cannot be assembled at the given values (the message lists the
        residual of every equation, by cut joint).
    """
    rng = np.random.default_rng(seed)
    q_syms = [v.symbol for v in variables]
    n = len(q_syms)
    subs = {tables.symbols[k]: v for k, v in tables.parameters.items()}
    length = max([1.0] + [abs(v) for v in tables.parameters.values()])
    # 1. identically zero: symbolically, else numerically at random configurations
    for eq in equations:
        if eq.expression == 0:
            eq.status = ZERO
    candidates = [e for e in equations if e.status != ZERO]
    phi_all, phi_q_all = _numeric([e.expression for e in candidates], q_syms, subs)
    randoms = [rng.uniform(-np.pi, np.pi, n) for _ in range(6)]
    values = np.array([phi_all(q) for q in randoms]) if candidates else np.zeros((6, 0))
    for col, eq in enumerate(candidates):
        if np.max(np.abs(values[:, col])) <= 1e-11 * length:
            eq.status = ZERO
    rows = [i for i, e in enumerate(candidates) if e.status != ZERO]
    live = [candidates[i] for i in rows]
    labels = [e.label for e in live]

    def phi(q):
        return phi_all(q)[rows]

    def phi_q(q):
        return phi_q_all(q)[rows]

    names = [v.name for v in variables]
    q0 = np.array([float(start.get(name, 0.0)) for name in names])
    free = np.array([i for i, name in enumerate(names) if name not in fixed], dtype=int)
    # 2. assemble at the given values
    sol = solve_positions(phi, phi_q, q0, free, tol, max_iter)
    if not sol.converged:
        held = ", ".join(f"{x} = {start.get(x, 0.0):.6g}" for x in fixed) or "none"
        raise CaseError([
            f"mechanism: cannot be assembled at the given values (Newton-Raphson on the cut-joint equations "
            f"did not converge in {max_iter} iterations; held fixed: {held}; start: initial.guess or 0); "
            f"residuals: {residual_report(labels, sol.residual)}; expected dimensions that close every loop, "
            f"or an initial.guess near an assembled configuration"])
    q_start = sol.q
    # 3. generic configurations: move along the free motion, project back
    points = [q_start]
    J0 = phi_q(q_start)
    if J0.size:
        _, s, vt = np.linalg.svd(J0)
        null = vt[_rank(J0):].T
    else:
        null = np.eye(n)
    all_free = np.arange(n)
    for _ in range(8):
        if null.shape[1] == 0 or len(points) >= 5:
            break
        for scale in (0.3, 0.1, 0.03):
            trial = q_start + scale * (null @ rng.standard_normal(null.shape[1]))
            moved = solve_positions(phi, phi_q, trial, all_free, tol, max_iter)
            if moved.converged:
                points.append(moved.q)
                break
    ranks = [_rank(phi_q(q)) for q in points]
    generic = max(ranks) if ranks else 0
    best = points[int(np.argmax(ranks))] if points else q_start
    rank_start = ranks[0] if ranks else 0
    notes = []
    # 4. an independent subset, by pivoted QR of Phi_q^T at a generic point
    if live:
        Jb = phi_q(best)
        _, _, piv = scipy.linalg.qr(Jb.T, pivoting=True, mode="economic")
        chosen = set(piv[:generic].tolist())
        for idx, eq in enumerate(live):
            if idx not in chosen:
                eq.status = DEPENDENT
    if rank_start < generic:
        notes.append(f"the Jacobian's rank drops from {generic} to {rank_start} at the given configuration: "
                     f"a singular position")
    return Reduction(equations=equations, generic_rank=generic, rank_at_start=rank_start, q_start=q_start,
                     samples=len(points), notes=notes)


def is_planar(tables: Tables, frames: Frames, variables: list[JointVariable], seed: int = 1) -> bool:
    """True when every joint is R or P and all R axes stay parallel (P axes normal to them).

    Checked numerically at a random configuration with the case's parameter values.
    """
    if any(c.type not in ("R", "P") for c in tables.couplings):
        return False
    rng = np.random.default_rng(seed)
    subs = {tables.symbols[k]: v for k, v in tables.parameters.items()}
    subs.update({v.symbol: float(x) for v, x in zip(variables, rng.uniform(-np.pi, np.pi, len(variables)))})
    numeric = {n: np.array(T.evalf(subs=subs), dtype=float) for n, T in frames.links.items()}
    axes: dict[str, list] = {}
    for c in tables.couplings:
        for link, index in ((c.i, c.k), (c.j, c.m)):
            local = np.array(frames.local[(link, index)].evalf(subs=subs), dtype=float)
            axes.setdefault(c.type, []).append((numeric[link] @ local)[:3, 2])
    rotations = axes.get("R", [])
    if not rotations:
        return False
    normal = rotations[0]
    parallel = all(np.linalg.norm(np.cross(normal, z)) < 1e-9 for z in rotations)
    normal_slides = all(abs(np.dot(normal, z)) < 1e-9 for z in axes.get("P", []))
    return parallel and normal_slides
