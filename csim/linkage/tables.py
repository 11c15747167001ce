"""The two tables of a link-coupling description, read and checked.

A mechanism is given under ``mechanism`` in a case file by

- ``links``: one row per link, the fixed link 0 included. Each row lists the link's joint
  frames, joint k (1-based) given by its type letter (R, P, C, U, S: the registered
  :data:`csim.linkage.joints.JOINT_TYPES`) and
  p = [x, y, z, phi, theta, psi]: the origin in the link frame [m] and the z-x'-z'' Euler
  angles [rad] that turn the link frame into the joint frame. Optional: a link ``name``,
  a ``point`` name per joint frame, and the mass properties ``mass`` [kg], ``com`` [m]
  (centre of mass in the link frame) and ``inertia`` [kg m^2] (about the centre of mass,
  link axes), checked as :mod:`csim.linkage.inertia` says. Links are numbered 0, 1, 2, ...
  without gaps.
- ``couplings``: one row per joint of the mechanism, ``[i, k, j, m]``: joint k of link i
  coupled with joint m of link j (links by number or name, joints by number or point
  name), optionally as ``{name: NAME, couple: [i, k, j, m]}``.

Numbers may be written as expressions of the named ``parameters`` (``l1``, ``xB/2``,
``90*deg``, ``pi/2``; :mod:`csim.linkage.expressions`), finite and real at the parameter
values, or with a unit (``50 mm``, ``30 deg``), converted to the entry's (m, rad, kg, kg m^2,
m/s^2). A parameter has no unit of its own: one written with a unit is converted to SI
base units (``l1: 50 mm`` is 0.05). Every problem is reported at once, naming the table row
(``mechanism.couplings[7] (coupling 8)``), the value found and what was expected; a row that
is wrong is reported once, not again by every coupling that names its link.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from csim.linkage.expressions import RESERVED, Scope, valid_name
from csim.linkage.inertia import parse_mass_properties
from csim.linkage.joints import JOINT_TYPES
from csim.quantities import SI_BASE, convert, is_quantity
from csim.schema import describe, finite_number


@dataclass(frozen=True)
class JointFrame:
    """Joint frame k of link i, fixed on the link.

    Attributes
    ----------
    link : int
        Link number i.
    index : int
        Joint number k on the link, 1-based.
    type : {"R", "P", "C", "U", "S"}
    p : tuple of 6 sympy expressions
        [x, y, z] origin in the link frame [m], [phi, theta, psi] z-x'-z'' Euler angles [rad].
    point : str or None
        Name of the point (for drawings, observables and messages).
    path : str
        Key path of its table entry.
    """

    link: int
    index: int
    type: str
    p: tuple
    point: str | None
    path: str

    @property
    def label(self) -> str:
        return f"({self.link},{self.index})" + (f" {self.point}" if self.point else "")


@dataclass(frozen=True)
class Link:
    """One row of the links table.

    Attributes
    ----------
    number : int
    name : str or None
    joints : list of JointFrame
    mass : sympy expression [kg]
    com : tuple of 3 sympy expressions [m], centre of mass in the link frame
    inertia : sympy Matrix (3, 3) [kg m^2], about the centre of mass, link axes
    path : str
    """

    number: int
    name: str | None
    joints: list[JointFrame]
    mass: sp.Expr
    com: tuple
    inertia: sp.Matrix
    path: str

    @property
    def label(self) -> str:
        return f"link {self.number}" + (f" {self.name!r}" if self.name else "")

    @property
    def has_mass(self) -> bool:
        return self.mass != 0 or any(x != 0 for x in self.inertia)


@dataclass(frozen=True)
class Coupling:
    """One row of the couplings table: joint k of link i with joint m of link j.

    Attributes
    ----------
    number : int
        1-based row number (the paper's joint number).
    name : str or None
    i, k, j, m : int
    type : str
        The common joint type.
    path : str
    """

    number: int
    name: str | None
    i: int
    k: int
    j: int
    m: int
    type: str
    path: str

    @property
    def label(self) -> str:
        name = f" {self.name!r}" if self.name else ""
        return f"coupling {self.number}{name} {self.type} ({self.i},{self.k})-({self.j},{self.m})"

    @property
    def freedoms(self) -> int:
        """Number of joint variables of its type."""
        return JOINT_TYPES[self.type].freedoms


@dataclass
class Tables:
    """A checked link-coupling description.

    Attributes
    ----------
    links : dict number -> Link
    couplings : list of Coupling
    parameters : dict name -> float
        Values of the named parameters.
    symbols : dict name -> Symbol
        Their symbols (real).
    gravity : tuple of 3 sympy expressions [m/s^2]
    drive : dict key -> raw value (checked once the joint variables are known)
    label : str
    """

    links: dict[int, Link]
    couplings: list[Coupling]
    parameters: dict[str, float]
    symbols: dict[str, sp.Symbol]
    gravity: tuple
    drive: dict = field(default_factory=dict)
    label: str = "linkage"

    def frame(self, link: int, index: int) -> JointFrame:
        return self.links[link].joints[index - 1]

    def link_label(self, number: int) -> str:
        return self.links[number].label

    @property
    def values(self) -> dict[sp.Symbol, float]:
        """Parameter values by symbol, for substitution."""
        return {self.symbols[k]: v for k, v in self.parameters.items()}


def _parameters(given: Any, problems: list[str]) -> tuple[dict[str, float], dict[str, sp.Symbol]]:
    values, symbols = {}, {}
    if given is None:
        return values, symbols
    if not isinstance(given, dict):
        problems.append(f"mechanism.parameters: got {describe(given)}; expected a mapping name: number")
        return values, symbols
    for key, value in given.items():
        path = f"mechanism.parameters.{key}"
        if not valid_name(key):
            problems.append(f"{path}: not a usable parameter name; expected a letter followed by letters, digits "
                            f"or _, other than {', '.join(sorted(RESERVED))} and Python keywords")
            continue
        if is_quantity(value):  # no unit of its own: 50 mm is 0.05 (SI base units)
            value, problem = convert(value, SI_BASE)
            if problem is not None:
                problems.append(f"{path}: got {describe(given[key])}; {problem}")
                continue
        if not finite_number(value):
            problems.append(f"{path}: got {describe(given[key])}; expected a finite number (SI units), or a number "
                            f"with a unit (50 mm)")
            continue
        values[key] = float(value)
        symbols[key] = sp.Symbol(key, real=True)
    return values, symbols


#: units of the entries of a joint frame's p = [x, y, z, phi, theta, psi]
P_UNITS = ("m", "m", "m", "rad", "rad", "rad")


def _p_vector(path: str, value: Any, scope: Scope, problems: list[str]) -> tuple | None:
    if value is None or (isinstance(value, (int, float)) and not isinstance(value, bool) and value == 0):
        return (sp.Integer(0),) * 6
    if not isinstance(value, list) or len(value) not in (3, 6):
        problems.append(f"{path}: got {describe(value)}; expected 0 or a list [x, y, z] or "
                        f"[x, y, z, phi, theta, psi] (m, rad; z-x'-z'' Euler angles)")
        return None
    entries = [scope.parse(f"{path}[{n}]", v, problems, P_UNITS[n]) for n, v in enumerate(value)]
    if any(e is None for e in entries):
        return None
    return tuple(entries) + (sp.Integer(0),) * (6 - len(entries))


def _joint(path: str, link: int, index: int, entry: Any, scope: Scope, problems: list[str]) -> JointFrame | None:
    point = None
    p_raw: Any = 0
    types = JOINT_TYPES.names()
    if isinstance(entry, str):
        kind = entry
    elif isinstance(entry, list) and 1 <= len(entry) <= 3:
        kind = entry[0]
        p_raw = entry[1] if len(entry) > 1 else 0
        point = entry[2] if len(entry) > 2 else None
    elif isinstance(entry, dict):
        unknown = [k for k in entry if k not in ("type", "p", "point")]
        if unknown:
            problems.append(f"{path}.{unknown[0]}: unknown key; valid keys here: type, p, point")
            return None
        if "type" not in entry:
            problems.append(f"{path}.type: missing; expected one of {types}")
            return None
        kind, p_raw, point = entry["type"], entry.get("p", 0), entry.get("point")
    else:
        problems.append(f"{path}: got {describe(entry)}; expected a joint type letter ({types}), "
                        f"[TYPE, p] or [TYPE, p, POINT], or {{type, p, point}}")
        return None
    if not isinstance(kind, str) or kind not in JOINT_TYPES:
        problems.append(f"{path}: joint type got {describe(kind)}; expected one of {types}")
        return None
    if point is not None and not valid_name(point):
        problems.append(f"{path}: point name got {describe(point)}; expected a name (letter, then letters, digits, _)")
        return None
    p = _p_vector(f"{path}.p" if isinstance(entry, dict) else f"{path}[1]", p_raw, scope, problems)
    if p is None:
        return None
    return JointFrame(link, index, kind, p, point, path)


def _joint_frames(path: str, number: int, joints_raw: Any, scope: Scope, problems: list[str]) -> list[JointFrame]:
    """The joint frames of a link row; empty when any is wrong (reported)."""
    if not isinstance(joints_raw, list) or not joints_raw:
        problems.append(f"{path}.joints: got {describe(joints_raw)}; expected a list of joint frames, "
                        f"e.g. [R, [R, [l1, 0, 0]]]")
        return []
    joints: list[JointFrame] = []
    points = set()
    for k, entry in enumerate(joints_raw):
        frame = _joint(f"{path}.joints[{k}]", number, k + 1, entry, scope, problems)
        if frame is None:
            continue
        if frame.point is not None:
            if frame.point in points:
                problems.append(f"{path}.joints[{k}]: point name {frame.point!r} used twice on this link")
            points.add(frame.point)
        joints.append(frame)
    return joints if len(joints) == len(joints_raw) else []


LINK_KEYS = ("link", "name", "joints", "mass", "com", "inertia")


@dataclass
class LinkRows:
    """What the links table gave.

    Attributes
    ----------
    links : dict number -> Link
        The valid rows.
    failed : set of int and str
        Numbers and names of the rows that exist but are wrong (reported once; the
        couplings that name them are not checked further).
    numbered : bool
        Whether every row had a usable link number (so that gaps can be told).
    """

    links: dict[int, Link] = field(default_factory=dict)
    failed: set = field(default_factory=set)
    numbered: bool = True


def _link_name(path: str, row: dict, names: dict[str, str], problems: list[str]) -> str | None:
    name = row.get("name")
    if name is None:
        return None
    if not valid_name(name):
        problems.append(f"{path}.name: got {describe(name)}; expected a name (letter, then letters, digits, _)")
        return None
    if name in names:
        problems.append(f"{path}.name: got {name!r}; already the name of {names[name]}; expected unique names")
        return None
    names[name] = path
    return name


def _links(rows: Any, scope: Scope, problems: list[str]) -> LinkRows:
    out = LinkRows()
    if not isinstance(rows, list) or not rows:
        problems.append(f"mechanism.links: got {describe(rows)}; expected a list of link rows, "
                        f"e.g. - {{link: 0, joints: [R, [R, [l1, 0, 0]]]}}")
        out.numbered = False
        return out
    names: dict[str, str] = {}
    for n, row in enumerate(rows):
        path = f"mechanism.links[{n}]"
        if not isinstance(row, dict):
            problems.append(f"{path}: got {describe(row)}; expected a mapping with keys {', '.join(LINK_KEYS)}")
            out.numbered = False
            continue
        for key in row:
            if key not in LINK_KEYS:
                problems.append(f"{path}.{key}: unknown key; valid keys here: {', '.join(LINK_KEYS)}")
        number = row.get("link", n)
        if isinstance(number, bool) or not isinstance(number, int) or number < 0:
            problems.append(f"{path}.link: got {describe(number)}; expected a link number (integer >= 0)")
            out.numbered = False
            continue
        if number in out.links or number in out.failed:
            first = out.links[number].path if number in out.links else "an earlier row"
            problems.append(f"{path}.link: got {number}; link {number} is already defined by {first}; "
                            f"expected each link number once")
            continue
        name = _link_name(path, row, names, problems)
        if name is None and isinstance(row.get("name"), str):
            out.failed.add(row["name"])  # reported; the couplings that use the name are not
        start = len(problems)
        joints = _joint_frames(path, number, row.get("joints"), scope, problems)
        props = parse_mass_properties(path, row, scope, problems)  # checked even when the joints are wrong
        if len(problems) > start or props is None or not joints:
            out.failed |= {number, name} - {None}
            continue
        out.links[number] = Link(number, name, joints, props.mass, props.com, props.inertia, path)
    return out


def _numbering(rows: LinkRows, problems: list[str]) -> None:
    """Link 0 and no gaps in the numbers (judged when every row had a usable number)."""
    numbers = set(rows.links) | {x for x in rows.failed if isinstance(x, int)}
    if not rows.numbered or not numbers:
        return
    if 0 not in numbers:
        problems.append("mechanism.links: no link 0; expected the fixed link (the frame of reference) numbered 0")
    top = max(numbers)
    # counted, not listed: a link numbered 10**9 must not build a billion-element set
    count = top - 1 - sum(1 for n in numbers if 1 <= n < top)
    missing = list(itertools.islice((n for n in range(1, top) if n not in numbers), 10))
    if missing:
        given = ", ".join(map(str, sorted(numbers)))
        more = f" and {count - len(missing)} more" if count > len(missing) else ""
        which = f"link {missing[0]} is" if count == 1 else f"links {', '.join(map(str, missing))}{more} are"
        problems.append(f"mechanism.links: {which} missing (links given: {given}); expected the links numbered "
                        f"0 to {max(numbers)} without gaps")


def _resolve_link(value, links, by_name):
    if isinstance(value, str):
        return by_name.get(value)
    if isinstance(value, int) and not isinstance(value, bool) and value in links:
        return value
    return None


def _resolve_joint(value, link: Link):
    if isinstance(value, str):
        return next((f.index for f in link.joints if f.point == value), None)
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= len(link.joints):
        return value
    return None


def _coupling_name(path: str, row: Any, names: dict[str, str], problems: list[str]) -> tuple[bool, Any, Any]:
    """(ok, name, spec) of a coupling row, the index form or ``{name, couple}``."""
    if not isinstance(row, dict):
        return True, None, row
    unknown = [k for k in row if k not in ("name", "couple")]
    if unknown:
        problems.append(f"{path}.{unknown[0]}: unknown key; valid keys here: name, couple")
        return False, None, None
    name, spec = row.get("name"), row.get("couple")
    if name is not None and (not valid_name(name) or name in names):
        why = f"already the name of {names[name]}" if valid_name(name) else "not a usable name"
        problems.append(f"{path}.name: got {describe(name)}; {why}; expected a unique name (letter, then "
                        f"letters, digits, _)")
        return False, None, None
    if name is not None:
        names[name] = path
    return True, name, spec


def _coupling_ends(path: str, spec: list, rows: LinkRows, by_name: dict, problems: list[str]) -> list | None:
    """The two (link, joint) ends of a coupling; None when one is wrong (reported, unless
    it names a link whose row was wrong and is reported already)."""
    links = rows.links
    ends = []
    for link_raw, joint_raw in ((spec[0], spec[1]), (spec[2], spec[3])):
        number = _resolve_link(link_raw, links, by_name)
        if number is None:
            if isinstance(link_raw, (int, str)) and not isinstance(link_raw, bool) and link_raw in rows.failed:
                return None
            known = ", ".join(str(x) for x in sorted(links)) + (
                f" or a name ({', '.join(sorted(by_name))})" if by_name else "")
            problems.append(f"{path}: link {describe(link_raw)} is not defined in mechanism.links; expected "
                            f"one of {known}")
            return None
        link = links[number]
        index = _resolve_joint(joint_raw, link)
        if index is None:
            pts = [f.point for f in link.joints if f.point]
            extra = f" or a point name ({', '.join(pts)})" if pts else ""
            problems.append(f"{path}: {link.label} has no joint {describe(joint_raw)}; expected a joint number "
                            f"1..{len(link.joints)}{extra} (see {link.path}.joints)")
            return None
        ends.append((number, index))
    return ends


def _pin_pairs(spec: Any) -> list[list] | None:
    """The [link, joint] pairs of a joint shared by three or more links, ``[[i, k], [j, m], [l, n], ...]``
    (None for any other form)."""
    if isinstance(spec, list) and len(spec) >= 3 and all(isinstance(p, list) and len(p) == 2 for p in spec):
        return spec
    return None


def _couplings(table: Any, rows: LinkRows, problems: list[str]) -> list[Coupling]:
    out: list[Coupling] = []
    if not isinstance(table, list) or not table:
        problems.append(f"mechanism.couplings: got {describe(table)}; expected a list of rows [i, k, j, m] "
                        f"(joint k of link i coupled with joint m of link j)")
        return out
    links = rows.links
    by_name = {link.name: number for number, link in links.items() if link.name}
    used: dict[tuple[int, int], str] = {}
    names: dict[str, str] = {}
    extra = len(table)  # the couplings of a shared joint beyond its first are numbered after the table
    for n, row in enumerate(table):
        path = f"mechanism.couplings[{n}] (coupling {n + 1})"
        ok, name, spec = _coupling_name(path, row, names, problems)
        if not ok:
            continue
        pairs = _pin_pairs(spec)
        if pairs is None and (not isinstance(spec, list) or len(spec) != 4):
            problems.append(f"{path}: got {describe(spec)}; expected [i, k, j, m] (link i, its joint k; link j, its "
                            f"joint m), {{name: NAME, couple: [i, k, j, m]}}, or a joint shared by three or more "
                            f"links, [[i, k], [j, m], [l, n], ...]")
            continue
        # a shared joint (ternary, quaternary pin): its first link's frame coupled with each other link's
        specs = [spec] if pairs is None else [[*pairs[0], *other] for other in pairs[1:]]
        first_end = None
        for t, one in enumerate(specs):
            number = n + 1 if t == 0 else (extra := extra + 1)
            sub_name = name if t == 0 or name is None else f"{name}_{t + 1}"
            if t > 0 and sub_name is not None:
                if sub_name in names:
                    problems.append(f"{path}.name: {name!r} names the shared joint's couplings {name}, {name}_2, ...; "
                                    f"{sub_name!r} is already the name of {names[sub_name]}")
                    break
                names[sub_name] = path
            coupling = _one_coupling(path, number, sub_name, one, rows, by_name, used, problems, shared=first_end)
            if coupling is None:
                break
            first_end = (coupling.i, coupling.k)
            out.append(coupling)
    return out


def _one_coupling(path: str, number: int, name: str | None, spec: list, rows: LinkRows, by_name: dict,
                  used: dict, problems: list[str], shared: tuple[int, int] | None = None) -> Coupling | None:
    """One binary coupling [i, k, j, m], checked; ``shared`` is the end a shared joint's couplings
    have in common (it may be coupled more than once)."""
    links = rows.links
    ends = _coupling_ends(path, spec, rows, by_name, problems)
    if ends is None:
        return None
    (i, k), (j, m) = ends
    if i == j:
        problems.append(f"{path}: couples link {i} with itself; expected two different links")
        return None
    clash = False
    for end in ends:
        if end in used and end != shared:
            problems.append(f"{path}: joint {end[1]} of link {end[0]} is already coupled by {used[end]}; "
                            f"expected each joint frame in one coupling only (a joint shared by three or more "
                            f"links is one row: [[i, k], [j, m], [l, n]])")
            clash = True
    if clash:
        return None
    a, b = links[i].joints[k - 1], links[j].joints[m - 1]
    if a.type != b.type:
        problems.append(f"{path}: couples a {a.type} joint (link {i}, joint {k}) with a {b.type} joint "
                        f"(link {j}, joint {m}); expected two joint frames of the same type")
        return None
    used[(i, k)] = used[(j, m)] = path
    return Coupling(number, name, i, k, j, m, a.type, path)


def _shared_point_names(links: dict[int, Link], couplings: list[Coupling]) -> list[str]:
    """A point name on frames of several links names one physical point: the frames must be
    joined, by couplings and by frames of one link at the same origin (``B`` on a crank and
    on its coupler). On frames nothing joins (``B`` on every crank) it would name several
    points, and the observables ``B_x``, ``B_y`` would follow the first one alone. Links not
    connected to the fixed link are left to the topology's own message."""
    parent: dict[tuple, tuple] = {}

    def root(f):
        while parent.get(f, f) != f:
            f = parent[f]
        return f

    def join(a, b):
        parent[root(a)] = root(b)

    connected, grown = {0}, True
    while grown:
        grown = False
        for c in couplings:
            if (c.i in connected) != (c.j in connected):
                connected |= {c.i, c.j}
                grown = True
    for c in couplings:
        join(("frame", c.i, c.k), ("frame", c.j, c.m))
    for number, link in links.items():
        for f in link.joints:  # frames of one link at one origin are one point
            join(("frame", number, f.index), ("origin", number, tuple(map(str, f.p[:3]))))
    by_name: dict[str, list[JointFrame]] = {}
    for number, link in sorted(links.items()):
        for f in link.joints:
            if f.point and number in connected:
                by_name.setdefault(f.point, []).append(f)
    problems = []
    for name, frames in by_name.items():
        groups: dict[tuple, JointFrame] = {}
        for f in frames:
            groups.setdefault(root(("frame", f.link, f.index)), f)
        if len(groups) > 1:
            a, b = list(groups.values())[:2]
            problems.append(f"{b.path}: point name {name!r} is also on {links[a.link].label} (joint {a.index}), and no "
                            f"coupling joins the two frames: they are different points; expected a name of its own "
                            f"for each point (e.g. {name}{a.link}, {name}{b.link})")
    return problems


#: the most rows of mechanism.links, mechanism.couplings and mechanism.forces
MAX_LINKS = 100
MAX_COUPLINGS = 200
MAX_FORCES = 200


def parse_tables(mechanism: dict, problems: list[str]) -> Tables | None:
    """Check the link-coupling keys of a ``mechanism`` section.

    Parameters
    ----------
    mechanism : dict
        The case's ``mechanism`` section (``links``, ``couplings``, ``parameters``,
        ``gravity``, ``drive``, ``label``).
    problems : list of str
        Every problem found is appended.

    Returns
    -------
    Tables, or None when a problem was found.
    """
    start = len(problems)
    for key, limit in (("links", MAX_LINKS), ("couplings", MAX_COUPLINGS), ("forces", MAX_FORCES)):
        rows = mechanism.get(key)
        if isinstance(rows, list) and len(rows) > limit:
            problems.append(f"mechanism.{key}: got {len(rows):,} rows; expected at most {limit} (the symbolic "
                            f"derivation grows with the square of a chain's length or faster: a 30-link chain "
                            f"takes seconds, hundreds of links hours)")
    if len(problems) > start:
        return None
    values, symbols = _parameters(mechanism.get("parameters"), problems)
    scope = Scope(symbols, {symbols[k]: v for k, v in values.items()})
    rows = _links(mechanism.get("links"), scope, problems)
    _numbering(rows, problems)
    couplings = _couplings(mechanism.get("couplings"), rows, problems) if rows.links else []
    if len(problems) == start:  # a coupling row in error leaves its frames unjoined: no second message
        problems += _shared_point_names(rows.links, couplings)
    gravity_raw = mechanism.get("gravity")
    gravity = (sp.Integer(0),) * 3
    if gravity_raw is not None:
        if not isinstance(gravity_raw, list) or len(gravity_raw) != 3:
            problems.append(f"mechanism.gravity: got {describe(gravity_raw)}; expected [gx, gy, gz] in the fixed "
                            f"frame [m/s^2], e.g. [0, -9.81, 0]")
        else:
            gravity = tuple(scope.parse(f"mechanism.gravity[{a}]", v, problems, "m/s^2")
                            for a, v in enumerate(gravity_raw))
    drive = mechanism.get("drive") or {}
    if not isinstance(drive, dict):
        problems.append(f"mechanism.drive: got {describe(drive)}; expected a mapping joint: value or expression of t")
        drive = {}
    label = mechanism.get("label") or "linkage"
    if not valid_name(label):
        problems.append(f"mechanism.label: got {describe(label)}; expected a name (letter, then letters, digits, _)")
    if len(problems) > start:
        return None
    return Tables(links=rows.links, couplings=couplings, parameters=values, symbols=symbols, gravity=gravity,
                  drive=drive, label=label)
