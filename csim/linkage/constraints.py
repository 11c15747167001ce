"""Cut-joint constraint equations, the removal of trivial and dependent ones, DOF counts.

A cut joint (i, k)-(j, m) contributes the equations of its type's record in
:data:`csim.linkage.joints.JOINT_TYPES` (the link-coupling paper's table: R gives r_ik = r_jm and
z_ik = z_jm, ..., S gives r_ik = r_jm), each with one reaction unknown, its multiplier.

Of these, equations that vanish identically (every out-of-plane one of a planar mechanism)
are removed: symbolically when sympy reduces them to 0, otherwise when they vanish at
random configurations with the case's parameter values. Of the rest, an independent set is
kept: the Jacobian's rank is taken at generic assembled configurations (the given one,
moved along the mechanism's free motion and projected back), and the rows are chosen by
QR with column pivoting of Phi_q^T there. An overconstrained mechanism (Bricard's 6R
linkage) loses its dependent rows this way.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from csim.errors import CaseError
from csim.linkage.frames import Frames
from csim.linkage.joints import JOINT_TYPES, CutGeometry
from csim.linkage.kinematics import residual_report, solve_positions
from csim.linkage.plan import DEPENDENT, KEPT, ZERO, EquationRecord
from csim.linkage.tables import Coupling, Tables
from csim.linkage.topology import JointVariable
from csim.linkage.transforms import simplify_entry
from csim.linkage.watch import numeric_constraints
from csim.model.deferred import DeferredFields


@dataclass
class Equation(DeferredFields):
    """One cut-joint equation (its expression pickled apart, unpickled where first read:
    :class:`csim.model.deferred.DeferredFields`).

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

    DEFERRED = ("expression",)

    @property
    def label(self) -> str:
        name = self.coupling.name or str(self.coupling.number)
        return f"joint {name} {self.component}"

    @property
    def unit(self) -> str:
        """``"m"`` for a component of the distance r_jm - r_ik, ``"1"`` for one between two axes."""
        return "m" if "(r_jm - r_ik)" in self.component else "1"

    def record(self) -> EquationRecord:
        """Its plain data (:class:`csim.linkage.plan.EquationRecord`)."""
        return EquationRecord(self.coupling.number, str(self.coupling.name or self.coupling.number), self.component,
                              self.reaction, self.status, self.unit)


def cut_joint_equations(coupling: Coupling, frames: Frames) -> list[Equation]:
    """The equations of one cut joint, from its type's record (:data:`JOINT_TYPES`),
    symbolic and simplified."""
    geometry = CutGeometry.from_transforms(frames.joint_frame(coupling.i, coupling.k),
                                           frames.joint_frame(coupling.j, coupling.m))
    return [Equation(coupling, eq.component, eq.reaction, simplify_entry(eq.expression(geometry)))
            for eq in JOINT_TYPES[coupling.type].cut_equations]


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


def _numeric(exprs: Sequence[sp.Expr], q_syms: list[sp.Symbol], parameters: dict[sp.Symbol, float]):
    """phi(q) (r,) and phi_q(q) (r, n) as numpy functions at the given parameter values, derived
    here, not filed (:func:`csim.linkage.watch.numeric_constraints`: the constraint watch's are
    filed, :meth:`csim.linkage.plan.LightLinkage.constraint_watch`)."""
    return numeric_constraints(len(exprs), len(q_syms), list(parameters.values()), "",
                               lambda: (exprs, q_syms, list(parameters)))


def _rank(J: np.ndarray) -> int:
    if J.size == 0:
        return 0
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(s > 1e-9 * max(s[0], 1.0)))


def _generic_configurations(phi: Callable, phi_q: Callable, q_start: np.ndarray, rng: np.random.Generator,
                            tol: float, max_iter: int) -> tuple[list[np.ndarray], list[int]]:
    """Assembled configurations near ``q_start``: it, then up to 4 more, each moved along the
    free motion (the null space of Phi_q) and projected back by Newton-Raphson.

    Returns
    -------
    points : list of ndarray (n,)
    ranks : list of int
        The rank of Phi_q at each point.
    """
    n = q_start.size
    points = [q_start]
    J0 = phi_q(q_start)
    if J0.size:
        _, _, vt = np.linalg.svd(J0)
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
    return points, [_rank(phi_q(q)) for q in points]


def free_mobility(phi: Callable, phi_q: Callable, q0: np.ndarray, tol: float, max_iter: int,
                  seed: int = 1) -> int | None:
    """Degrees of freedom found with every joint variable free: Newton-Raphson from ``q0``
    (which cannot fail for holding too many variables), then the number of variables minus
    the generic rank around the assembled point. None when even that does not assemble."""
    sol = solve_positions(phi, phi_q, q0, np.arange(q0.size), tol, max_iter)
    if not sol.converged:
        return None
    _, ranks = _generic_configurations(phi, phi_q, sol.q, np.random.default_rng(seed), tol, max_iter)
    return q0.size - max(ranks)


def _remove_zero(equations: list[Equation], q_syms: list[sp.Symbol], tables: Tables, rng: np.random.Generator):
    """Mark the identically zero equations: symbolically, else numerically at random
    configurations. Returns the others and phi, phi_q of them (numpy functions of q)."""
    n = len(q_syms)
    length = max([1.0] + [abs(v) for v in tables.parameters.values()])
    for eq in equations:
        if eq.expression == 0:
            eq.status = ZERO
    candidates = [e for e in equations if e.status != ZERO]
    phi_all, phi_q_all = _numeric([e.expression for e in candidates], q_syms, tables.values)
    randoms = [rng.uniform(-np.pi, np.pi, n) for _ in range(6)]
    values = np.array([phi_all(q) for q in randoms]) if candidates else np.zeros((6, 0))
    for col, eq in enumerate(candidates):
        if np.max(np.abs(values[:, col])) <= 1e-11 * length:
            eq.status = ZERO
    rows = [i for i, e in enumerate(candidates) if e.status != ZERO]

    def phi(q):
        return phi_all(q)[rows]

    def phi_q(q):
        return phi_q_all(q)[rows]

    return [candidates[i] for i in rows], phi, phi_q


def reduce_equations(equations: list[Equation], variables: list[JointVariable], tables: Tables,
                     start: dict[str, float], fixed: list[str], tol: float = 1e-12, max_iter: int = 50,
                     seed: int = 0, mobility_check: Callable[[int], list[str]] | None = None) -> Reduction:
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
    mobility_check : callable dof -> list of str, optional
        Called before the assembly that holds ``fixed``, with the degrees of freedom found
        with every variable free (:func:`free_mobility`); the problems it returns are
        raised. So "3 drives for 1 degree of freedom" is said instead of an assembly failure.

    Raises
    ------
    CaseError
        ``mobility_check`` found problems, or the mechanism cannot be assembled at the given
        values (the message lists the residual of every equation, by cut joint).
    """
    rng = np.random.default_rng(seed)
    q_syms = [v.symbol for v in variables]
    # 1. identically zero: symbolically, else numerically at random configurations
    live, phi, phi_q = _remove_zero(equations, q_syms, tables, rng)
    names = [v.name for v in variables]
    q0 = np.array([float(start.get(name, 0.0)) for name in names])
    if mobility_check is not None:
        dof = free_mobility(phi, phi_q, q0, tol, max_iter, seed + 1)
        problems = [] if dof is None else mobility_check(dof)
        if problems:
            raise CaseError(problems)
    free = np.array([i for i, name in enumerate(names) if name not in fixed], dtype=int)
    # 2. assemble at the given values
    sol = solve_positions(phi, phi_q, q0, free, tol, max_iter)
    if not sol.converged:
        held = ", ".join(f"{x} = {start.get(x, 0.0):.6g}" for x in fixed) or "none"
        raise CaseError([
            f"mechanism: cannot be assembled at the given values (Newton-Raphson on the cut-joint equations "
            f"did not converge in {max_iter} iterations; held fixed: {held}; start: initial.guess or 0); "
            f"residuals: {residual_report([e.label for e in live], sol.residual)}; expected dimensions that "
            f"close every loop, or an initial.guess near an assembled configuration"])
    q_start = sol.q
    # 3. generic configurations: move along the free motion, project back
    points, ranks = _generic_configurations(phi, phi_q, q_start, rng, tol, max_iter)
    generic = max(ranks)
    best = points[int(np.argmax(ranks))]
    rank_start = ranks[0]
    notes = []
    # 4. an independent subset, by pivoted QR of Phi_q^T at a generic point
    if live:
        import scipy.linalg  # here: a cached linkage never gets this far (0.2 s of a warm run)

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


@dataclass(frozen=True)
class Plane:
    """The plane of motion of a planar mechanism.

    Attributes
    ----------
    normal : ndarray (3,)
        Its unit normal in the fixed frame.
    link_normals : dict link number -> ndarray (3,)
        The same normal in each link's axes (constant: the links turn about it).
    """

    normal: np.ndarray
    link_normals: dict[int, np.ndarray]


def plane_of_motion(tables: Tables, frames: Frames, variables: list[JointVariable], seed: int = 1) -> Plane | None:
    """The plane of a planar mechanism, or None for a spatial one.

    Planar: every joint type has a :attr:`~csim.linkage.joints.JointType.planar_axis`, the
    z axes of the ``"normal"`` ones (R) are all parallel, and those of the ``"in_plane"``
    ones (P) normal to them. Checked numerically at a random configuration with the case's
    parameter values.
    """
    kinds = [JOINT_TYPES[c.type].planar_axis for c in tables.couplings]
    if None in kinds:
        return None
    rng = np.random.default_rng(seed)
    subs = tables.values
    subs.update({v.symbol: float(x) for v, x in zip(variables, rng.uniform(-np.pi, np.pi, len(variables)))})
    numeric = {n: np.array(T.evalf(subs=subs), dtype=float) for n, T in frames.links.items()}
    axes: dict[str, list] = {"normal": [], "in_plane": []}
    for c, kind in zip(tables.couplings, kinds):
        for link, index in ((c.i, c.k), (c.j, c.m)):
            local = np.array(frames.local[(link, index)].evalf(subs=subs), dtype=float)
            axes[kind].append((numeric[link] @ local)[:3, 2])
    if not axes["normal"]:
        return None
    normal = axes["normal"][0]
    parallel = all(np.linalg.norm(np.cross(normal, z)) < 1e-9 for z in axes["normal"])
    normal_slides = all(abs(np.dot(normal, z)) < 1e-9 for z in axes["in_plane"])
    if not (parallel and normal_slides):
        return None
    return Plane(normal, {n: T[:3, :3].T @ normal for n, T in numeric.items()})
