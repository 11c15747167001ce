"""Force elements (``mechanism.forces``) on registered mechanisms.

A registered mechanism declares where elements may act (:class:`csim.model.definition.Sites`):
its bodies, each with a planar frame (origin, angle) and named material points, and its
joints, each one relative coordinate as a function of q. :class:`DeclaredGeometry` offers
these to the element kinds of :mod:`csim.linkage.forces` through the same interface as a
link-coupling mechanism's tables, so every kind (spring, joint_spring, actuator, force,
torque, switching laws) works on both, with the same keys and the same derivation:

- a point ``[BODY, POINT]`` is the body's declared point; ``[BODY, [x, y, z]]`` is
  ``origin + R(angle) (x, y)`` (and z out of the plane) [m];
- a joint is a declared joint's coordinate (``joint: O``);
- a link-frame direction turns with the body, R(angle) e; a torque on a body works on its
  angle, Q = d(angle)/dq u.

:func:`with_forces` returns the registered definition extended by the elements: their
potentials added to V, their loads and observables appended. Parameters that only the
elements use (``mechanism.parameters.k``, not one of the mechanism's) become parameters of
the extended model.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import sympy as sp

from csim.linkage.expressions import valid_name
from csim.linkage.forces import Contribution, ElementGeometry, JointCoordinate, build_forces
from csim.model.definition import MechanismDefinition, Parameter, SiteBody, Sites
from csim.model.light import full_definition
from csim.schema import describe, finite_number


def _rotation(angle: sp.Expr) -> sp.Matrix:
    """Rz(angle) (3, 3): a body's axes in global axes."""
    c, s = sp.cos(angle), sp.sin(angle)
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _column(xy: tuple) -> sp.Matrix:
    """A planar point (x, y) as a global position (3, 1) [m]."""
    return sp.Matrix([sp.sympify(xy[0]), sp.sympify(xy[1]), 0 if len(xy) < 3 else sp.sympify(xy[2])])


class DeclaredGeometry(ElementGeometry):
    """A registered mechanism's sites as an :class:`~csim.linkage.forces.ElementGeometry`.

    Parameters
    ----------
    definition : MechanismDefinition
        The registered mechanism (its ``sites`` set).
    values : dict name -> float
        Parameter values: the mechanism's (defaults and the case's) and the extra ones.
    extra : dict name -> Symbol
        Parameters the case adds for its elements.
    """

    def __init__(self, definition: MechanismDefinition, values: dict[str, float], extra: dict[str, sp.Symbol]):
        self.definition = definition
        self.sites: Sites = definition.sites
        self._symbols = {**{p.name: p.symbol for p in definition.parameters}, **extra}
        self._values = {self._symbols[k]: v for k, v in values.items() if k in self._symbols}
        self._bodies = {b.name: b for b in self.sites.bodies}
        self._joints = {j.name: j for j in self.sites.joints}

    @property
    def q(self) -> list[sp.Symbol]:
        return list(self.definition.coordinates)

    @property
    def qd(self) -> list[sp.Symbol]:
        return list(self.definition.velocities)

    @property
    def symbols(self) -> dict[str, sp.Symbol]:
        return self._symbols

    @property
    def values(self) -> dict[sp.Symbol, float]:
        return self._values

    def variables(self) -> dict[str, sp.Symbol]:
        return {str(s): s for s in (*self.q, *self.qd)}

    def link(self, path: str, raw: Any, problems: list[str]) -> SiteBody | None:
        body = self._bodies.get(raw) if isinstance(raw, str) else None
        if body is None:
            problems.append(f"{path}: got {describe(raw)}; not a body of {self.definition.name}; expected one of "
                            f"{', '.join(self._bodies)}")
        return body

    def point(self, path: str, raw: Any, problems: list[str]) -> tuple[sp.Matrix, SiteBody] | None:
        if not isinstance(raw, list) or len(raw) != 2:
            problems.append(f"{path}: got {describe(raw)}; expected [BODY, POINT] (a point name of the body) or "
                            f"[BODY, [x, y, z]] (in the body frame, m)")
            return None
        body = self.link(f"{path}[0]", raw[0], problems)
        if body is None:
            return None
        spot = raw[1]
        if isinstance(spot, list) and len(spot) == 3:
            local = [self.scope().parse(f"{path}[1][{a}]", v, problems, "m") for a, v in enumerate(spot)]
            if any(x is None for x in local):
                return None
            return _column(body.origin) + _rotation(body.angle) * sp.Matrix(local), body
        if not isinstance(spot, str) or spot not in body.points:
            problems.append(f"{path}[1]: got {describe(spot)}; body {body.name} has no such point; expected one of "
                            f"its points ({', '.join(body.points) or 'none'}) or [x, y, z] in its frame [m]")
            return None
        return _column(body.points[spot]), body

    def named_point(self, name: str) -> sp.Matrix | None:
        """The point ``name`` on the first body that declares it."""
        for body in self.sites.bodies:
            if name in body.points:
                return _column(body.points[name])
        return None

    def joint(self, path: str, raw: Any, problems: list[str], unit: str | None = None) -> JointCoordinate | None:
        joint = self._joints.get(raw) if isinstance(raw, str) else None
        if joint is None:
            problems.append(f"{path}: got {describe(raw)}; no such joint of {self.definition.name}; expected one of "
                            f"{', '.join(self._joints) or 'none'}")
            return None
        return JointCoordinate(joint.value, joint.unit, f"joint {joint.name} ({joint.description})")

    def rotation(self, link: SiteBody) -> sp.Matrix:
        return _rotation(link.angle)

    def omega(self, link: SiteBody) -> sp.Matrix:
        # planar: omega = d(angle)/dt about z, the same in the body's axes and in global axes
        return sp.Matrix([0, 0, self.rate(sp.sympify(link.angle))])


def _extra_parameters(given: dict, definition: MechanismDefinition) -> dict[str, float]:
    """Entries of ``mechanism.parameters`` that are not the mechanism's: candidate element
    parameters (numbers with usable names; anything else is left to the parameter check)."""
    names = set(definition.parameter_names) | set(definition.coordinate_names) | {str(v) for v in
                                                                                   definition.velocities}
    return {str(k): float(v) for k, v in given.items() if str(k) not in names and valid_name(str(k))
            and finite_number(v)}


def _used(contribution: Contribution) -> set[sp.Symbol]:
    """Every symbol the elements' expressions use."""
    exprs = [contribution.potential]
    for load in contribution.loads:
        exprs += [load.coordinate, load.law if load.law is not None else sp.Integer(0), *(load.direction or [])]
    exprs += [o.expression for o in contribution.observables]
    return set().union(*(sp.sympify(e).free_symbols for e in exprs))


def _name_clashes(definition: MechanismDefinition, contribution: Contribution, raw: list) -> list[str]:
    """Elements whose load (the element's name) or observable (``NAME_length``) is named like
    one of the mechanism's loads or observables."""
    taken = {ld.name: "load" for ld in definition.loads} | {o.name: "observable" for o in definition.observables}
    rows = {row.get("name"): n for n, row in enumerate(raw) if isinstance(row, dict)}
    out = []
    for what, name in [*(("load", ld.name) for ld in contribution.loads),
                       *(("observable", o.name) for o in contribution.observables)]:
        if name in taken:
            element = name if name in rows else name.rsplit("_", 1)[0]
            article = "an" if taken[name] == "observable" else "a"
            out.append(f"mechanism.forces[{rows.get(element, 0)}] ({element}).name: the {what} {name!r} it adds is "
                       f"already {article} {taken[name]} of {definition.name}; expected another name")
    return out


def with_forces(definition: Any, raw: Any, given: dict, problems: list[str]) -> MechanismDefinition | None:
    """The registered mechanism with the force elements of ``mechanism.forces`` added.

    Parameters
    ----------
    definition : MechanismDefinition or LightDefinition
        The registered mechanism.
    raw : list
        ``mechanism.forces`` as written (:func:`csim.linkage.forces.build_forces`).
    given : dict
        ``mechanism.parameters`` as written: the values the element checks use, and the
        parameters the elements add.
    problems : list of str
        Appended to (None is returned when there are any).

    Returns
    -------
    MechanismDefinition or None
        V + sum of the elements' potentials, the mechanism's loads then the elements',
        its observables then the elements', its parameters then the ones the elements add.
    """
    full = full_definition(definition)
    if full.sites is None:
        problems.append(f"mechanism.forces: the registered mechanism {full.name!r} declares no bodies or joints to "
                        f"place force elements on; expected no mechanism.forces (use loads)")
        return None
    extra = _extra_parameters(given or {}, full)
    values = {p.name: p.default for p in full.parameters}
    values.update({str(k): float(v) for k, v in (given or {}).items() if finite_number(v)})
    symbols = {name: sp.Symbol(name, real=True) for name in extra}
    before = len(problems)
    contribution = build_forces(raw, DeclaredGeometry(full, values, symbols), problems)
    problems += _name_clashes(full, contribution, raw if isinstance(raw, list) else [])
    if len(problems) > before:
        return None
    used = _used(contribution)
    added = [Parameter(name, value, "", "parameter of mechanism.forces") for name, value in extra.items()
             if symbols[name] in used]
    return dataclasses.replace(
        full,
        parameters=[*full.parameters, *added],
        potential_energy=full.potential_energy + contribution.potential,
        loads=[*full.loads, *contribution.loads],
        observables=[*full.observables, *contribution.observables],
    )
