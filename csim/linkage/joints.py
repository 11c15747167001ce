"""Joint types of a link-coupling description: one record per type, in one registry.

Everything csim knows about a joint type lives in its :class:`JointType` record in
:data:`JOINT_TYPES`: the type letter used in the links table, its joint variables (names,
units, meanings), the joint transform T_jm^(ik) (frame jm relative to frame ik), the
angular velocity of frame jm relative to frame ik, the equations and reaction unknowns of
the joint when it is cut, the preference for cutting it, and how it fits a planar
mechanism. The parser, the topology, the transforms, the constraints, the energies and
``csim describe`` all read this registry, so a new joint type is one new record
(:func:`register_joint_type`).

The five joint types (docs/link-coupling.md), with q1, q2, q3 the joint
variables:

====  ===========  =======================  ================================================
type  variables    T_jm^(ik)                cut-joint equations (d = r_jm - r_ik)
====  ===========  =======================  ================================================
R     q [rad]      Rz(q)                    d = 0; x_ik.z_jm = y_ik.z_jm = 0
P     s [m]        Tz(s)                    x_ik.d = y_ik.d = 0; y_ik.z_jm = x_ik.z_jm =
                                            x_ik.y_jm = 0
C     q, s         Rz(q) Tz(s)              x_ik.d = y_ik.d = 0; y_ik.z_jm = x_ik.z_jm = 0
U     q1, q2       Rz(q1) Rx(-pi/2) Rz(q2)  d = 0; z_ik.z_jm = 0
S     q1, q2, q3   Rz(q1) Rx(q2) Rz(q3)     d = 0
====  ===========  =======================  ================================================
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import sympy as sp

from csim.linkage.transforms import euler_zxz, rot_x, rot_z, simplify_matrix, translation

#: How a joint's z axis lies in a planar mechanism (:attr:`JointType.planar_axis`).
PLANAR_AXES = {
    "normal": "the joint's z axis is the normal of the plane of motion (a rotation in the plane)",
    "in_plane": "the joint's z axis lies in the plane of motion (a translation in the plane)",
}


@dataclass(frozen=True)
class VariableSpec:
    """One joint variable of a joint type.

    Attributes
    ----------
    template : str
        Name of the variable of a coupling named J, with ``{J}`` for the name
        (``"q_{J}"``, ``"s_{J}"``, ``"q_{J}_2"``). Unnamed couplings get ``q1, q2, ...``.
    unit : str
        ``"rad"`` or ``"m"``.
    meaning : str
        What it measures, e.g. ``"rotation about z_ik"``.
    """

    template: str
    unit: str
    meaning: str


@dataclass(frozen=True)
class CutGeometry:
    """The two joint frames of a cut joint, in the fixed frame.

    Attributes
    ----------
    r_ik, r_jm : sympy Matrix (3, 1)
        Origins [m].
    A_ik, A_jm : sympy Matrix (3, 3)
        Rotations; their columns are the unit axes x, y, z.
    """

    r_ik: sp.Matrix
    r_jm: sp.Matrix
    A_ik: sp.Matrix
    A_jm: sp.Matrix

    @classmethod
    def from_transforms(cls, T_ik: sp.Matrix, T_jm: sp.Matrix) -> CutGeometry:
        """From the global transforms T_ik^(0), T_jm^(0), each (4, 4)."""
        return cls(T_ik[:3, 3], T_jm[:3, 3], T_ik[:3, :3], T_jm[:3, :3])

    @property
    def d(self) -> sp.Matrix:
        """r_jm - r_ik, (3, 1) [m]."""
        return self.r_jm - self.r_ik

    def axis_ik(self, a: int) -> sp.Matrix:
        """Unit axis ``a`` (0: x, 1: y, 2: z) of frame ik, (3, 1)."""
        return self.A_ik[:, a]

    def axis_jm(self, a: int) -> sp.Matrix:
        """Unit axis ``a`` (0: x, 1: y, 2: z) of frame jm, (3, 1)."""
        return self.A_jm[:, a]


@dataclass(frozen=True)
class CutEquation:
    """One constraint equation of a cut joint, with its reaction unknown.

    Attributes
    ----------
    component : str
        Which component, e.g. ``"x_ik . z_jm"``.
    reaction : str
        The reaction it carries (its multiplier), e.g. ``"moment m_x about x_ik"``.
    unknown : str
        The reaction unknown's short name in the joint frame ik, e.g. ``"m_x"``.
    expression : callable CutGeometry -> sympy expression
        Phi_i [m for positions, 1 for directions].
    """

    component: str
    reaction: str
    unknown: str
    expression: Callable[[CutGeometry], sp.Expr]


def _dot(a: sp.Matrix, b: sp.Matrix) -> sp.Expr:
    return a.dot(b)


#: r_ik = r_jm, in global components: the reaction force (3).
COINCIDENT_ORIGINS = tuple(
    CutEquation(f"{a}: (r_jm - r_ik).e_{a}", f"force along global {a}", f"f_{a}", lambda g, n=n: g.d[n])
    for n, a in enumerate("xyz"))
#: r_jm on the z axis of frame ik (x_ik.d = y_ik.d = 0): force normal to the axis.
ON_AXIS = (
    CutEquation("x_ik . (r_jm - r_ik)", "force f_x along x_ik", "f_x", lambda g: _dot(g.axis_ik(0), g.d)),
    CutEquation("y_ik . (r_jm - r_ik)", "force f_y along y_ik", "f_y", lambda g: _dot(g.axis_ik(1), g.d)),
)
#: z_ik = z_jm, as its two independent components in frame ik (near z_jm = z_ik, not -z_ik).
PARALLEL_AXES = (
    CutEquation("y_ik . z_jm", "moment m_x about x_ik", "m_x", lambda g: _dot(g.axis_ik(1), g.axis_jm(2))),
    CutEquation("x_ik . z_jm", "moment m_y about y_ik", "m_y", lambda g: _dot(g.axis_ik(0), g.axis_jm(2))),
)
#: With z_ik = z_jm, A_ik = A_jm needs the third component, no twist about z.
NO_TWIST = (
    CutEquation("x_ik . y_jm", "moment m_z about z_ik", "m_z", lambda g: _dot(g.axis_ik(0), g.axis_jm(1))),
)
#: z_ik . z_jm = 0: the cross of a universal joint.
PERPENDICULAR_AXES = (
    CutEquation("z_ik . z_jm", "moment m along z_ik x z_jm", "m", lambda g: _dot(g.axis_ik(2), g.axis_jm(2))),
)


@dataclass(frozen=True)
class JointType:
    """Everything about one joint type (see the module docstring).

    Attributes
    ----------
    name : str
        The type letter of the links table (``"R"``).
    title : str
        ``"revolute"``.
    variables : tuple of VariableSpec
        Its joint variables, in the order of the transform's arguments.
    transform : callable list of sympy expressions -> sympy Matrix (4, 4)
        T_jm^(ik)(q): frame jm relative to frame ik.
    angular_velocity : callable (q, qd) -> sympy Matrix (3, 1)
        Angular velocity of frame jm relative to frame ik, in frame ik axes [rad/s], from
        the joint variables q and their rates qd (lists, one entry per variable).
    cut_equations : tuple of CutEquation
        The equations (and reaction unknowns) of the joint when it is cut.
    cut_preference : int
        Higher is cut first: the tree takes the low ones (the paper cuts U, S and C).
    planar_axis : {"normal", "in_plane"} or None
        How its z axis lies in a planar mechanism (:data:`PLANAR_AXES`); None: a mechanism
        with this joint is spatial.
    placement : str
        The link-coupling paper's rule for placing its joint frame on a link.
    measure : callable (CutGeometry, simplify) -> tuple of sympy expressions, or None
        The joint variables measured from the two frames of the joint when it is cut (for
        force elements on a cut joint, :mod:`csim.linkage.forces`): the inverse of
        ``transform``, exact where the cut equations hold; ``simplify`` is applied to each
        scalar product of the frames' axes. None: elements cannot act on it when cut.
    """

    name: str
    title: str
    variables: tuple[VariableSpec, ...]
    transform: Callable[[list], sp.Matrix]
    angular_velocity: Callable[[list, list], sp.Matrix]
    cut_equations: tuple[CutEquation, ...]
    cut_preference: int
    planar_axis: str | None
    placement: str
    measure: Callable[[CutGeometry, Callable], tuple] | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isalpha():
            raise ValueError(f"joint type name {self.name!r}: expected letters, e.g. 'R'")
        if self.planar_axis is not None and self.planar_axis not in PLANAR_AXES:
            raise ValueError(f"joint type {self.name}: planar_axis {self.planar_axis!r}; expected None or one of "
                             f"{', '.join(PLANAR_AXES)}")
        names = self.variable_names("J")
        if any("{J}" not in v.template for v in self.variables) or len(set(names)) != len(names):
            raise ValueError(f"joint type {self.name}: variable templates {[v.template for v in self.variables]}; "
                             f"expected distinct names, each with {{J}} for the coupling's name")

    @property
    def freedoms(self) -> int:
        """Number of joint variables (degrees of freedom of the joint)."""
        return len(self.variables)

    @property
    def reactions(self) -> list[str]:
        """Reaction unknowns of the cut joint, one per equation, in the joint frame ik."""
        return [e.unknown for e in self.cut_equations]

    def variable_names(self, coupling: str) -> list[str]:
        """Names of the joint variables of a coupling named ``coupling``."""
        return [v.template.format(J=coupling) for v in self.variables]


class UnknownJointType(KeyError, ValueError):
    """A joint type name that is not in the registry; the message lists the valid names."""

    def __str__(self) -> str:
        return str(self.args[0])


class JointTypeRegistry(dict):
    """Joint types by name; looking up an unknown name raises :class:`UnknownJointType`."""

    def __missing__(self, name):
        raise UnknownJointType(f"unknown joint type {name!r}; expected one of {self.names()}")

    def names(self) -> str:
        """The valid names, ``"R, P, C, U, S"``."""
        return ", ".join(self)


def _revolute_rate(q, qd):
    return qd[0] * sp.Matrix([0, 0, 1])


def _universal_rate(q, qd):
    ez = sp.Matrix([0, 0, 1])
    return qd[0] * ez + qd[1] * ((rot_z(q[0]) * rot_x(-sp.pi / 2))[:3, :3] * ez)


def _spherical_rate(q, qd):
    ez, ex = sp.Matrix([0, 0, 1]), sp.Matrix([1, 0, 0])
    return qd[0] * ez + qd[1] * (rot_z(q[0])[:3, :3] * ex) + qd[2] * ((rot_z(q[0]) * rot_x(q[1]))[:3, :3] * ez)


def _relative(g: CutGeometry, simplify: Callable) -> Callable[[int, int], sp.Expr]:
    """(a, b) -> entry (a, b) of A_ik^T A_jm, axis a of frame ik . axis b of frame jm (simplified)."""
    return lambda a, b: simplify(_dot(g.axis_ik(a), g.axis_jm(b)))


def _measure_angle(g: CutGeometry, simplify: Callable) -> sp.Expr:
    """The rotation q of frame jm about z_ik, x_jm = Rz(q) x_ik: atan2(z_ik . (x_ik x x_jm), x_ik . x_jm)."""
    return sp.atan2(simplify(g.axis_ik(2).dot(g.axis_ik(0).cross(g.axis_jm(0)))), simplify(_dot(g.axis_ik(0),
                                                                                                  g.axis_jm(0))))


def _measure_slide(g: CutGeometry, simplify: Callable) -> sp.Expr:
    """The translation s of frame jm along z_ik: z_ik . (r_jm - r_ik)."""
    return simplify(_dot(g.axis_ik(2), g.d))


def _measure_universal(g: CutGeometry, simplify: Callable) -> tuple:
    """q1, q2 of R = A_ik^T A_jm = Rz(q1) Rx(-pi/2) Rz(q2): its third column is
    (-sin q1, cos q1, 0), its third row (-sin q2, -cos q2, 0)."""
    R = _relative(g, simplify)
    return sp.atan2(-R(0, 2), R(1, 2)), sp.atan2(-R(2, 0), -R(2, 1))


def _measure_spherical(g: CutGeometry, simplify: Callable) -> tuple:
    """The z-x-z Euler angles of R = A_ik^T A_jm = Rz(q1) Rx(q2) Rz(q3): third column
    (sin q1 sin q2, -cos q1 sin q2, cos q2), third row (sin q2 sin q3, sin q2 cos q3, cos q2);
    q2 in [0, pi] (q1 and q3 are undefined where q2 = 0 or pi, gimbal lock)."""
    R = _relative(g, simplify)
    return (sp.atan2(R(0, 2), -R(1, 2)), sp.atan2(sp.sqrt(R(0, 2) ** 2 + R(1, 2) ** 2), R(2, 2)),
            sp.atan2(R(2, 0), R(2, 1)))


_ROTATION = VariableSpec("q_{J}", "rad", "rotation about z_ik")
_TRANSLATION = VariableSpec("s_{J}", "m", "translation along z_ik")

JOINT_TYPES = JointTypeRegistry()


def register_joint_type(joint: JointType, replace: bool = False) -> JointType:
    """Add ``joint`` to :data:`JOINT_TYPES` (``replace``: over an existing one of its name)."""
    if joint.name in JOINT_TYPES and not replace:
        raise ValueError(f"joint type {joint.name!r} is already registered ({JOINT_TYPES[joint.name].title})")
    JOINT_TYPES[joint.name] = joint
    return joint


register_joint_type(JointType(
    "R", "revolute", (_ROTATION,), lambda q: rot_z(q[0]), _revolute_rate,
    COINCIDENT_ORIGINS + PARALLEL_AXES, cut_preference=0, planar_axis="normal",
    placement="origin at the coupling point, z along the rotation axis",
    measure=lambda g, simplify: (_measure_angle(g, simplify),)))
register_joint_type(JointType(
    "P", "prismatic", (_TRANSLATION,), lambda q: translation(0, 0, q[0]), lambda q, qd: sp.zeros(3, 1),
    ON_AXIS + PARALLEL_AXES + NO_TWIST, cut_preference=0, planar_axis="in_plane",
    placement="origin anywhere on the sliding line, z along the sliding direction",
    measure=lambda g, simplify: (_measure_slide(g, simplify),)))
register_joint_type(JointType(
    "C", "cylindrical", (_ROTATION, _TRANSLATION), lambda q: rot_z(q[0]) * translation(0, 0, q[1]),
    _revolute_rate, ON_AXIS + PARALLEL_AXES, cut_preference=1, planar_axis=None,
    placement="origin anywhere on the axis, z along the axis",
    measure=lambda g, simplify: (_measure_angle(g, simplify), _measure_slide(g, simplify))))
register_joint_type(JointType(
    "U", "universal", (VariableSpec("q_{J}_1", "rad", "rotation about z_ik"),
                       VariableSpec("q_{J}_2", "rad", "rotation about z_jm")),
    lambda q: simplify_matrix(rot_z(q[0]) * rot_x(-sp.pi / 2) * rot_z(q[1])), _universal_rate,
    COINCIDENT_ORIGINS + PERPENDICULAR_AXES, cut_preference=2, planar_axis=None,
    placement="origin at the centre of the cross, z along the revolute axis attached to this link",
    measure=_measure_universal))
register_joint_type(JointType(
    "S", "spherical", (VariableSpec("q_{J}_1", "rad", "Euler angle about z_ik"),
                       VariableSpec("q_{J}_2", "rad", "Euler angle about x'"),
                       VariableSpec("q_{J}_3", "rad", "Euler angle about z_jm")),
    lambda q: euler_zxz(q[0], q[1], q[2]), _spherical_rate,
    COINCIDENT_ORIGINS, cut_preference=3, planar_axis=None,
    placement="origin at the coupling point, axes any", measure=_measure_spherical))
