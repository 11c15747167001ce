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

import numpy as np
import sympy as sp

from csim.linkage.constraints import KEPT, ZERO
from csim.linkage.joints import JOINT_TYPES, CutGeometry
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
    J = sp.Matrix(columns).T if columns else sp.zeros(6, 0)
    f = sp.lambdify([list(r_ik), list(A_ik), list(r_jm), list(A_jm)], J, "numpy")
    n = len(columns)

    def jacobian(ri, Ai, rj, Aj):
        return np.asarray(f(list(ri), list(np.ravel(Ai)), list(rj), list(np.ravel(Aj))), dtype=float).reshape(6, n)

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
    q_syms, p_syms = list(definition.coordinates), list(definition.parameter_symbols)
    cuts = linkage.topology.cut_joints
    mats = [m for c in cuts for m in (linkage.frames.joint_frame(c.i, c.k), linkage.frames.joint_frame(c.j, c.m))]
    f = sp.lambdify([q_syms, p_syms], mats, "numpy", cse=True)

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
        Multipliers of the kept equations (NaN where a sample could not be evaluated).

    Returns
    -------
    list of JointReaction
        One per cut joint, in the order of ``linkage.topology.cut_joints``.
    """
    kept = linkage.reduction.kept
    column = {id(eq): n for n, eq in enumerate(kept)}
    frames = _frame_functions(linkage, definition)
    cuts = linkage.topology.cut_joints
    equations = {c.number: [eq for eq in linkage.reduction.equations if eq.coupling.number == c.number]
                 for c in cuts}
    N = q.shape[0]
    values = {c.number: np.full((4, N, 3), np.nan) for c in cuts}  # F, M global; F, M in frame ik
    for s in range(N):
        if not np.all(np.isfinite(q[s])):
            continue
        at = frames(q[s], par)
        for c in cuts:
            T_ik, T_jm = at[c.number]
            lam_eq = np.array([lam[s, column[id(eq)]] if id(eq) in column else 0.0 for eq in equations[c.number]])
            wrench = -wrench_jacobian(c.type)(T_ik[:3, 3], T_ik[:3, :3], T_jm[:3, 3], T_jm[:3, :3]) @ lam_eq
            A = T_ik[:3, :3]
            values[c.number][:, s] = wrench[:3], wrench[3:], A.T @ wrench[:3], A.T @ wrench[3:]
    out = []
    for c in cuts:
        name = str(c.name or c.number)
        label = f"joint {name} ({c.type}, {linkage.tables.link_label(c.i)} on {linkage.tables.link_label(c.j)})"
        v = values[c.number]
        out.append(JointReaction(name, label, v[0], v[1], v[2], v[3], _removed(equations[c.number])))
    return out
