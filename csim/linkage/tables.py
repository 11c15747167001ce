"""The two tables of a link-coupling description, read and checked.

A mechanism is given under ``mechanism`` in a case file by

- ``links``: one row per link, the fixed link 0 included. Each row lists the link's joint
  frames, joint k (1-based) given by its type letter (R, P, C, U, S) and
  p = [x, y, z, phi, theta, psi]: the origin in the link frame [m] and the z-x'-z'' Euler
  angles [rad] that turn the link frame into the joint frame. Optional: a link ``name``,
  a ``point`` name per joint frame, and the mass properties ``mass`` [kg], ``com`` [m]
  (centre of mass in the link frame) and ``inertia`` [kg m^2] (about the centre of mass,
  link axes).
- ``couplings``: one row per joint of the mechanism, ``[i, k, j, m]``: joint k of link i
  coupled with joint m of link j (links by number or name, joints by number or point
  name), optionally as ``{name: NAME, couple: [i, k, j, m]}``.

Numbers may be written as expressions of the named ``parameters`` (``l1``, ``xB/2``,
``90*deg``, ``pi/2``). Every problem is reported at once, naming the table row
(``mechanism.couplings[7] (coupling 8)``), the value found and what was expected.
"""
from __future__ import annotations

import keyword
import math
import re
from dataclasses import dataclass, field
from typing import Any

import sympy as sp
from sympy.parsing.sympy_parser import parse_expr

from csim.schema import describe

#: Joint type letter -> number of joint variables (degrees of freedom of the joint).
JOINT_FREEDOMS: dict[str, int] = {"R": 1, "P": 1, "C": 2, "U": 2, "S": 3}

#: Functions and constants an expression may use besides the parameters.
FUNCTIONS: dict[str, Any] = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos, "atan": sp.atan,
    "atan2": sp.atan2, "sqrt": sp.sqrt, "exp": sp.exp, "pi": sp.pi, "deg": sp.pi / 180,
}

#: Names a parameter may not take: the generated code's arguments and locals, the time.
RESERVED = {"q", "qd", "par", "out", "math", "np", "t", "float"} | set(FUNCTIONS)

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_EXPRESSION_CHARS = re.compile(r"^[A-Za-z0-9_+\-*/().,^ \t]*$")
_GLOBALS = {"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational, "Symbol": sp.Symbol,
            "__builtins__": {}}


def valid_name(name: Any) -> bool:
    """A name usable as a symbol in generated code: an identifier, not reserved."""
    return isinstance(name, str) and bool(_NAME.match(name)) and not keyword.iskeyword(name) \
        and name not in RESERVED


def parse_expression(path: str, value: Any, symbols: dict[str, sp.Symbol], problems: list[str]) -> sp.Expr | None:
    """A number, or an expression string in ``symbols``, as an exact sympy expression.

    Floats become rationals (0.1 -> 1/10), so that sums cancel exactly.

    Parameters
    ----------
    path : str
        Key path for messages.
    value : int, float or str
    symbols : dict name -> Symbol
        The names the expression may use (besides :data:`FUNCTIONS`).
    problems : list of str
        Appended to, one line per problem.

    Returns
    -------
    sympy expression, or None when the value is not valid.
    """
    allowed = ", ".join(sorted(symbols)) or "none"
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        problems.append(f"{path}: got {describe(value)}; expected a number or an expression of the parameters "
                        f"({allowed})")
        return None
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            problems.append(f"{path}: got {describe(value)}; expected a finite number")
            return None
        return sp.Rational(repr(value))
    text = value.strip()
    if "//" in text or "**" in text or re.search(r"\^[^()+\-*/]*\^", text):
        problems.append(f"{path}: got {describe(value)}; expected + - * / and single powers ^ (no //, ** or "
                        f"a^b^c)")
        return None
    if not text or not _EXPRESSION_CHARS.match(text):
        problems.append(f"{path}: got {describe(value)}; expected an expression of numbers, the parameters "
                        f"({allowed}), + - * / ^ ( ) and {', '.join(FUNCTIONS)}")
        return None
    unknown = [name for name in _IDENT.findall(re.sub(r"\d+\.?\d*[eE][-+]?\d+", "0", text))
               if name not in symbols and name not in FUNCTIONS]
    if unknown:
        problems.append(f"{path}: got {describe(value)}; unknown name {unknown[0]!r}: expected a parameter "
                        f"({allowed}) or one of {', '.join(FUNCTIONS)}")
        return None
    try:
        expr = parse_expr(text.replace("^", "**"), local_dict={**FUNCTIONS, **symbols}, global_dict=dict(_GLOBALS))
        expr = sp.nsimplify(sp.sympify(expr), rational=True)
    except Exception as exc:
        problems.append(f"{path}: got {describe(value)}; not a valid expression ({type(exc).__name__})")
        return None
    if not isinstance(expr, sp.Expr) or expr.has(sp.zoo, sp.oo, sp.nan, sp.I):
        problems.append(f"{path}: got {describe(value)}; expected a finite real expression")
        return None
    return expr


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
        return JOINT_FREEDOMS[self.type]


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
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            problems.append(f"{path}: got {describe(value)}; expected a finite number")
            continue
        values[key] = float(value)
        symbols[key] = sp.Symbol(key, real=True)
    return values, symbols


def _p_vector(path: str, value: Any, symbols, problems) -> tuple | None:
    if value is None or (isinstance(value, (int, float)) and not isinstance(value, bool) and value == 0):
        return (sp.Integer(0),) * 6
    if not isinstance(value, list) or len(value) not in (3, 6):
        problems.append(f"{path}: got {describe(value)}; expected 0 or a list [x, y, z] or "
                        f"[x, y, z, phi, theta, psi] (m, rad; z-x'-z'' Euler angles)")
        return None
    entries = [parse_expression(f"{path}[{n}]", v, symbols, problems) for n, v in enumerate(value)]
    if any(e is None for e in entries):
        return None
    return tuple(entries) + (sp.Integer(0),) * (6 - len(entries))


def _joint(path: str, link: int, index: int, entry: Any, symbols, problems) -> JointFrame | None:
    point = None
    p_raw: Any = 0
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
            problems.append(f"{path}.type: missing; expected one of {', '.join(JOINT_FREEDOMS)}")
            return None
        kind, p_raw, point = entry["type"], entry.get("p", 0), entry.get("point")
    else:
        problems.append(f"{path}: got {describe(entry)}; expected a joint type letter ({', '.join(JOINT_FREEDOMS)}), "
                        f"[TYPE, p] or [TYPE, p, POINT], or {{type, p, point}}")
        return None
    if kind not in JOINT_FREEDOMS:
        problems.append(f"{path}: joint type got {describe(kind)}; expected one of {', '.join(JOINT_FREEDOMS)}")
        return None
    if point is not None and not valid_name(point):
        problems.append(f"{path}: point name got {describe(point)}; expected a name (letter, then letters, digits, _)")
        return None
    p = _p_vector(f"{path}.p" if isinstance(entry, dict) else f"{path}[1]", p_raw, symbols, problems)
    if p is None:
        return None
    return JointFrame(link, index, kind, p, point, path)


def _inertia(path: str, value: Any, symbols, problems) -> sp.Matrix | None:
    if value is None:
        return sp.zeros(3, 3)
    if not isinstance(value, list):
        j = parse_expression(path, value, symbols, problems)
        return None if j is None else j * sp.eye(3)
    if len(value) == 3 and all(not isinstance(v, list) for v in value):
        diag = [parse_expression(f"{path}[{n}]", v, symbols, problems) for n, v in enumerate(value)]
        return None if any(d is None for d in diag) else sp.diag(*diag)
    if len(value) == 3 and all(isinstance(row, list) and len(row) == 3 for row in value):
        rows = [[parse_expression(f"{path}[{a}][{b}]", v, symbols, problems) for b, v in enumerate(row)]
                for a, row in enumerate(value)]
        if any(e is None for row in rows for e in row):
            return None
        matrix = sp.Matrix(rows)
        if matrix != matrix.T:
            problems.append(f"{path}: got {describe(value)}; expected a symmetric 3x3 inertia tensor")
            return None
        return matrix
    problems.append(f"{path}: got {describe(value)}; expected a number J (J on every axis), [Ixx, Iyy, Izz] or a "
                    f"symmetric 3x3 list [kg m^2]")
    return None


LINK_KEYS = ("link", "name", "joints", "mass", "com", "inertia")


def _links(rows: Any, symbols, problems) -> dict[int, Link]:
    links: dict[int, Link] = {}
    if not isinstance(rows, list) or not rows:
        problems.append(f"mechanism.links: got {describe(rows)}; expected a list of link rows, "
                        f"e.g. - {{link: 0, joints: [R, [R, [l1, 0, 0]]]}}")
        return links
    names: dict[str, str] = {}
    for n, row in enumerate(rows):
        path = f"mechanism.links[{n}]"
        if not isinstance(row, dict):
            problems.append(f"{path}: got {describe(row)}; expected a mapping with keys {', '.join(LINK_KEYS)}")
            continue
        for key in row:
            if key not in LINK_KEYS:
                problems.append(f"{path}.{key}: unknown key; valid keys here: {', '.join(LINK_KEYS)}")
        number = row.get("link", n)
        if isinstance(number, bool) or not isinstance(number, int) or number < 0:
            problems.append(f"{path}.link: got {describe(number)}; expected a link number (integer >= 0)")
            continue
        if number in links:
            problems.append(f"{path}.link: got {number}; link {number} is already defined by {links[number].path}; "
                            f"expected each link number once")
            continue
        name = row.get("name")
        if name is not None:
            if not valid_name(name):
                problems.append(f"{path}.name: got {describe(name)}; expected a name (letter, then letters, digits, _)")
                name = None
            elif name in names:
                problems.append(f"{path}.name: got {name!r}; already the name of {names[name]}; expected unique names")
                name = None
            else:
                names[name] = path
        joints_raw = row.get("joints")
        joints: list[JointFrame] = []
        if not isinstance(joints_raw, list) or not joints_raw:
            problems.append(f"{path}.joints: got {describe(joints_raw)}; expected a list of joint frames, "
                            f"e.g. [R, [R, [l1, 0, 0]]]")
        else:
            points = set()
            for k, entry in enumerate(joints_raw):
                frame = _joint(f"{path}.joints[{k}]", number, k + 1, entry, symbols, problems)
                if frame is None:
                    continue
                if frame.point is not None:
                    if frame.point in points:
                        problems.append(f"{path}.joints[{k}]: point name {frame.point!r} used twice on this link")
                    points.add(frame.point)
                joints.append(frame)
            if len(joints) != len(joints_raw):
                joints = []  # reported; the mass properties are still checked
        mass = parse_expression(f"{path}.mass", row.get("mass", 0), symbols, problems)
        com_raw = row.get("com", [0, 0, 0])
        com = None
        if not isinstance(com_raw, list) or len(com_raw) != 3:
            problems.append(f"{path}.com: got {describe(com_raw)}; expected [x, y, z] in the link frame [m]")
        else:
            com = tuple(parse_expression(f"{path}.com[{a}]", v, symbols, problems) for a, v in enumerate(com_raw))
        inertia = _inertia(f"{path}.inertia", row.get("inertia"), symbols, problems)
        if mass is None or com is None or any(c is None for c in com) or inertia is None or not joints:
            continue
        links[number] = Link(number, name, joints, mass, com, inertia, path)
    return links


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


def _couplings(rows: Any, links: dict[int, Link], problems: list[str]) -> list[Coupling]:
    out: list[Coupling] = []
    if not isinstance(rows, list) or not rows:
        problems.append(f"mechanism.couplings: got {describe(rows)}; expected a list of rows [i, k, j, m] "
                        f"(joint k of link i coupled with joint m of link j)")
        return out
    by_name = {link.name: number for number, link in links.items() if link.name}
    used: dict[tuple[int, int], str] = {}
    names: dict[str, str] = {}
    for n, row in enumerate(rows):
        path = f"mechanism.couplings[{n}] (coupling {n + 1})"
        name = None
        spec = row
        if isinstance(row, dict):
            unknown = [k for k in row if k not in ("name", "couple")]
            if unknown:
                problems.append(f"{path}.{unknown[0]}: unknown key; valid keys here: name, couple")
                continue
            name, spec = row.get("name"), row.get("couple")
            if name is not None and (not valid_name(name) or name in names):
                why = f"already the name of {names[name]}" if name in names else "not a usable name"
                problems.append(f"{path}.name: got {describe(name)}; {why}; expected a unique name (letter, then "
                                f"letters, digits, _)")
                continue
            if name is not None:
                names[name] = path
        if not isinstance(spec, list) or len(spec) != 4:
            problems.append(f"{path}: got {describe(spec)}; expected [i, k, j, m] (link i, its joint k; link j, its "
                            f"joint m) or {{name: NAME, couple: [i, k, j, m]}}")
            continue
        ends = []
        for link_raw, joint_raw in ((spec[0], spec[1]), (spec[2], spec[3])):
            number = _resolve_link(link_raw, links, by_name)
            if number is None:
                known = ", ".join(str(x) for x in sorted(links)) + (
                    f" or a name ({', '.join(sorted(by_name))})" if by_name else "")
                problems.append(f"{path}: link {describe(link_raw)} is not defined in mechanism.links; expected "
                                f"one of {known}")
                break
            link = links[number]
            index = _resolve_joint(joint_raw, link)
            if index is None:
                pts = [f.point for f in link.joints if f.point]
                extra = f" or a point name ({', '.join(pts)})" if pts else ""
                problems.append(f"{path}: {link.label} has no joint {describe(joint_raw)}; expected a joint number "
                                f"1..{len(link.joints)}{extra} (see {link.path}.joints)")
                break
            ends.append((number, index))
        if len(ends) != 2:
            continue
        (i, k), (j, m) = ends
        if i == j:
            problems.append(f"{path}: couples link {i} with itself; expected two different links")
            continue
        clash = False
        for end in ends:
            if end in used:
                problems.append(f"{path}: joint {end[1]} of link {end[0]} is already coupled by {used[end]}; "
                                f"expected each joint frame in one coupling only")
                clash = True
        if clash:
            continue
        a, b = links[i].joints[k - 1], links[j].joints[m - 1]
        if a.type != b.type:
            problems.append(f"{path}: couples a {a.type} joint (link {i}, joint {k}) with a {b.type} joint "
                            f"(link {j}, joint {m}); expected two joint frames of the same type")
            continue
        used[(i, k)] = used[(j, m)] = path
        out.append(Coupling(n + 1, name, i, k, j, m, a.type, path))
    return out


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
    values, symbols = _parameters(mechanism.get("parameters"), problems)
    links = _links(mechanism.get("links"), symbols, problems)
    if links and 0 not in links and len(problems) == start:
        problems.append("mechanism.links: no link 0; expected the fixed link (the frame of reference) numbered 0")
    couplings = _couplings(mechanism.get("couplings"), links, problems) if links else []
    gravity_raw = mechanism.get("gravity")
    gravity = (sp.Integer(0),) * 3
    if gravity_raw is not None:
        if not isinstance(gravity_raw, list) or len(gravity_raw) != 3:
            problems.append(f"mechanism.gravity: got {describe(gravity_raw)}; expected [gx, gy, gz] in the fixed "
                            f"frame [m/s^2], e.g. [0, -9.81, 0]")
        else:
            gravity = tuple(parse_expression(f"mechanism.gravity[{a}]", v, symbols, problems)
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
    return Tables(links=links, couplings=couplings, parameters=values, symbols=symbols, gravity=gravity,
                  drive=drive, label=label)
