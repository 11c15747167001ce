"""From the two tables to a :class:`MechanismDefinition`: the link-coupling pipeline.

tables -> topology (tree, chains, cut joints, joint variables) -> frames (transforms) ->
constraints (cut-joint equations, independent set, DOF) -> MechanismDefinition:

- coordinates: the joint variables of the tree joints;
- constraints: the independent cut-joint equations;
- kinetic energy sum 1/2 m |v_C|^2 + 1/2 omega^T I omega over the links with mass, with
  omega in link axes accumulated along the tree, and potential energy -sum m g . r_C plus
  the potentials of the force elements (springs, :mod:`csim.linkage.forces`);
- loads: the non-conservative force elements (dampers, actuators, applied forces);
- observables: the global coordinates of every named point that moves;
- a Drawing through the joint-frame origins of each link (x, y; a spatial mechanism is
  drawn in its x-y projection).

The result is handled by :mod:`csim.model` and the solvers like a hand-written mechanism.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import sympy as sp

from csim.errors import CaseError
from csim.linkage.constraints import (
    Equation,
    Plane,
    Reduction,
    cut_joint_equations,
    plane_of_motion,
    reduce_equations,
)
from csim.linkage.expressions import MAX_MAGNITUDE, evaluate, parse_expression, value_problem
from csim.linkage.forces import Contribution, Geometry, build_forces
from csim.linkage.frames import Frames, build_frames
from csim.linkage.inertia import check_inertia
from csim.linkage.joints import JOINT_TYPES
from csim.linkage.lambdacache import build_key, cache_enabled, cached_build, linkage_key
from csim.linkage.plan import JointRecord, LinkagePlan
from csim.linkage.recursive import recursive_terms
from csim.linkage.tables import Coupling, Tables, parse_tables
from csim.linkage.topology import Topology, analyse, grubler_kutzbach, subtree
from csim.linkage.transforms import simplify_entry
from csim.model.cache import definition_key, remember_key
from csim.model.definition import Drawing, MechanismDefinition, Observable, Parameter
from csim.model.derive import drive_rates
from csim.model.light import snapshot
from csim.model.recursive import sparse_jacobian
from csim.quantities import convert, is_quantity
from csim.schema import describe, finite_number

T = sp.Symbol("t", real=True)


@dataclass
class Linkage:
    """Everything csim derives from a link-coupling description.

    Attributes
    ----------
    tables, topology, frames, reduction
        The stages (see the module docstring).
    planar : bool
    grubler : int
        Grubler-Kutzbach mobility count (planar formula when ``planar``).
    dof : int
        Actual degrees of freedom: number of joint variables minus the generic rank.
    drive : dict variable name -> sympy expression of t and parameters
    drive_source : dict variable name -> str
        Each drive as the user wrote it (``"0.5773 + 0.05*sin(2*pi*t)"``), for reports.
    start : dict variable name -> float
        The assembled given configuration.
    definition : MechanismDefinition
    forces : Contribution
        What ``mechanism.forces`` adds: potential [J], loads and observables.
    cache_key : str
        Files the numeric functions derived from the linkage after a run (the reactions).
    build_key : str
        Files the linkage itself and the functions that depend on how it was assembled (the
        constraint watch): :func:`csim.linkage.lambdacache.build_key` ("": not cached).
    definition_key : str
        :func:`csim.model.cache.definition_key` of ``definition`` ("": none), kept so that a
        linkage read back from the cache need not print its definition again to find it.
    """

    tables: Tables
    topology: Topology
    frames: Frames
    reduction: Reduction
    planar: bool
    grubler: int
    dof: int
    drive: dict[str, sp.Expr]
    start: dict[str, float]
    definition: MechanismDefinition | None = None
    notes: list[str] = field(default_factory=list)
    drive_source: dict[str, str] = field(default_factory=dict)
    forces: Contribution = field(default_factory=Contribution)
    #: :func:`csim.linkage.lambdacache.linkage_key` of the mechanism ("": its functions are not cached)
    cache_key: str = ""
    #: :func:`csim.linkage.lambdacache.build_key` of the sections it was built from ("": not cached)
    build_key: str = ""
    definition_key: str = ""

    def __getstate__(self) -> dict:
        """The fields, less the numeric functions the reactions keep on it (``_reaction_*``,
        closures: a linkage that has run is sent to a worker process or filed again without them)."""
        return {k: v for k, v in vars(self).items() if not k.startswith("_reaction_")}

    @property
    def variable_names(self) -> list[str]:
        return [v.name for v in self.topology.variables]

    def drive_rows(self, names: list[str], values: list[float]) -> tuple[list, list]:
        """The drives and their first two derivatives in t, with the parameters ``names`` given
        ``values`` (:func:`csim.model.derive.drive_rates`): the arguments ([t]) and the three rows,
        which :func:`csim.linkage.plan.drive_function` lambdifies (and files: a warm run of the same
        case does no symbolic work for them; the derivation and lambdify took 50 ms of each driven run).

        Each value is put in with 17 digits (it reads back as the same float, as the compiled drive
        rows have it): with the parameters as symbols, the rates of w t^n with n = 1 are 0/0 and
        0 * inf at t = 0 (helper-28).
        """
        subs = {self.tables.symbols[n]: sp.Float(v, 17) for n, v in zip(names, values)}
        exprs = [sp.sympify(e).subs(subs) for e in self.drive.values()]
        return [[T]], [exprs, *drive_rates(exprs, T)]

    def drive_expressions(self, parameters: dict[str, float], keep: list[str]) -> list[str]:
        """Each drive f_j(t) as sympy's ``srepr``, for the compiled model's drive rows
        (:class:`csim.fast.module.Drives`): in the time symbol ``t`` and the parameters named in
        ``keep`` (the model's, read from its parameter vector), any other parameter's value put in."""
        subs = {self.tables.symbols[k]: v for k, v in parameters.items() if k in self.tables.symbols and k not in keep}
        return [sp.srepr(sp.sympify(e).subs(subs)) for e in self.drive.values()]

    def plan(self) -> LinkagePlan:
        """Its plain data (:class:`csim.linkage.plan.LinkagePlan`): what a run reads of it (a linkage
        built with its definition, as a case's is: ``build_linkage(..., definition=True)``)."""
        tables, topology = self.tables, self.topology

        def record(c: Coupling, below: set[int] = frozenset()) -> JointRecord:
            return JointRecord(c.number, c.name, c.type, c.i, c.k, c.j, c.m,
                               tuple(v.name for v in topology.variables_of(c)), tuple(sorted(below)))

        child = {e.coupling.number: n for n, e in topology.edges.items()}
        normal = next((c for c in tables.couplings if JOINT_TYPES[c.type].planar_axis == "normal"), None)
        drives = [sp.sympify(e) for e in self.drive.values()]
        used = set().union(*(e.free_symbols for e in drives))
        substituted = _drive_parameters_put_in(drives)
        return LinkagePlan(
            variables=self.variable_names, start=dict(self.start), drive_names=list(self.drive),
            drive_expressions=[sp.srepr(e) for e in drives],
            drive_parameters=[n for n, symbol in tables.symbols.items() if symbol in used],
            drive_substituted=[n for n, symbol in tables.symbols.items() if symbol in substituted],
            dof=self.dof, planar=self.planar, parameters=dict(tables.parameters),
            link_labels={n: link.label for n, link in sorted(tables.links.items())},
            mass_links=[n for n, link in sorted(tables.links.items()) if n != 0 and link.has_mass],
            equations=[e.record() for e in self.reduction.equations], generic_rank=self.reduction.generic_rank,
            cut_joints=[record(c) for c in topology.cut_joints],
            tree_joints=[record(c, subtree(topology, child[c.number])) for c in topology.tree_joints],
            normal_joint=None if normal is None else [normal.i, normal.k],
            definition=snapshot(self.definition), cache_key=self.cache_key, build_key=self.build_key)


def _drive_parameters_put_in(drives: list) -> set:
    """The parameters whose values the compiled drive rows must take (:attr:`LinkagePlan.drive_substituted`):
    those in an exponent (w t^n: differentiated with n a symbol, n (n - 1) w t^(n - 2) is 0 * inf at
    t = 0 for n = 1), and those in a term of a drive or its first two derivatives that is not finite at
    t = 0 (b t^1.5: 0.75 b / sqrt(t) is 0 * inf there for b = 0, where the Python path, which puts every
    value in first, runs w t + b t^1.5 as w t; for b != 0 the case is rejected, csim.case)."""
    put_in = set().union(*(p.exp.free_symbols for e in drives for p in e.atoms(sp.Pow)))
    for row in (drives, *drive_rates(drives, T)):
        for expr in row:
            for term in sp.Add.make_args(sp.expand(expr)):
                if term.subs(T, 0).has(sp.zoo, sp.oo, -sp.oo, sp.nan):
                    put_in |= term.free_symbols - {T}
    return put_in


def _resolve_drive(tables: Tables, problems: list[str]) -> tuple[dict[int, list], dict]:
    """Drive keys naming a coupling (number or name) -> {coupling number: values per joint
    variable (None: not driven)}; the other keys are returned as pending (variable names?)."""
    by_name = {c.name: c for c in tables.couplings if c.name}
    by_number = {c.number: c for c in tables.couplings}
    out: dict[int, list] = {}
    pending = {}
    for key, value in tables.drive.items():
        path = f"mechanism.drive.{key}"
        c = by_number.get(key) if isinstance(key, int) and not isinstance(key, bool) else by_name.get(key)
        if c is None:
            pending[key] = value
            continue
        values = value if isinstance(value, list) else [value]
        if len(values) != c.freedoms:
            expected = "a value" if c.freedoms == 1 else f"a list of {c.freedoms} (null: not driven)"
            problems.append(f"{path}: got {describe(value)}; {c.label} has {c.freedoms} joint variable(s); "
                            f"expected {expected}")
            continue
        out[c.number] = values
    return out, pending


def _resolve_variable_keys(tables: Tables, per_coupling: dict[int, list], pending: dict,
                           problems: list[str]) -> None:
    """Drive keys that are joint-variable names (as ``csim describe`` lists them) join
    ``per_coupling``, by their joint and slot."""
    if not pending:
        return
    variables = {v.name: v for v in analyse(tables, set(per_coupling)).variables}
    couplings = ", ".join(str(c.name or c.number) for c in tables.couplings)
    for key, value in pending.items():
        var = variables.get(key)
        if var is None:
            problems.append(f"mechanism.drive.{key}: no such joint; expected a coupling number or name "
                            f"({couplings}) or a joint variable ({', '.join(variables)})")
            continue
        values = per_coupling.setdefault(var.coupling.number, [None] * var.coupling.freedoms)
        values[var.slot] = value


def _drive_expressions(tables, topology, per_coupling, problems) -> tuple[dict[str, sp.Expr], dict[str, str]]:
    """The drives by joint variable: sympy expressions of t and the parameters, and the
    text the user wrote for each."""
    symbols = {**tables.symbols, "t": T}
    drive: dict[str, sp.Expr] = {}
    source: dict[str, str] = {}
    for number, values in per_coupling.items():
        c = next(c for c in tables.couplings if c.number == number)
        if c in topology.cut_joints:
            problems.append(f"mechanism.drive: {c.label} closes a loop of driven joints and was cut; expected "
                            f"driving joints that do not form a closed loop")
            continue
        for var, value in zip(topology.variables_of(c), values):
            if value is None:
                continue
            expr = parse_expression(f"mechanism.drive.{c.name or c.number}", value, symbols, problems, unit=var.unit)
            if expr is not None:
                drive[var.name] = expr
                source[var.name] = value.strip() if isinstance(value, str) else str(value)
    return drive, source


def link_angular_velocities(topology: Topology, frames: Frames) -> dict[int, sp.Matrix]:
    """omega_i in link i's own axes, (3, 1) [rad/s], accumulated from the root."""
    omega = {0: sp.zeros(3, 1)}
    for child in topology.order[1:]:
        edge = topology.edges[child]
        c = edge.coupling
        vs = topology.variables_of(c)
        w_joint = JOINT_TYPES[c.type].angular_velocity([v.symbol for v in vs], [v.velocity for v in vs])
        A_ik = frames.local[(c.i, c.k)][:3, :3]
        R_rel = frames.relative[child][:3, :3]  # child axes in parent axes
        w_rel = A_ik * w_joint if edge.forward else -R_rel * A_ik * w_joint
        omega[child] = (R_rel.T * (omega[edge.parent] + w_rel)).applyfunc(simplify_entry)
    return omega


def energies(tables: Tables, topology: Topology, frames: Frames) -> tuple[sp.Expr, sp.Expr]:
    """Kinetic energy T(q, qd) and potential energy V(q) [J] of the links with mass."""
    q = [v.symbol for v in topology.variables]
    qd = sp.Matrix([v.velocity for v in topology.variables])
    g = sp.Matrix(tables.gravity)
    kinetic, potential = sp.Integer(0), sp.Integer(0)
    omega = None
    for number, link in sorted(tables.links.items()):
        if number == 0 or not link.has_mass:
            continue
        if omega is None:
            omega = link_angular_velocities(topology, frames)
        r_c = (frames.links[number] * sp.Matrix([*link.com, 1]))[:3, 0].applyfunc(simplify_entry)
        v_c = sparse_jacobian(list(r_c), q) * qd if q else sp.zeros(3, 1)
        w = omega[number]
        # left as products of sums: expanding |v_c|^2 grows with the fourth power of a link's
        # depth in the tree (the equations of motion come from csim.linkage.recursive, not
        # from this expression; it is what csim describe, the kinematic model and the model's
        # cache key read)
        kinetic += sp.Rational(1, 2) * link.mass * (v_c.T * v_c)[0] + sp.Rational(1, 2) * (w.T * link.inertia * w)[0]
        potential += -link.mass * (g.T * r_c)[0]
    return kinetic, potential


def _point_name(tables: Tables, link: int, index: int) -> str:
    frame = tables.frame(link, index)
    return frame.point or f"L{link}J{index}"


def drawing_and_observables(tables: Tables, frames: Frames, planar: bool = True) -> tuple[Drawing, list[Observable]]:
    """Joint-frame origins: drawn per link, as (x, y) for a planar mechanism and (x, y, z)
    for a spatial one; named ones recorded as observables."""
    points: dict[str, tuple] = {}
    links, ground = [], []
    observables = []
    seen = set()
    for number, link in sorted(tables.links.items()):
        names = []
        for f in link.joints:
            name = _point_name(tables, number, f.index)
            key = name if name not in points else f"{name}_{number}"
            r = frames.joint_frame(number, f.index)[:3, 3]
            points[key] = (r[0], r[1]) if planar else (r[0], r[1], r[2])
            names.append(key)
            if f.point and f.point not in seen:
                seen.add(f.point)
                for axis, value in zip("xyz", r):
                    if value.free_symbols - set(tables.symbols.values()):
                        where = f"global {axis} of point {f.point} ({tables.link_label(number)})"
                        observables.append(Observable(f"{f.point}_{axis}", value, "m", "m/s", where))
        if number == 0:
            ground = names
        else:
            links.append(tuple(names) if len(names) > 1 else (names[0], names[0]))
    return Drawing(points=points, links=links, ground=ground), observables


def build_linkage(mechanism: dict, initial: dict | None = None, tol: float = 1e-12, max_iter: int = 50,
                  definition: bool = True) -> Linkage:
    """Derive the whole link-coupling model of a case's ``mechanism`` section (read back from
    the cache where the same sections were built before: :func:`csim.linkage.lambdacache.cached_build`).

    Parameters
    ----------
    mechanism : dict
        ``links``, ``couplings``, ``parameters``, optional ``gravity``, ``drive``, ``label``,
        ``forces`` (:mod:`csim.linkage.forces`).
    initial : dict, optional
        The case's ``initial`` section: ``guess`` (start values of joint variables) and, for
        a run without drive, ``q`` (held fixed while assembling).
    tol, max_iter : float, int
        Newton settings of the assembly.
    definition : bool
        Also derive the dynamics model (:attr:`Linkage.definition`: the energies, the
        drawing, the partition); ``csim describe``, which reports the kinematics, leaves it
        out (most of a long chain's derivation time).

    Raises
    ------
    CaseError
        Naming the table row: bad tables (:func:`csim.linkage.tables.parse_tables`), links not
        connected to link 0, an inertia that is not a rigid body's in this (planar or spatial)
        mechanism (:func:`csim.linkage.inertia.check_inertia`), more or fewer drives than
        degrees of freedom ("2 drives for 1 degree of freedom", found with every variable
        free, before the assembly that holds the drives), a mechanism that cannot be
        assembled.
    """
    key = build_key(mechanism, initial, dict(tol=tol, max_iter=max_iter, definition=definition)) \
        if cache_enabled() else ""
    linkage = cached_build(key, lambda: _build_linkage(mechanism, initial, tol, max_iter, definition, key))
    if linkage.definition is not None and linkage.definition_key:
        remember_key(linkage.definition, linkage.definition_key)
    return linkage


def _build_linkage(mechanism: dict, initial: dict | None, tol: float, max_iter: int, definition: bool,
                   key: str) -> Linkage:
    """:func:`build_linkage`, every time (``key``: its build key, recorded)."""
    problems: list[str] = []
    tables = parse_tables(mechanism, problems)
    if tables is None:
        raise CaseError(problems)
    per_coupling, pending = _resolve_drive(tables, problems)
    _resolve_variable_keys(tables, per_coupling, pending, problems)
    topology = analyse(tables, set(per_coupling))
    problems += _chain_problems(tables, topology)
    drive, drive_source = _drive_expressions(tables, topology, per_coupling, problems)
    if problems:
        raise CaseError(problems)
    frames = build_frames(tables, topology)
    forces = build_forces(mechanism.get("forces"), Geometry(tables, topology, frames), problems)
    equations = [e for c in topology.cut_joints for e in cut_joint_equations(c, frames)]
    names = [v.name for v in topology.variables]
    partial = mechanism.get("drive_mode") == "dynamic"  # driven dynamics may leave joints free
    units = {v.name: v.unit for v in topology.variables}
    start, fixed = _start(tables, names, drive, drive_source, initial or {}, problems, partial, units)
    plane = plane_of_motion(tables, frames, topology.variables)
    problems += _inertia_problems(tables, plane)
    if problems:
        raise CaseError(problems)
    # the count of drives (or of initial.q) against the DOF, before the assembly that holds them
    count = ((lambda dof: _drive_count(drive, dof, partial) + _held_count(fixed, dof, drive)) if drive else
             (lambda dof: _held_count(fixed, dof)))
    reduction = reduce_equations(equations, topology.variables, tables, start, fixed, tol=tol, max_iter=max_iter,
                                 mobility_check=count)
    planar = plane is not None
    dof = len(names) - reduction.generic_rank
    linkage = Linkage(tables=tables, topology=topology, frames=frames, reduction=reduction, planar=planar,
                      grubler=grubler_kutzbach(tables, planar), dof=dof, drive=drive,
                      start=dict(zip(names, reduction.q_start.tolist())), notes=list(reduction.notes),
                      drive_source=drive_source, forces=forces,
                      cache_key=linkage_key(mechanism) if cache_enabled() else "", build_key=key)
    if drive and _drive_count(drive, dof, partial):
        raise CaseError(_drive_count(drive, dof, partial))
    if definition:
        linkage.definition = _definition(linkage)
        linkage.definition_key = definition_key(linkage.definition)
    return linkage


#: the most moving links in one chain of the spanning tree, from the ground to a leaf
MAX_CHAIN = 40


def _chain_problems(tables: Tables, topology) -> list[str]:
    """The longest chain of the spanning tree, if it is longer than :data:`MAX_CHAIN`.

    The global transforms are products along the chain and the symbolic work grows faster
    than the square of its length (a planar chain validates in 4 s at 20 links, 28 s at 40,
    over ten minutes at 99 on the 2-core machine), so a long chain is refused before any
    of it is derived; a wide mechanism (the 81 links of the 40-loop N-four-bar hang at most
    two deep) is not.
    """
    depth, path = {0: 0}, {0: [0]}
    for link in topology.order:
        edge = topology.edges.get(link)
        if edge is not None:
            depth[link] = depth[edge.parent] + 1
            path[link] = path[edge.parent] + [link]
    deepest = max(depth, key=depth.get)
    if depth[deepest] <= MAX_CHAIN:
        return []
    labels = [tables.link_label(n) for n in path[deepest]]
    chain = " - ".join([*labels[:3], "...", *labels[-2:]])
    return [f"mechanism.links: a chain of {depth[deepest]} moving links from the ground ({chain}); expected at "
            f"most {MAX_CHAIN} in one chain of the spanning tree (its symbolic transforms grow faster than the "
            f"square of its length: 40 links take about 30 s to derive, 99 more than ten minutes)"]


def _start(tables: Tables, names: list[str], drive: dict[str, sp.Expr], drive_source: dict[str, str],
           initial: dict, problems: list[str], partial: bool = False,
           units: dict[str, str] | None = None) -> tuple[dict[str, float], list[str]]:
    """Start values of the assembly (``initial.guess``, ``initial.q``, the drives at t = 0)
    and the variables it holds fixed: the drives, else ``initial.q``; with ``partial``
    (driven dynamics, which may drive fewer joints than degrees of freedom) the drives and
    the free variables ``initial.q`` names. A value written with a unit (``30 deg``) is
    converted to its variable's unit (``units``); one that cannot be, and a number that is
    not finite, is left to the case's own check of ``initial``."""
    start: dict[str, float] = {}
    for source in ("guess", "q"):
        for key, value in (initial.get(source) or {}).items():
            if key not in names:  # before the assembly, whose failure would hide the typo
                problems.append(f"initial.{source}.{key}: not a joint variable of this mechanism; expected one of "
                                f"{', '.join(names)}")
            elif isinstance(value, (int, float)) and not isinstance(value, bool):
                if finite_number(value):  # else (.nan, 10**400) the case's own check of initial names it
                    start[key] = float(value)
            elif is_quantity(value) and units and key in units:
                number, _ = convert(value, units[key])
                if finite_number(number):
                    start[key] = float(number)
    if not drive:
        return start, [k for k in (initial.get("q") or {}) if k in names]
    at_zero = {**tables.values, T: 0.0}
    for key, expr in drive.items():
        what = value_problem(expr, at_zero)
        if what is not None:
            problems.append(f"mechanism.drive.{key}: got {drive_source[key]!r}; at t = 0 it is {what}; expected a "
                            f"finite real value of magnitude at most {MAX_MAGNITUDE:g}")
        else:
            start[key] = evaluate(expr, at_zero).real
    free = [k for k in (initial.get("q") or {}) if partial and k in names and k not in drive]
    return start, [*drive, *free]


def _inertia_problems(tables: Tables, plane: Plane | None) -> list[str]:
    """The inertia rules that depend on the plane of motion (:func:`csim.linkage.inertia.check_inertia`)."""
    return [problem for number, link in sorted(tables.links.items()) if number != 0
            for problem in check_inertia(link.path, link.label, link.inertia, tables.values,
                                         None if plane is None else plane.link_normals[number])]


def _plural(count: int, word: str) -> str:
    return f"{count} {word}{'' if count == 1 else 's'}"


def _drive_count(drive: dict[str, sp.Expr], dof: int, partial: bool = False) -> list[str]:
    """The problem of driving ``len(drive)`` joint variables of a mechanism with ``dof`` DOF:
    a kinematic analysis needs one drive per degree of freedom; driven dynamics
    (``partial``) at most that many, the others moving freely."""
    n = len(drive)
    if n == dof or (partial and n < dof):
        return []
    if n > dof:
        why, expected = "over-driven: the drives would contradict the constraints", f"at most {dof}" if partial \
            else f"exactly {dof}"
    else:
        why, expected = ("under-driven: a kinematic analysis needs the whole motion prescribed; "
                         "mechanism.drive_mode: dynamic lets the other joints move freely"), f"exactly {dof}"
    return [f"mechanism.drive: {_plural(n, 'drive')} for {_plural(dof, 'degree')} of freedom "
            f"({', '.join(drive)} driven); expected {expected} driven joint variable(s) ({why})"]


def _held_count(held: list[str], dof: int, drive: dict | None = None) -> list[str]:
    """The problem of holding more coordinates (the drives and ``initial.q``) than the
    mechanism has DOF; fewer are reported by the case's own check of ``initial.q``."""
    if len(held) <= dof or (drive and len(drive) > dof):  # too many drives: said by _drive_count
        return []
    free = [name for name in held if not drive or name not in drive]
    driven = f" besides {_plural(len(drive), 'drive')}" if drive else ""
    return [f"initial.q: {_plural(len(free), 'coordinate')}{driven} for {_plural(dof, 'degree')} of freedom "
            f"({', '.join(free)}); expected exactly {dof - len(held) + len(free)} independent coordinate(s)"]


def _definition(linkage: Linkage) -> MechanismDefinition:
    tables, topology, frames = linkage.tables, linkage.topology, linkage.frames
    variables = topology.variables
    kinetic, potential = energies(tables, topology, frames)
    drawing, observables = drawing_and_observables(tables, frames, linkage.planar)
    kept = linkage.reduction.kept
    names = linkage.variable_names
    independent, guess = _partition(linkage)
    return MechanismDefinition(
        name=f"linkage_{tables.label}",
        description=f"link-coupling mechanism {tables.label!r}: {len(tables.links)} links, "
                    f"{len(tables.couplings)} joints, {len(topology.cut_joints)} cut",
        coordinates=[v.symbol for v in variables],
        velocities=[v.velocity for v in variables],
        coordinate_units=[v.unit for v in variables],
        parameters=[Parameter(k, v, "", "parameter of the case file") for k, v in tables.parameters.items()],
        kinetic_energy=kinetic,
        potential_energy=potential + linkage.forces.potential,
        constraints=[e.expression for e in kept],
        loads=list(linkage.forces.loads),
        observables=observables + linkage.forces.observables,
        drawing=drawing,
        default_independent={n: linkage.start[n] for n in independent},
        default_independent_velocities={n: 0.0 for n in independent},
        default_guess={n: linkage.start[n] for n in names if n not in independent},
        recursive=LinkageTerms(tables, topology, frames, kept),  # (picklable: cached)
    )


@dataclass(eq=False)
class LinkageTerms:
    """The ``recursive`` hook of a linkage's :class:`MechanismDefinition`: called, the
    link-by-link terms of its kept cut-joint equations (:func:`csim.linkage.recursive.recursive_terms`);
    it also keeps those equations, so that the kind of each constraint row, and with it its
    unit, can be read from the definition (:attr:`constraint_units`)."""

    tables: Tables
    topology: Topology
    frames: Frames
    kept: list[Equation]

    def __call__(self):
        return recursive_terms(self.tables, self.topology, self.frames, self.kept)

    @property
    def constraint_units(self) -> list[str]:
        """The unit of each constraint row, in the definition's order: ``m`` for a position
        (translation) equation, a component of r_jm - r_ik; ``1`` for an orientation equation,
        a product of two unit axes (:attr:`csim.linkage.constraints.Equation.unit`)."""
        return [e.unit for e in self.kept]


def _partition(linkage: Linkage) -> tuple[list[str], list[str]]:
    """Independent coordinates at the start: the drives, and the columns left out of the
    best-conditioned dependent block among the others (pivoted QR of Phi_q at the assembled
    start)."""
    names = linkage.variable_names
    kept = linkage.reduction.kept
    if linkage.drive and len(linkage.drive) == linkage.dof:
        return list(linkage.drive), [n for n in names if n not in linkage.drive]
    if not kept:
        return names, []
    import scipy.linalg

    tables = linkage.tables
    subs = tables.values
    subs.update({v.symbol: linkage.start[v.name] for v in linkage.topology.variables})
    at = {k: sp.Float(v) for k, v in subs.items()}
    J = np.array(sparse_jacobian([e.expression for e in kept], [v.symbol for v in linkage.topology.variables])
                 .xreplace(at).evalf(), dtype=float)
    # the dependent block among the columns not driven (a drive is independent by definition)
    columns = [i for i, n in enumerate(names) if n not in linkage.drive]
    _, _, piv = scipy.linalg.qr(J[:, columns], pivoting=True)
    dependent = {columns[i] for i in piv[:len(kept)].tolist()}
    return [n for i, n in enumerate(names) if i not in dependent], [n for i, n in enumerate(names) if i in dependent]


def couplings_by_number(tables: Tables) -> dict[int, Coupling]:
    return {c.number: c for c in tables.couplings}
