"""Force elements of a link-coupling mechanism: springs, dampers, actuators, applied loads.

``mechanism.forces`` is a list of named elements, each a mapping with a ``type`` of
:data:`FORCE_KINDS` (``spring``, ``joint_spring``, ``actuator``, ``force``, ``torque``).
No element is given as a generalized force: each is located by the geometry (points on
links, joints) of an :class:`ElementGeometry`: the tables of a link-coupling mechanism
(:class:`Geometry`; a cut joint's variables measured from its two frames), or the declared
bodies and joints of a registered one (:class:`csim.mechanisms.sites.DeclaredGeometry`).
csim derives what each does:

- a **conservative** part (a linear spring, a preload) as a potential V_e(q) added to the
  mechanism's potential energy, so that h = dV/dq carries it and T + V stays constant;
- a **non-conservative** part (a damper, an actuator, a general force law, an applied
  force) as a :class:`csim.model.definition.Load`: a scalar value u(q, qd, t) (the law),
  acting along the generalized direction b(q) given by virtual power, P = u b . qd. Its
  work is integrated with the motion (``energy/work``), so the energy balance
  T + V - T0 - V0 - sum W stays meaningful.

Every expression is parsed with the names it may use (:func:`law_symbols`): the
parameters, the time ``t`` [s], the joint variables and their rates (``NAME_dot``), and the
element's own variable (``l``, ``ldot`` for a spring; ``x``, ``xdot`` for a joint element).
Problems are reported naming the row (``mechanism.forces[2] (damper)``), the key, the value
found and what was expected.
"""
from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from csim.linkage.expressions import Scope, evaluate, parse_expression, valid_name
from csim.linkage.frames import Frames
from csim.linkage.joints import JOINT_TYPES, CutGeometry
from csim.linkage.tables import Coupling, Tables
from csim.linkage.topology import Topology
from csim.linkage.transforms import simplify_entry
from csim.load_laws import REPORTED, VELOCITY_CONDITIONS, window_bound
from csim.model.definition import Load, Observable, time_symbol
from csim.schema import describe


class ElementGeometry:
    """What force elements are located by: the interface the element kinds use.

    Two implementations: :class:`Geometry` (a link-coupling mechanism: its tables, tree and
    transforms) and :class:`csim.mechanisms.sites.DeclaredGeometry` (a registered
    mechanism's declared bodies, points and joints, :class:`csim.model.definition.Sites`).
    Every position is a sympy expression of the coordinates q and the parameters.
    """

    @property
    def q(self) -> list[sp.Symbol]:
        raise NotImplementedError

    @property
    def qd(self) -> list[sp.Symbol]:
        raise NotImplementedError

    @property
    def symbols(self) -> dict[str, sp.Symbol]:
        """The parameters' symbols by name."""
        raise NotImplementedError

    @property
    def values(self) -> dict[sp.Symbol, float]:
        """The parameters' values by symbol."""
        raise NotImplementedError

    def variables(self) -> dict[str, sp.Symbol]:
        """The coordinates and their rates by the names a law may use."""
        raise NotImplementedError

    def link(self, path: str, raw: Any, problems: list[str]) -> Any:
        """The link (body) named by ``raw`` (None, with the problem listed, when none is)."""
        raise NotImplementedError

    def point(self, path: str, raw: Any, problems: list[str]) -> tuple[sp.Matrix, Any] | None:
        """``[LINK, POINT]`` or ``[LINK, [x, y, z]]``: the global position r(q) (3, 1) [m] and the link."""
        raise NotImplementedError

    def named_point(self, name: str) -> sp.Matrix | None:
        """The global position (3, 1) [m] of the point called ``name`` (None: no such point)."""
        raise NotImplementedError

    def joint(self, path: str, raw: Any, problems: list[str], unit: str | None = None) -> JointCoordinate | None:
        """The joint variable named by ``raw`` (``unit`` resolves a joint with several)."""
        raise NotImplementedError

    def rotation(self, link: Any) -> sp.Matrix:
        """The link's axes in global axes, (3, 3)."""
        raise NotImplementedError

    def omega(self, link: Any) -> sp.Matrix:
        """Angular velocity of a link in its own axes (3, 1) [rad/s], linear in the velocities."""
        raise NotImplementedError

    def rate(self, expr: sp.Expr) -> sp.Expr:
        """d expr/dt = (d expr/dq) qd of an expression of q (no explicit time)."""
        return sum((sp.diff(expr, qi) * qdi for qi, qdi in zip(self.q, self.qd)), sp.Integer(0))

    def gradient(self, expr: sp.Expr) -> list[sp.Expr]:
        """d expr/dq, one entry per coordinate."""
        return [sp.diff(expr, qi) for qi in self.q]

    def scope(self) -> Scope:
        return Scope(self.symbols, self.values)


@dataclass
class Geometry(ElementGeometry):
    """A link-coupling mechanism's geometry: the tables, the tree and the symbolic transforms.

    Attributes
    ----------
    tables, topology, frames
        The link-coupling model's stages (:mod:`csim.linkage.model`).
    """

    tables: Tables
    topology: Topology
    frames: Frames
    _omega: dict[int, sp.Matrix] | None = None

    def omega(self, link: int) -> sp.Matrix:
        if self._omega is None:
            from csim.linkage.model import link_angular_velocities

            self._omega = link_angular_velocities(self.topology, self.frames)
        return self._omega[link]

    @property
    def q(self) -> list[sp.Symbol]:
        return [v.symbol for v in self.topology.variables]

    @property
    def qd(self) -> list[sp.Symbol]:
        return [v.velocity for v in self.topology.variables]

    @property
    def symbols(self) -> dict[str, sp.Symbol]:
        return self.tables.symbols

    @property
    def values(self) -> dict[sp.Symbol, float]:
        return self.tables.values

    def variables(self) -> dict[str, sp.Symbol]:
        names = {}
        for v in self.topology.variables:
            names[v.name], names[str(v.velocity)] = v.symbol, v.velocity
        return names

    def link(self, path: str, raw: Any, problems: list[str]) -> int | None:
        return link_of(self, path, raw, problems)

    def point(self, path: str, raw: Any, problems: list[str]) -> tuple[sp.Matrix, int] | None:
        return point_of(self, path, raw, problems)

    def named_point(self, name: str) -> sp.Matrix | None:
        return _point_named(self, name)

    def joint(self, path: str, raw: Any, problems: list[str], unit: str | None = None) -> JointCoordinate | None:
        return joint_of(self, path, raw, problems, unit)

    def rotation(self, link: int) -> sp.Matrix:
        return self.frames.links[link][:3, :3]


@dataclass(frozen=True)
class JointCoordinate:
    """A joint variable an element acts on: a tree joint's coordinate, or a cut joint's
    relative rotation or translation as a function of the coordinates.

    Attributes
    ----------
    value : sympy expression of q [rad or m]
    unit : {"rad", "m"}
    label : str
        For messages and descriptions (``"q_A (coupling 1 'A' R (0,1)-(1,1))"``).
    """

    value: sp.Expr
    unit: str
    label: str


@dataclass(frozen=True)
class ElementRecord:
    """One built element, for reports (``csim describe``).

    Attributes
    ----------
    name, kind : str
        The row's ``name`` and ``type``.
    row : dict
        Its other keys as written.
    potential : sympy expression
        What it adds to V [J] (0 for none).
    loads : list of Load
        The loads it adds (direction, law, switching).
    """

    name: str
    kind: str
    row: dict
    potential: sp.Expr
    loads: list[Load]


@dataclass
class Contribution:
    """What one element (or the whole list) adds to the mechanism: potential [J], loads,
    observables; ``elements`` records each element of the list (:func:`build_forces`)."""

    potential: sp.Expr = field(default_factory=lambda: sp.Integer(0))
    loads: list[Load] = field(default_factory=list)
    observables: list[Observable] = field(default_factory=list)
    elements: list[ElementRecord] = field(default_factory=list)


@dataclass(frozen=True)
class ForceKind:
    """One registered type of force element.

    Attributes
    ----------
    name : str
        The ``type`` of a ``mechanism.forces`` row.
    keys : tuple of str
        The keys a row may have besides ``name`` and ``type``.
    summary : str
        One line for messages and the README.
    build : callable (Element, ElementGeometry, problems) -> Contribution or None
        Locates the element and derives its potential and loads (None: a problem was
        reported).
    """

    name: str
    keys: tuple[str, ...]
    summary: str
    build: Callable[..., Contribution | None]


@dataclass(frozen=True)
class Element:
    """One row of ``mechanism.forces``: its name, type, raw entries and key path."""

    name: str
    kind: str
    row: dict
    path: str

    def key(self, key: str) -> str:
        return f"{self.path}.{key}"


class ForceKindRegistry(dict):
    """Force element kinds by name (:data:`FORCE_KINDS`)."""

    def names(self) -> str:
        return ", ".join(self)


FORCE_KINDS = ForceKindRegistry()


def register_force_kind(kind: ForceKind) -> ForceKind:
    """Add a kind of force element to :data:`FORCE_KINDS`."""
    FORCE_KINDS[kind.name] = kind
    return kind


# ---------------------------------------------------------------------------------------
# locating: points, joints, switching coordinates
# ---------------------------------------------------------------------------------------
def _link_number(geo: Geometry, raw: Any) -> int | None:
    links = geo.tables.links
    if isinstance(raw, str):
        return next((n for n, link in links.items() if link.name == raw), None)
    if isinstance(raw, int) and not isinstance(raw, bool) and raw in links:
        return raw
    return None


def _link_choices(geo: Geometry) -> str:
    names = [link.name for link in geo.tables.links.values() if link.name]
    return ", ".join(map(str, sorted(geo.tables.links))) + (f" or a name ({', '.join(names)})" if names else "")


def link_of(geo: Geometry, path: str, raw: Any, problems: list[str]) -> int | None:
    """A link by number or name."""
    number = _link_number(geo, raw)
    if number is None:
        problems.append(f"{path}: got {describe(raw)}; not a link of mechanism.links; expected {_link_choices(geo)}")
    return number


def point_of(geo: Geometry, path: str, raw: Any, problems: list[str]) -> tuple[sp.Matrix, int] | None:
    """A point on a link, ``[LINK, POINT]`` (a point name of the link's joint frames) or
    ``[LINK, [x, y, z]]`` (link frame [m]): its global position r(q) (3, 1) and the link."""
    if not isinstance(raw, list) or len(raw) != 2:
        problems.append(f"{path}: got {describe(raw)}; expected [LINK, POINT] (a point name of the link) or "
                        f"[LINK, [x, y, z]] (in the link frame, m)")
        return None
    number = link_of(geo, f"{path}[0]", raw[0], problems)
    if number is None:
        return None
    link = geo.tables.links[number]
    spot = raw[1]
    if isinstance(spot, list) and len(spot) == 3:
        local = [geo.scope().parse(f"{path}[1][{a}]", v, problems, "m") for a, v in enumerate(spot)]
        if any(x is None for x in local):
            return None
        r = (geo.frames.links[number] * sp.Matrix([*local, 1]))[:3, 0]
        return r.applyfunc(simplify_entry), number
    frame = next((f for f in link.joints if isinstance(spot, str) and f.point == spot), None)
    if frame is None:
        names = [f.point for f in link.joints if f.point]
        problems.append(f"{path}[1]: got {describe(spot)}; {link.label} has no such point; expected one of its "
                        f"point names ({', '.join(names) or 'none: name them in mechanism.links'}) or [x, y, z]")
        return None
    return geo.frames.joint_frame(number, frame.index)[:3, 3], number


def _coupling(geo: Geometry, raw: Any) -> Coupling | None:
    for c in geo.tables.couplings:
        if (isinstance(raw, str) and c.name == raw) or (isinstance(raw, int) and not isinstance(raw, bool)
                                                        and c.number == raw):
            return c
    return None


def _cut_coordinate(geo: Geometry, c: Coupling, slot: int) -> sp.Expr:
    """Joint variable ``slot`` of a cut joint, measured from its two frames as a function of
    q (:attr:`csim.linkage.joints.JointType.measure`, exact on the constraint manifold).

    E.g. a rotation about z_ik: atan2(z_ik . (x_ik x x_jm), x_ik . x_jm); a translation
    along z_ik: z_ik . (r_jm - r_ik); the angles of a U or S joint from A_ik^T A_jm.
    """
    g = CutGeometry.from_transforms(geo.frames.joint_frame(c.i, c.k), geo.frames.joint_frame(c.j, c.m))
    return JOINT_TYPES[c.type].measure(g, simplify_entry)[slot]


def _cut_variables(geo: Geometry) -> dict[str, tuple[Coupling, int]]:
    """The variables of the cut joints by name (not coordinates: measured from the joint's
    frames): the type's templates with the coupling's name, or its number (``q_B_1``, ``q_4_2``)."""
    return {name: (c, slot) for c in geo.topology.cut_joints
            for slot, name in enumerate(JOINT_TYPES[c.type].variable_names(str(c.name or c.number)))}


def joint_of(geo: Geometry, path: str, raw: Any, problems: list[str], unit: str | None = None
             ) -> JointCoordinate | None:
    """The joint variable named by ``raw``: a coupling number or name, or a joint variable
    name. A joint with several variables is resolved by ``unit`` ("rad" for a torque, "m"
    for a force) when that leaves one; otherwise its variable must be named."""
    variables = {v.name: (v.coupling, v.slot) for v in geo.topology.variables}
    variables.update(_cut_variables(geo))
    c, slot = _coupling(geo, raw), None
    if c is None and isinstance(raw, str) and raw in variables:
        c, slot = variables[raw]
    if c is None:
        couplings = ", ".join(str(x.name or x.number) for x in geo.tables.couplings)
        problems.append(f"{path}: got {describe(raw)}; no such joint; expected a coupling number or name "
                        f"({couplings}) or a joint variable ({', '.join(variables) or 'none'})")
        return None
    specs = JOINT_TYPES[c.type].variables
    if slot is None:
        slots = [s for s, spec in enumerate(specs) if unit is None or spec.unit == unit]
        if len(slots) != 1:
            names = ", ".join(name for name, (d, _) in variables.items() if d is c) or "its joint variables"
            problems.append(f"{path}: {c.label} has {len(specs)} joint variables; expected one of them named "
                            f"({names})" if slots else
                            f"{path}: {c.label} has no {'rotation' if unit == 'rad' else 'translation'}; expected a "
                            f"{'force' if unit == 'rad' else 'torque'} on it, or another joint")
            return None
        slot = slots[0]
    if c in geo.topology.cut_joints:
        if JOINT_TYPES[c.type].measure is None:
            measured = ", ".join(name for name, kind in JOINT_TYPES.items() if kind.measure is not None)
            problems.append(f"{path}: {c.label} is a cut {c.type} joint, whose relative motion csim does not "
                            f"measure; expected an element on a tree joint or on a cut joint of type {measured}")
            return None
        return JointCoordinate(_cut_coordinate(geo, c, slot), specs[slot].unit, f"{c.label} (cut)")
    var = next(v for v in geo.topology.variables_of(c) if v.slot == slot)
    return JointCoordinate(var.symbol, var.unit, f"{var.name} ({c.label})")


def _point_named(geo: Geometry, name: str) -> sp.Matrix | None:
    """The global position of the point ``name``: its first frame that moves (the two frames
    of a P joint share a name, and only one of them moves), else its first."""
    found = [geo.frames.joint_frame(number, f.index)[:3, 3] for number, link in sorted(geo.tables.links.items())
             for f in link.joints if f.point == name]
    moving = [r for r in found if r.free_symbols & set(geo.q)]
    return (moving or found or [None])[0]


def two_points(geo: ElementGeometry, path: str, ends: Any, problems: list[str]) -> tuple | None:
    """Two points on links, ``[[LINK, POINT], [LINK, POINT]]`` at ``path``, as :func:`point_of`
    gives each (None, with the problem listed, when either is not one)."""
    if not isinstance(ends, list) or len(ends) != 2:
        problems.append(f"{path}: got {describe(ends)}; expected two points [[LINK, POINT], [LINK, POINT]]")
        return None
    a, b = (geo.point(f"{path}[{n}]", e, problems) for n, e in enumerate(ends))
    return None if a is None or b is None else (a, b)


def switch_coordinate(geo: ElementGeometry, path: str, raw: Any, problems: list[str]) -> tuple[sp.Expr, str] | None:
    """The coordinate a switching law watches (``on``): a joint (as :func:`joint_of`), a
    named point's global coordinate ``POINT_x`` / ``_y`` / ``_z``, or ``{distance: [A, B]}``
    between two points on links. Returns (s(q), unit)."""
    if isinstance(raw, dict) and set(raw) == {"distance"}:
        ends = two_points(geo, f"{path}.distance", raw["distance"], problems)
        if ends is None:
            return None
        a, b = ends
        d = a[0] - b[0]
        return sp.sqrt(simplify_entry((d.T * d)[0])), "m"
    if isinstance(raw, str) and raw[-2:] in ("_x", "_y", "_z"):
        found = geo.named_point(raw[:-2])
        if found is not None:
            return found["xyz".index(raw[-1])], "m"
    problems_here: list[str] = []
    joint = geo.joint(path, raw, problems_here)
    if joint is None:
        problems.append(f"{path}: got {describe(raw)}; expected a joint (coupling number or name, or joint "
                        f"variable), a named point's coordinate POINT_x, POINT_y or POINT_z, or "
                        f"{{distance: [[LINK, POINT], [LINK, POINT]]}}")
        return None
    return joint.value, joint.unit


# ---------------------------------------------------------------------------------------
# numbers and laws
# ---------------------------------------------------------------------------------------
def law_symbols(geo: ElementGeometry, local: dict[str, sp.Symbol]) -> dict[str, sp.Symbol]:
    """The names a law may use: parameters, t, joint variables and rates, the element's own."""
    names = dict(geo.symbols)
    names["t"] = time_symbol()
    names.update(geo.variables())
    names.update(local)
    return names


def law_of(geo: ElementGeometry, path: str, raw: Any, local: dict[str, sp.Expr], problems: list[str],
           unit: str | None = None) -> sp.Expr | None:
    """A force law: a number or an expression of :func:`law_symbols`, with the element's own
    names (``local``: name -> expression of q and qd) substituted. A constant law may be
    written with its unit (``2 kN``, ``150 N cm``), converted to ``unit`` (N or N m)."""
    # an own name that is also a parameter's or coordinate's is ambiguous where the law uses it
    clash = sorted(set(local) & (set(geo.symbols) | set(geo.variables())))
    used = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", raw)) if isinstance(raw, str) else set()
    if set(clash) & used:
        name = sorted(set(clash) & used)[0]
        problems.append(f"{path}: the element's own variable {name!r} is also the name of a parameter or "
                        f"coordinate; expected that parameter renamed, or the law written without {name!r}")
        return None
    local = {name: value for name, value in local.items() if name not in clash}
    own = {name: sp.Symbol(name, real=True) for name in local}
    expr = parse_expression(path, raw, law_symbols(geo, own), problems, geo.values, unit)
    if expr is None:
        return None
    return expr.xreplace({own[name]: value for name, value in local.items()})


def number_of(geo: ElementGeometry, element: Element, key: str, unit: str, problems: list[str], default: Any = None,
              minimum: float | None = None) -> sp.Expr | None:
    """A constant of an element: a number or an expression of the parameters, >= ``minimum``."""
    raw = element.row.get(key, default)
    path = element.key(key)
    expr = geo.scope().parse(path, raw, problems, unit)
    if expr is None or minimum is None:
        return expr
    value = evaluate(expr, geo.values)
    if value is not None and not value.real >= minimum:
        problems.append(f"{path}: got {describe(raw)}, {value.real:g} {unit} at the parameter values; expected a "
                        f"value >= {minimum:g} {unit}")
        return None
    return expr


def _direction(geo: ElementGeometry, element: Element, key: str, problems: list[str]) -> sp.Matrix | None:
    """A unit vector from a row's [x, y, z] (any length but zero)."""
    raw = element.row.get(key)
    path = element.key(key)
    if not isinstance(raw, list) or len(raw) != 3:
        problems.append(f"{path}: got {describe(raw)}; expected [x, y, z], a direction (normalized by csim)")
        return None
    entries = [geo.scope().parse(f"{path}[{a}]", v, problems) for a, v in enumerate(raw)]
    if any(e is None for e in entries):
        return None
    e = sp.Matrix(entries)
    norm = sp.sqrt((e.T * e)[0])
    if evaluate(norm, geo.values) is None or abs(evaluate(norm, geo.values)) == 0:
        problems.append(f"{path}: got {describe(raw)}; a zero vector; expected a direction [x, y, z] of nonzero "
                        f"length")
        return None
    return e / norm


def _switching(geo: ElementGeometry, element: Element, default: tuple[sp.Expr, str] | None,
               problems: list[str]) -> tuple[sp.Expr, str, tuple[float, float], str] | None:
    """The switching law of a row: (s(q), unit of s, window, velocity condition).

    ``on`` chooses s; without it s is ``default`` (None: the element has no coordinate of
    its own, so a window or a velocity condition needs ``on``). A window bound may be
    written with its unit (``[10 mm, 50 mm]``, ``[-30 deg, 30 deg]``), converted to s's.
    """
    row, path = element.row, element.path
    window_raw, velocity = row.get("window"), row.get("velocity", "any")
    ok = True
    if velocity not in VELOCITY_CONDITIONS:
        problems.append(f"{path}.velocity: got {describe(velocity)}; expected one of {', '.join(VELOCITY_CONDITIONS)}")
        ok = False
    on = default
    if "on" in row:
        on = switch_coordinate(geo, f"{path}.on", row["on"], problems)
        ok = ok and on is not None
    elif default is None and (window_raw is not None or velocity != "any"):
        problems.append(f"{path}: a window or velocity condition with no coordinate to watch; expected 'on' (a joint, "
                        f"POINT_x/_y/_z or {{distance: [A, B]}})")
        ok = False
    if not ok:
        return None
    s, unit = on if on is not None else (sp.Integer(0), "-")
    window = _window(f"{path}.window", window_raw, unit, problems)
    if window is None:
        return None
    return s, unit, window, velocity


def _window(path: str, raw: Any, unit: str, problems: list[str]) -> tuple[float, float] | None:
    """``window: [lo, hi]`` as floats in ``unit`` (s's: m, rad, or - for none); None, reported,
    for anything but two numbers (or quantities, or .inf) in increasing order."""
    if raw is None:
        return -math.inf, math.inf
    expected = (f"expected [lo, hi] with lo < hi, numbers in {unit} or written with their unit (use .inf for an "
                f"open end)" if unit not in ("-", "") else "expected [lo, hi] with lo < hi (use .inf for an open end)")
    if not isinstance(raw, list) or len(raw) != 2:
        problems.append(f"{path}: got {describe(raw)}; {expected}")
        return None
    bounds = [window_bound(f"{path}[{n}]", value, unit, problems) for n, value in enumerate(raw)]
    if any(b is REPORTED for b in bounds):
        return None
    if None in bounds or not bounds[0] < bounds[1]:
        problems.append(f"{path}: got {describe(raw)}; {expected}")
        return None
    return bounds[0], bounds[1]


# ---------------------------------------------------------------------------------------
# the kinds
# ---------------------------------------------------------------------------------------
def _one_of(element: Element, keys: tuple[str, ...], problems: list[str]) -> str | None:
    given = [k for k in keys if k in element.row]
    if len(given) != 1:
        problems.append(f"{element.path}: got {', '.join(given) or 'none'} of the keys {', '.join(keys)}; expected "
                        f"exactly one")
        return None
    return given[0]


def _damper_load(element: Element, s: sp.Expr, rate: sp.Expr, damping: sp.Expr, geo: ElementGeometry, unit: str,
                 s_unit: str, what: str) -> Load:
    """A damper on s: the force c ds/dt opposing the motion, Q = -(ds/dq) c ds/dt."""
    direction = [-g for g in geo.gradient(s)]
    return Load(element.name, s, unit, s_unit, f"{what} of {element.name!r}, c ds/dt, opposing ds/dt > 0",
                direction=direction, law=damping * rate, magnitude=1.0)


def build_spring(element: Element, geo: ElementGeometry, problems: list[str]) -> Contribution | None:
    """Point-to-point spring-damper between two points on links.

    l = |r_B - r_A|. Linear: tension f = k (l - l0) + F0 + c ldot, with the potential
    V = k (l - l0)^2 / 2 + F0 l and the damper as a load. General: the tension
    f(l, ldot, t) as a load (``force``). Either way Q = -(dl/dq) f (a tension pulls the
    points together).
    """
    ends = two_points(geo, element.key("between"), element.row.get("between"), problems)
    if ends is None:
        return None
    a, b = ends
    d = b[0] - a[0]
    if all(simplify_entry(x) == 0 for x in d):
        problems.append(f"{element.key('between')}: got {describe(element.row.get('between'))}; the two points are "
                        f"one point in every position (length 0: no direction to pull along); expected two distinct "
                        f"points")
        return None
    length = sp.sqrt(simplify_entry((d.T * d)[0]))
    if not length.free_symbols & set(geo.q):
        problems.append(f"{element.key('between')}: got {describe(element.row.get('between'))}; the distance between "
                        f"the points never changes (both on the fixed link, or on one link), so the spring does "
                        f"nothing; expected points on two links that move relative to each other")
        return None
    rate = geo.rate(length)
    out = Contribution(observables=[Observable(f"{element.name}_length", length, "m", "m/s",
                                               f"length of spring {element.name!r}")])
    linear = ("stiffness", "free_length", "damping", "preload")
    if "force" in element.row:
        both = [k for k in linear if k in element.row]
        if both:
            problems.append(f"{element.path}: got force together with {', '.join(both)}; expected either force (a "
                            f"law of l, ldot, t) or the linear keys")
            return None
        law = law_of(geo, element.key("force"), element.row["force"], {"l": length, "ldot": rate}, problems, "N")
        if law is None:
            return None
        out.loads.append(Load(element.name, length, "N", "m", f"tension of spring {element.name!r}, f(l, ldot, t)",
                              direction=[-g for g in geo.gradient(length)], law=law, magnitude=1.0))
        return out
    k = number_of(geo, element, "stiffness", "N/m", problems, default=0, minimum=0.0)
    l0 = number_of(geo, element, "free_length", "m", problems, default=0, minimum=0.0)
    c = number_of(geo, element, "damping", "N s/m", problems, default=0, minimum=0.0)
    f0 = number_of(geo, element, "preload", "N", problems, default=0)
    if None in (k, l0, c, f0):
        return None
    # V = k (l - l0)^2 / 2 + F0 l: -dV/dq = -(dl/dq) (k (l - l0) + F0)
    out.potential = k * (length - l0) ** 2 / 2 + f0 * length
    if c != 0:
        out.loads.append(_damper_load(element, length, rate, c, geo, "N", "m", "damper tension"))
    return out


def build_joint_spring(element: Element, geo: ElementGeometry, problems: list[str]) -> Contribution | None:
    """Spring-damper on a joint variable x: V = k (x - x0)^2 / 2, the damper c xdot as a load."""
    joint = geo.joint(element.key("joint"), element.row.get("joint"), problems)
    if joint is None:
        return None
    angular = joint.unit == "rad"
    free_key, wrong = ("free_angle", "free_length") if angular else ("free_length", "free_angle")
    if wrong in element.row:
        problems.append(f"{element.key(wrong)}: {joint.label} is a {'rotation' if angular else 'translation'}; "
                        f"expected {free_key}")
        return None
    k = number_of(geo, element, "stiffness", "N m/rad" if angular else "N/m", problems, default=0, minimum=0.0)
    x0 = number_of(geo, element, free_key, joint.unit, problems, default=0)
    c = number_of(geo, element, "damping", "N m s/rad" if angular else "N s/m", problems, default=0, minimum=0.0)
    if None in (k, x0, c):
        return None
    out = Contribution(potential=k * (joint.value - x0) ** 2 / 2)
    if c != 0:
        out.loads.append(_damper_load(element, joint.value, geo.rate(joint.value), c, geo,
                                      "N m" if angular else "N", joint.unit, "damper torque" if angular
                                      else "damper force"))
    return out


def _applied_load(element: Element, geo: ElementGeometry, law_key: str, coordinate: tuple[sp.Expr, str] | None,
                  direction: list[sp.Expr] | None, local: dict[str, sp.Expr], unit: str, what: str,
                  problems: list[str]) -> Contribution | None:
    """A load u = active * law(...) with its switching law (``window``, ``velocity``, ``on``)."""
    law = law_of(geo, element.key(law_key), element.row.get(law_key), local, problems, unit)
    switch = _switching(geo, element, coordinate, problems)
    if law is None or switch is None:
        return None
    s, s_unit, window, velocity = switch
    if direction is None and coordinate is not None and s is not coordinate[0]:
        direction = geo.gradient(coordinate[0])  # it works along its own coordinate, switching on another
    return Contribution(loads=[Load(element.name, s, unit, s_unit, what, direction=direction, law=law,
                                    magnitude=1.0, window=window, velocity=velocity)])


def build_actuator(element: Element, geo: ElementGeometry, problems: list[str]) -> Contribution | None:
    """A torque (``torque``, rotations) or force (``force``, translations) on a joint:
    Q = (dx/dq) u, the power u xdot."""
    key = _one_of(element, ("torque", "force"), problems)
    if key is None:
        return None
    joint = geo.joint(element.key("joint"), element.row.get("joint"), problems,
                      unit="rad" if key == "torque" else "m")
    if joint is None:
        return None
    if (joint.unit == "rad") != (key == "torque"):
        right = "torque" if joint.unit == "rad" else "force"
        problems.append(f"{element.key(key)}: {joint.label} is a {'rotation' if joint.unit == 'rad' else 'translation'}"
                        f"; expected {right}")
        return None
    rate = geo.rate(joint.value)
    return _applied_load(element, geo, key, (joint.value, joint.unit), None, {"x": joint.value, "xdot": rate},
                         "N m" if key == "torque" else "N", f"actuator {key} on {joint.label}", problems)


def _frame(element: Element, problems: list[str]) -> str | None:
    frame = element.row.get("frame", "global")
    if frame not in ("global", "link"):
        problems.append(f"{element.key('frame')}: got {describe(frame)}; expected global or link")
        return None
    return frame


def build_force(element: Element, geo: ElementGeometry, problems: list[str]) -> Contribution | None:
    """A force of value u along a direction e at a point P of a link: Q = (dr_P/dq)^T e u.

    e is fixed in the global frame (then the force works along s = e . r_P, its default
    switching coordinate) or in the link's frame (e = R e_link).
    """
    point = None
    if geo.link(element.key("link"), element.row.get("link"), problems) is not None:
        if "point" not in element.row:
            problems.append(f"{element.key('point')}: missing; expected a point name of the link or [x, y, z] (in the "
                            f"link frame, m)")
        else:  # point_of names the point [LINK, POINT][1]: here it is the key point
            found: list[str] = []
            point = geo.point(element.key("point"), [element.row["link"], element.row["point"]], found)
            problems += [line.replace(f"{element.key('point')}[1]", element.key("point"), 1) for line in found]
    e = _direction(geo, element, "direction", problems)
    frame = _frame(element, problems)
    if point is None or e is None or frame is None:
        return None
    r, link = point
    if not r.free_symbols & set(geo.q):
        problems.append(f"{element.key('link')}: got {describe(element.row.get('link'))}; the point "
                        f"{describe(element.row.get('point'))} does not move (it is on the fixed link), so the force "
                        f"does no work; expected a point of a moving link")
        return None
    if frame == "global":
        s = simplify_entry((e.T * r)[0])
        if not s.free_symbols & set(geo.q):
            problems.append(_out_of_plane(element, "direction", "the point never moves along it"))
            return None
        return _applied_load(element, geo, "value", (s, "m"), None, {}, "N", f"force on {element.name!r} along "
                             f"{list(e)}", problems)
    e_global = geo.rotation(link) * e
    direction = [simplify_entry(x) for x in (r.jacobian(geo.q).T * e_global)]
    if all(x == 0 for x in direction):
        problems.append(_out_of_plane(element, "direction", "the point never moves along it"))
        return None
    return _applied_load(element, geo, "value", None, direction, {}, "N", f"force on {element.name!r} along "
                         f"{list(e)} in the frame of link {link}", problems)


def _out_of_plane(element: Element, key: str, why: str) -> str:
    """The problem of a force direction or torque axis that does no work in any motion."""
    return (f"{element.key(key)}: got {describe(element.row.get(key))}; {why} (in a planar mechanism, "
            f"{'a direction out of' if key == 'direction' else 'an axis in'} the plane of motion), so it does no work; "
            f"expected {'a direction' if key == 'direction' else 'an axis'} with a component the mechanism moves "
            f"along")


def build_torque(element: Element, geo: ElementGeometry, problems: list[str]) -> Contribution | None:
    """A torque of value u about an axis e on a link: Q = d(e . omega)/dqd u (e in the global
    or the link frame)."""
    link = geo.link(element.key("link"), element.row.get("link"), problems)
    e = _direction(geo, element, "axis", problems)
    frame = _frame(element, problems)
    if link is None or e is None or frame is None:
        return None
    R = geo.rotation(link)
    if not R.free_symbols & set(geo.q):
        problems.append(f"{element.key('link')}: got {describe(element.row.get('link'))}; the link never turns (the "
                        f"fixed link, or one that only slides), so the torque does no work; expected a link that "
                        f"turns")
        return None
    e_link = R.T * e if frame == "global" else e  # omega is in link axes
    power = simplify_entry((e_link.T * geo.omega(link))[0])  # e . omega, linear in qd
    direction = [simplify_entry(sp.diff(power, v)) for v in geo.qd]
    if all(x == 0 for x in direction):
        problems.append(_out_of_plane(element, "axis", "the link never turns about it"))
        return None
    return _applied_load(element, geo, "value", None, direction, {}, "N m", f"torque on {element.name!r} about "
                         f"{list(e)}", problems)


SWITCH_KEYS = ("window", "velocity", "on")
for _kind in (
    ForceKind("spring", ("between", "stiffness", "free_length", "damping", "preload", "force"),
              "point-to-point spring-damper between two points on links", build_spring),
    ForceKind("joint_spring", ("joint", "stiffness", "free_angle", "free_length", "damping"),
              "spring-damper on a joint variable", build_joint_spring),
    ForceKind("actuator", ("joint", "torque", "force", *SWITCH_KEYS),
              "torque or force on a joint", build_actuator),
    ForceKind("force", ("link", "point", "direction", "frame", "value", *SWITCH_KEYS),
              "force on a point of a link", build_force),
    ForceKind("torque", ("link", "axis", "frame", "value", *SWITCH_KEYS),
              "torque on a link", build_torque),
):
    register_force_kind(_kind)


# ---------------------------------------------------------------------------------------
# the list
# ---------------------------------------------------------------------------------------
def _element(n: int, row: Any, names: set[str], problems: list[str]) -> Element | None:
    """The name, kind and keys of row n, checked."""
    path = f"mechanism.forces[{n}]"
    if not isinstance(row, dict):
        problems.append(f"{path}: got {describe(row)}; expected a mapping with name, type ({FORCE_KINDS.names()}) "
                        f"and the keys of its type")
        return None
    name = row.get("name")
    if not valid_name(name) or name in names:
        why = "already the name of another element" if name in names else "not a usable name"
        problems.append(f"{path}.name: got {describe(name)}; {why}; expected a unique name (letter, then letters, "
                        f"digits, _)")
        return None
    names.add(name)
    path = f"{path} ({name})"
    kind = FORCE_KINDS.get(row.get("type")) if isinstance(row.get("type"), str) else None
    if kind is None:
        problems.append(f"{path}.type: got {describe(row.get('type'))}; expected one of {FORCE_KINDS.names()}")
        return None
    unknown = [k for k in row if k not in ("name", "type", *kind.keys)]
    if unknown:
        problems.append(f"{path}.{unknown[0]}: unknown key for a {kind.name}; valid keys here: name, type, "
                        f"{', '.join(kind.keys)}")
        return None
    return Element(name, kind.name, row, path)


def build_forces(raw: Any, geo: ElementGeometry, problems: list[str]) -> Contribution:
    """All elements of ``mechanism.forces``: their potential summed, their loads and
    observables in row order. Problems are appended (every row is checked)."""
    total = Contribution()
    if raw is None:
        return total
    if not isinstance(raw, list):
        problems.append(f"mechanism.forces: got {describe(raw)}; expected a list of force elements, e.g. "
                        f"- {{name: s1, type: spring, between: [[1, B], [0, D]], stiffness: 100}}")
        return total
    names: set[str] = set()
    for n, row in enumerate(raw):
        element = _element(n, row, names, problems)
        if element is None:
            continue
        part = FORCE_KINDS[element.kind].build(element, geo, problems)
        if part is None:
            continue
        total.potential += part.potential
        total.loads += part.loads
        total.observables += part.observables
        total.elements.append(ElementRecord(element.name, element.kind, {k: v for k, v in element.row.items()
                                                                         if k not in ("name", "type")},
                                            part.potential, list(part.loads)))
    return total
