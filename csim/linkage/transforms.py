"""Homogeneous transforms: joint frames on a link, joint transforms per type, link to link.

All matrices are 4x4 sympy matrices [[A, r], [0, 1]]: A (3, 3) the rotation (direction
cosines) of the moved frame in the reference frame, r (3,) its origin [m].

- A joint frame on its link: T_ik^(i) = Trans(x, y, z) Rz(phi) Rx(theta) Rz(psi), from
  p = [x, y, z, phi, theta, psi] (z-x'-z'' Euler angles).
- A joint, frame jm relative to frame ik: the transform of its type's record in
  :data:`csim.linkage.joints.JOINT_TYPES` (R: Rz(q); P: Tz(q); ...).
- Link j relative to link i across a coupling: T_j^(i) = T_ik^(i) T_jm^(ik) (T_jm^(j))^-1.
"""
from __future__ import annotations

import sympy as sp
from sympy.simplify.fu import TR8


def _cos_sin(angle: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """cos and sin; of a number without an exact value (cos(3/5)) as floats, so that the
    coefficients of products merge instead of piling up symbolic constants."""
    angle = sp.sympify(angle)
    c, s = sp.cos(angle), sp.sin(angle)
    if angle.is_number:
        c = c.evalf(17) if c.has(sp.cos, sp.sin) else c
        s = s.evalf(17) if s.has(sp.cos, sp.sin) else s
    return c, s


def rot_z(angle: sp.Expr) -> sp.Matrix:
    """Rotation about z by ``angle`` [rad], (4, 4)."""
    c, s = _cos_sin(angle)
    return sp.Matrix([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])


def rot_x(angle: sp.Expr) -> sp.Matrix:
    """Rotation about x by ``angle`` [rad], (4, 4)."""
    c, s = _cos_sin(angle)
    return sp.Matrix([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def translation(x: sp.Expr, y: sp.Expr, z: sp.Expr) -> sp.Matrix:
    """Translation by (x, y, z) [m], (4, 4)."""
    return sp.Matrix([[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]])


def euler_zxz(phi: sp.Expr, theta: sp.Expr, psi: sp.Expr) -> sp.Matrix:
    """Rz(phi) Rx(theta) Rz(psi), (4, 4): the z-x'-z'' Euler angles [rad]."""
    return rot_z(phi) * rot_x(theta) * rot_z(psi)


def frame_transform(p) -> sp.Matrix:
    """T_ik^(i) of a joint frame from p = [x, y, z, phi, theta, psi], (4, 4)."""
    x, y, z, phi, theta, psi = p
    return simplify_matrix(translation(x, y, z) * euler_zxz(phi, theta, psi))


def joint_transform(kind: str, q: list[sp.Expr]) -> sp.Matrix:
    """T_jm^(ik): frame jm relative to frame ik for joint type ``kind`` and variables ``q``.

    The transform of each type is in its record of :data:`csim.linkage.joints.JOINT_TYPES`.

    Parameters
    ----------
    kind : str
        A registered joint type (``"R"``, ``"P"``, ``"C"``, ``"U"``, ``"S"``).
    q : list of sympy expressions
        Its joint variables, as many as the type has (R: angle [rad]; P: translation [m];
        C: angle, translation; U: two angles; S: z-x'-z'' angles).

    Returns
    -------
    sympy Matrix (4, 4)

    Raises
    ------
    UnknownJointType
        ``kind`` is not registered (the message lists the registered types).
    """
    from csim.linkage.joints import JOINT_TYPES  # the registry builds its transforms from this module

    return JOINT_TYPES[kind].transform(q)


def inverse(T: sp.Matrix) -> sp.Matrix:
    """Inverse of a homogeneous transform: [[A^T, -A^T r], [0, 1]]."""
    A, r = T[:3, :3], T[:3, 3]
    out = sp.eye(4)
    out[:3, :3] = A.T
    out[:3, 3] = -A.T * r
    return out


def rotation(T: sp.Matrix) -> sp.Matrix:
    """A, (3, 3)."""
    return T[:3, :3]


def origin(T: sp.Matrix) -> sp.Matrix:
    """r, (3, 1) [m]."""
    return T[:3, 3]


#: Expressions with more terms are only expanded (products to sums would grow them).
MAX_TERMS_TO_CONTRACT = 24
#: ... and so are those with a term of more sine and cosine factors than this.
MAX_FACTORS_TO_CONTRACT = 3


#: Float coefficients below this are round-off of float constants (cos(3/5)), dropped.
CHOP = 1e-14


def _chop(expr: sp.Expr) -> sp.Expr:
    """Drop the terms whose float coefficient is round-off (1e-17 cos(q1))."""
    if not expr.has(sp.Float):
        return expr
    keep = []
    for term in sp.Add.make_args(expr):
        coeff, _ = term.as_coeff_Mul()
        if not (coeff.is_Float and abs(coeff) < CHOP):
            keep.append(term)
    return sp.Add(*keep)


def _trig_factors(term: sp.Expr) -> int:
    """Number of sine and cosine factors of a product (powers counted)."""
    count = 0
    for factor in sp.Mul.make_args(term):
        base, exponent = factor.as_base_exp()
        if isinstance(base, (sp.sin, sp.cos)) and base.args[0].free_symbols:
            count += int(exponent) if exponent.is_Integer else 1
    return count


def simplify_entry(expr: sp.Expr) -> sp.Expr:
    """Expand, then turn products of sines and cosines into sines and cosines of sums
    (cos a cos b - sin a sin b -> cos(a + b)) where that makes the expression shorter.

    Exact and cheap: planar chains collapse to the paper's cos(q1 + q2 + q3) form, spatial
    ones keep the shorter expanded product form.
    """
    expr = _chop(sp.expand(expr))
    terms = sp.Add.make_args(expr)
    if not expr.has(sp.sin, sp.cos) or len(terms) > MAX_TERMS_TO_CONTRACT \
            or max(_trig_factors(term) for term in terms) > MAX_FACTORS_TO_CONTRACT:
        return expr
    contracted = sp.expand(TR8(expr))
    return contracted if sp.count_ops(contracted) <= sp.count_ops(expr) else expr


def simplify_matrix(T: sp.Matrix) -> sp.Matrix:
    """:func:`simplify_entry` on every entry."""
    return T.applyfunc(simplify_entry)


def link_to_link(T_ik: sp.Matrix, T_joint: sp.Matrix, T_jm: sp.Matrix) -> sp.Matrix:
    """T_j^(i) = T_ik^(i) T_jm^(ik) (T_jm^(j))^-1, (4, 4)."""
    return simplify_matrix(T_ik * T_joint * inverse(T_jm))
