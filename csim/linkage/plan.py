"""A linkage's plain data, filed beside its cached build, so that a warm run imports no sympy.

A run of a link-coupling case reads, of everything :func:`csim.linkage.model.build_linkage`
derives, names and numbers only: the joint variables and their assembled start, the drives'
names and their expressions as text, the kept and removed cut-joint equations' labels,
units and reactions, the tree and cut joints and the links with mass, the cache keys under
which the numeric functions of the model, the constraint watch and the reactions are filed,
and the definition's plain data (:class:`csim.model.light.LightDefinition`). A
:class:`LinkagePlan` holds exactly these; it is filed as JSON
(``<cache>/linkage/<build key>_plan.json``) beside the pickled linkage, under the same
:func:`~csim.linkage.lambdacache.build_key` (the sections as written, the build's options,
sympy's version and every csim source), with a hash of its content. A warm run
(:func:`load_linkage`) reads it instead of unpickling the symbolic linkage (sympy: 0.2-0.35 s
of a one-second run); a cold run, or ``CSIM_LINKAGE_CACHE=0``, builds the linkage as before
and takes its plan from it (:meth:`csim.linkage.model.Linkage.plan`), so that both run the
same numeric code on the same numbers. A missing, damaged, foreign or stale plan file is
built again; the symbolic linkage is read back (:meth:`LightLinkage.full`) only where a
numeric function is not in the cache.

Nothing here imports sympy.
"""
from __future__ import annotations

import contextlib
import copy
import hashlib
import json
import re
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from pathlib import Path

import numpy as np

from csim.errors import CacheError
from csim.io.atomic import write_atomically
from csim.linkage.lambdacache import MAX_LINKAGES, build_key, cache_enabled, cached_lambdify, evict
from csim.model.cache import cache_dir
from csim.model.light import LightDefinition

#: bump when the plan's content changes
PLAN_VERSION = "4"

#: the status of a cut-joint equation (:class:`csim.linkage.constraints.Equation`)
KEPT, ZERO, DEPENDENT = "kept", "identically zero", "dependent"


@dataclass(frozen=True)
class EquationRecord:
    """A cut-joint equation's plain data (its expression is on :class:`csim.linkage.constraints.Equation`).

    Attributes
    ----------
    joint : int
        The number of its cut joint (coupling).
    name : str
        The joint's name, else its number, as the labels write it.
    component, reaction, status, unit : str
        As :class:`~csim.linkage.constraints.Equation`'s (``unit``: ``"m"`` or ``"1"``).
    """

    joint: int
    name: str
    component: str
    reaction: str
    status: str
    unit: str

    @property
    def label(self) -> str:
        """``joint NAME COMPONENT``, as :attr:`csim.linkage.constraints.Equation.label`."""
        return f"joint {self.name} {self.component}"


@dataclass(frozen=True)
class JointRecord:
    """A joint's plain data: joint k of link i with joint m of link j (:class:`csim.linkage.tables.Coupling`).

    Attributes
    ----------
    number : int
    name : str or None
    type : str
    i, k, j, m : int
    variables : tuple of str
        Its joint variables' names (a tree joint's; a cut joint has none).
    below : tuple of int
        A tree joint's subtree, the links beyond it away from link 0 (:func:`csim.linkage.topology.subtree`).
    """

    number: int
    name: str | None
    type: str
    i: int
    k: int
    j: int
    m: int
    variables: tuple[str, ...] = ()
    below: tuple[int, ...] = ()


@dataclass
class LinkagePlan:
    """Everything a run reads of a :class:`csim.linkage.model.Linkage`, as plain data (see the module docstring).

    Attributes
    ----------
    variables : list of str
        The joint variables' names, the model's coordinates in their order.
    start : dict str -> float
        The assembled given configuration.
    drive_names : list of str
        The driven joint variables, in the drives' order (the symbolic linkage's ``drive`` maps
        each to its expression).
    drive_expressions : list of str
        Each drive as sympy's ``srepr``, in ``t`` and the parameters (the compiled drive rows').
    drive_parameters : list of str
        The parameters the drives read.
    drive_substituted : list of str
        Those of them whose values the compiled drive rows take, where the others stay parameters of
        the model: those in an exponent (a drive w t^n: differentiated with n a symbol, f'' = n (n - 1)
        w t^(n - 2) is 0 * inf at t = 0 for n = 1), and those in a term not finite at t = 0 (b t^1.5
        with b = 0: f'' = 0.75 b / sqrt(t)) (:func:`csim.linkage.model._drive_parameters_put_in`).
    dof : int
    planar : bool
    parameters : dict str -> float
        The tables' parameter values [SI], in their order (the numeric functions' parameter vector).
    link_labels : dict int -> str
    mass_links : list of int
        The moving links with mass or inertia, ascending.
    equations : list of EquationRecord
        Every generated cut-joint equation, with its status.
    generic_rank : int
    cut_joints, tree_joints : list of JointRecord
    definition : dict
        The plain data of its definition (:func:`csim.model.light.snapshot`).
    normal_joint : list of two int, or None
        [i, k] of a joint frame whose z axis is a planar mechanism's normal (an R joint's).
    cache_key, build_key : str
        As :class:`~csim.linkage.model.Linkage`'s.
    """

    variables: list[str]
    start: dict[str, float]
    drive_names: list[str]
    drive_expressions: list[str]
    drive_parameters: list[str]
    drive_substituted: list[str]
    dof: int
    planar: bool
    parameters: dict[str, float]
    link_labels: dict[int, str]
    mass_links: list[int]
    equations: list[EquationRecord]
    generic_rank: int
    cut_joints: list[JointRecord]
    tree_joints: list[JointRecord]
    definition: dict
    normal_joint: list[int] | None = None
    cache_key: str = ""
    build_key: str = ""

    def to_json(self) -> dict:
        """The plan as JSON data (the keys of ``link_labels`` become strings)."""
        data = asdict(self)
        data["link_labels"] = {str(k): v for k, v in self.link_labels.items()}
        return data

    @classmethod
    def from_json(cls, data: dict) -> LinkagePlan:
        """The plan of :meth:`to_json`'s data (raises KeyError, TypeError or ValueError on anything else).

        It checks the field names and converts the containers it rebuilds, not every value's
        type: the data is what :func:`write_plan` filed, with a hash of its content that
        :func:`read_plan` checks. A file damaged by accident fails that check; one forged with
        a recomputed hash (someone who can write the cache can write its code too) is out of
        scope.
        """
        if set(data) != {f.name for f in fields(cls)}:
            raise KeyError(f"the fields of a linkage plan, got {sorted(data)}")
        out = cls(**data)
        out.link_labels = {int(k): str(v) for k, v in data["link_labels"].items()}
        out.equations = [EquationRecord(**e) for e in data["equations"]]
        out.cut_joints = [_joint(j) for j in data["cut_joints"]]
        out.tree_joints = [_joint(j) for j in data["tree_joints"]]
        out.start = {str(k): float(v) for k, v in data["start"].items()}
        out.parameters = {str(k): float(v) for k, v in data["parameters"].items()}
        return out


def _joint(data: dict) -> JointRecord:
    return JointRecord(**{**data, "variables": tuple(data["variables"]), "below": tuple(data["below"])})


def _digest(data: dict) -> str:
    return hashlib.sha256(json.dumps(data, sort_keys=True).encode()).hexdigest()


def plan_path(key: str) -> Path:
    """Where the plan of the build ``key`` is filed (beside ``<key>_linkage.pickle``)."""
    return cache_dir() / "linkage" / f"{key}_plan.json"


def read_plan(key: str) -> LinkagePlan | None:
    """The plan filed under the build ``key``, or None: none, or one that is damaged, of another
    version, filed under another key or not matching its hash (built again by the caller)."""
    try:
        filed = json.loads(plan_path(key).read_text())
        if filed["version"] != PLAN_VERSION or filed["key"] != key or filed["digest"] != _digest(filed["plan"]):
            return None
        plan = LinkagePlan.from_json(filed["plan"])
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    return plan if plan.build_key == key else None


def write_plan(plan: LinkagePlan) -> None:
    """File ``plan`` under its build key (a cache that cannot be written costs the next run the
    read-back; a value JSON cannot hold is a programming error, and raises)."""
    data = plan.to_json()
    filed = {"version": PLAN_VERSION, "key": plan.build_key, "digest": _digest(data), "plan": data}
    path = plan_path(plan.build_key)
    with contextlib.suppress(OSError):
        write_atomically(path, json.dumps(filed).encode())
        evict(path.parent, "*_plan.json", MAX_LINKAGES)


@dataclass
class Builder:
    """What builds a case's symbolic linkage: :func:`csim.linkage.model.build_linkage` of copies
    of its sections as given (the case changes its own afterwards), read back from the cache
    where it was built before. Picklable, so that a :class:`LightLinkage` sent to a worker
    process can build its linkage there."""

    mechanism: dict
    initial: dict | None
    tol: float
    max_iter: int

    def __post_init__(self):
        self.mechanism, self.initial = copy.deepcopy(self.mechanism), copy.deepcopy(self.initial)

    @property
    def key(self) -> str:
        """The :func:`~csim.linkage.lambdacache.build_key` of the build ("": not cached)."""
        return build_key(self.mechanism, self.initial, dict(tol=self.tol, max_iter=self.max_iter, definition=True)) \
            if cache_enabled() else ""

    def __call__(self):
        from csim.linkage.model import build_linkage  # sympy

        return build_linkage(copy.deepcopy(self.mechanism), copy.deepcopy(self.initial), tol=self.tol,
                             max_iter=self.max_iter)


def load_linkage(mechanism: dict, initial: dict | None, tol: float = 1e-12, max_iter: int = 50) -> LightLinkage:
    """The linkage of a case's ``mechanism`` and ``initial`` sections for a run: read from its
    plan where one is filed under their build key (no sympy), else built
    (:func:`csim.linkage.model.build_linkage`, which raises :class:`~csim.errors.CaseError` on
    bad tables) and its plan filed.

    Parameters
    ----------
    mechanism, initial : dict
        The sections, as :func:`~csim.linkage.model.build_linkage` takes them.
    tol, max_iter : float, int
        Newton settings of the assembly.

    Returns
    -------
    LightLinkage
        With its symbolic linkage where it was built here (:attr:`LightLinkage.loaded`).

    Raises
    ------
    CaseError
        Bad tables, naming the row (:func:`~csim.linkage.model.build_linkage`; only where
        the linkage is built: a plan is filed for a build that succeeded).
    """
    builder = Builder(mechanism, initial, tol, max_iter)
    key = builder.key
    plan = read_plan(key) if key else None
    if plan is not None:
        with contextlib.suppress(KeyError, TypeError, ValueError):  # a definition's data it cannot read: built again
            return LightLinkage(plan, builder)
    linkage = builder()
    plan = linkage.plan()
    if key and plan.build_key == key:
        write_plan(plan)
    return LightLinkage(plan, builder, linkage)


#: the fields of the plan a :class:`LightLinkage` answers as its own attributes
PLAN_FIELDS = ("drive_names", "dof", "planar", "start", "parameters", "cache_key", "build_key")


class LightLinkage:
    """A linkage for a run: its plan (:class:`LinkagePlan`), and its symbolic
    :class:`~csim.linkage.model.Linkage` built (read back from the cache) on first use.

    The plan's fields named in :data:`PLAN_FIELDS` (``drive_names``: the driven joint
    variables' names; ``parameters``: the tables' values [SI], a value written with a unit
    converted; ``dof``, ``start``, ...), the properties and methods below are read without
    sympy; any other attribute (``drive``: each driven variable's expression, ``tables``,
    ``topology``, ``frames``, ``reduction``, ...) is the symbolic linkage's (:meth:`full`).

    Parameters
    ----------
    plan : LinkagePlan
    builder : callable () -> Linkage
        Builds the symbolic linkage (:class:`Builder`).
    full : Linkage, optional
        The symbolic linkage, where already built.
    """

    def __init__(self, plan: LinkagePlan, builder: Callable, full=None):
        self.plan = plan
        self._builder = builder
        self._full = None
        self.definition = LightDefinition(plan.definition, self._full_definition)
        if full is not None:
            self._attach(full)

    def full(self):
        """The symbolic linkage (built, or read back from the cache, with sympy, on the first call).

        Raises
        ------
        CacheError
            It does not match the plan (:meth:`_attach`).
        """
        if self._full is None:
            self._attach(self._builder())
        return self._full

    def _attach(self, full) -> None:
        """Take ``full`` as the symbolic linkage, after a cheap check that it is the plan's
        (:func:`_differences`): the plan is read from its own file, the symbolic linkage from its
        pickle or a new build, and a plan filed by another build would have run numbers that are
        not this linkage's. Such a plan is removed (the next run builds it again) and the run
        stops. The definition's plain fields a case set are set on its symbolic one
        (:meth:`csim.model.light.LightDefinition.attach`)."""
        differ = _differences(self.plan, full)
        if differ:
            if self.plan.build_key:
                with contextlib.suppress(OSError):
                    plan_path(self.plan.build_key).unlink()
            raise CacheError(f"the symbolic linkage does not match its plan (csim.linkage.plan): "
                               f"{', '.join(differ)} differ; the plan was removed from the cache, and the next "
                               f"run builds it again")
        self._full = full
        self.definition.attach(full.definition)

    @property
    def loaded(self) -> bool:
        """Whether the symbolic linkage has been built or read back (a warm run's has not)."""
        return self._full is not None

    def _full_definition(self):
        return self.full().definition

    def __getattr__(self, attr: str):
        # only for what is not set on the instance or the class: the plan's fields it answers, else the symbolic parts
        if attr.startswith("_"):
            raise AttributeError(attr)
        if attr in PLAN_FIELDS:
            return getattr(self.plan, attr)
        return getattr(self.full(), attr)

    def __getstate__(self) -> dict:
        """The fields, less the numeric functions the reactions keep on it (``_reaction_*``: closures)."""
        return {k: v for k, v in vars(self).items() if not k.startswith("_reaction_")}

    # -- the plan's data ------------------------------------------------------------------
    @property
    def has_mass(self) -> bool:
        """Whether a moving link has mass or inertia."""
        return bool(self.plan.mass_links)

    @property
    def variable_names(self) -> list[str]:
        """The joint variables' names, the model's coordinates in their order."""
        return self.plan.variables

    @property
    def driven_indices(self) -> list[int]:
        """The driven joint variables' indices among :attr:`variable_names`, in the drives' order."""
        return [self.plan.variables.index(n) for n in self.plan.drive_names]

    @property
    def redundant(self) -> bool:
        """Whether equations were removed as dependent (an overconstrained mechanism)."""
        return any(e.status == DEPENDENT for e in self.plan.equations)

    @property
    def kept(self) -> list[EquationRecord]:
        """The kept cut-joint equations, the model's constraint rows in their order."""
        return [e for e in self.plan.equations if e.status == KEPT]

    @property
    def equation_labels(self) -> list[str]:
        """The labels of :attr:`kept` (``joint NAME COMPONENT``)."""
        return [e.label for e in self.kept]

    # -- numeric functions ----------------------------------------------------------------
    def drive_function(self, parameters: dict[str, float]) -> Callable[[float], tuple]:
        """t -> (u, ud, udd) at the given parameter values (:func:`drive_function`)."""
        return drive_function(self.cache_key, sorted(self.plan.parameters), parameters,
                              lambda names, values: self.full().drive_rows(names, values))

    def drive_expressions(self, parameters: dict[str, float], keep: list[str]) -> list[str]:
        """Each drive as sympy's ``srepr``, in ``t`` and the parameters named in ``keep``
        (:meth:`csim.linkage.model.Linkage.drive_expressions`), but for those of ``drive_substituted``,
        whose values are put in: the filed text (with their values written in, :func:`_with_values`)
        where the drives read no other parameter, else derived with the values of the others put in."""
        substituted = self.plan.drive_substituted
        keep = [name for name in keep if name not in substituted]
        if set(self.plan.drive_parameters) - set(keep) <= set(substituted):
            values = {name: parameters.get(name, self.plan.parameters.get(name)) for name in substituted}
            return [_with_values(text, values) for text in self.plan.drive_expressions]
        return self.full().drive_expressions(parameters, keep)

    def constraint_watch(self, parameters, par: np.ndarray):
        """Every non-trivial cut-joint equation (:func:`csim.linkage.watch.constraint_watch`) at the
        run's parameter values: ``par`` (n_par,) of the definition's ``parameters`` (a
        sequence of :class:`~csim.model.definition.Parameter`), the tables' values for the others.

        The watch's functions are filed under the build key (``<key>_watch_*.py``), their
        parameters in the order of the plan's ``parameters``: this is their one writer, so a
        file read back takes its parameters in the order it was derived with."""
        from csim.linkage.watch import constraint_watch

        values = dict(self.plan.parameters)
        values.update({p.name: v for p, v in zip(parameters, par) if p.name in values})

        def symbolic():
            full = self.full()
            return full.reduction.equations, full.topology.variables, [full.tables.symbols[n] for n in values]

        return constraint_watch(self.plan.equations, len(self.plan.variables), self.plan.generic_rank,
                                list(values.values()), self.build_key, symbolic)


def _with_values(text: str, values: dict[str, float]) -> str:
    """A drive's ``srepr`` with each parameter of ``values`` written in as the Float of its value (as sympy's
    ``subs`` of a float puts it in, 17 digits round-trip), without sympy: a warm run's drive rows."""
    for name, value in values.items():
        symbol = re.compile(r"Symbol\('" + re.escape(name) + r"'(?:, \w+=(?:True|False))*\)")
        text = symbol.sub(f"Float('{float(value)!r}', precision=53)", text)
    return text


def _differences(plan: LinkagePlan, full) -> list[str]:
    """What of ``plan`` the symbolic linkage ``full`` does not match: its build key (where both
    have one), joint variables, degrees of freedom, rank, cut-joint equations and their status."""
    checks = {
        "build_key": not (plan.build_key and full.build_key) or plan.build_key == full.build_key,
        "variables": plan.variables == full.variable_names,
        "dof": plan.dof == full.dof,
        "generic_rank": plan.generic_rank == full.reduction.generic_rank,
        "equations": plan.equations == [e.record() for e in full.reduction.equations],
    }
    return [name for name, same in checks.items() if not same]


def drive_function(key: str, names: list[str], parameters: dict[str, float],
                   rows: Callable[[list[str], list[float]], tuple]) -> Callable[[float], tuple]:
    """t -> (u, ud, udd), each (d,) [rad or m, per s, per s^2], of a linkage's drives at the given
    parameter values.

    Parameters
    ----------
    key : str
        The linkage's :func:`~csim.linkage.lambdacache.linkage_key` ("": not cached).
    names : list of str
        Every parameter of the tables, sorted.
    parameters : dict str -> float
        Their values, by name.
    rows : callable (names, values) -> (args, exprs)
        The symbolic work (:meth:`csim.linkage.model.Linkage.drive_rows`), done only when the
        function is not cached: it is filed under a hash of the values
        (:func:`csim.linkage.lambdacache.cached_lambdify`).
    """
    values = [float(parameters[n]) for n in names]
    tag = hashlib.sha256(repr(values).encode()).hexdigest()[:16]
    f = cached_lambdify(key or None, f"drive_{tag}", lambda: rows(names, values))

    def drive(t: float):
        u, ud, udd = f([t])
        return (np.array(u, dtype=float), np.array(ud, dtype=float), np.array(udd, dtype=float))

    return drive
