"""A mechanism definition's plain data, kept on disk, so that a warm run needs no sympy.

Importing sympy and building a mechanism symbolically takes about half a second, which a
run whose generated code is already cached does not need: validating a case file wants
names, units, parameter defaults and the counts, and the code cache wants the key of the
definition. :func:`snapshot` takes these as JSON data and :class:`LightDefinition` answers
them; anything symbolic (coordinates, energies, constraints, drawing, ...) builds the full
:class:`MechanismDefinition` on first use. A registered mechanism's snapshot is filed under
``<cache>/definitions/``, under a hash of its source files (:func:`light_definition`); a
link-coupling mechanism's is part of its linkage's plan (:class:`csim.linkage.plan.LinkagePlan`).
"""
from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

from csim.io.atomic import write_atomically
from csim.io.units import declared_constraint_units
from csim.model.definition import MechanismDefinition, Parameter

#: bump when the snapshot's content changes
SNAPSHOT_VERSION = "3"

#: the files every generated model depends on, beside the mechanism's own module
MODEL_SOURCES = ("definition.py", "derive.py", "codegen.py", "cache.py", "light.py", "recursive.py")


@dataclass(frozen=True)
class LoadInfo:
    """A load's name, units and default values (its coordinate s_k(q) and law are on the full
    definition, :class:`csim.model.definition.Load`).

    A registered mechanism's loads are switched constants (no law) of magnitude 0 unless the
    case names them; a link-coupling mechanism's force elements have a law (``has_law``),
    magnitude 1.
    """

    name: str
    unit: str
    coordinate_unit: str
    description: str
    has_law: bool = False
    magnitude: float = 0.0
    window: tuple[float, float] = (float("-inf"), float("inf"))
    velocity: str = "any"


@dataclass(frozen=True)
class ObservableInfo:
    """An observable's name and units (its expression is on the full definition)."""

    name: str
    unit: str
    rate_unit: str
    description: str


#: the plain fields a case sets on the definition it runs (:func:`csim.case._drive_start`: the
#: drives' rates at t = 0), set on the symbolic definition too (:meth:`LightDefinition.attach`)
CASE_FIELDS = ("default_independent", "default_independent_velocities", "default_guess")


class LightDefinition:
    """The plain data of a :class:`MechanismDefinition`; the rest from the full one, built on demand.

    Attributes read here without sympy: ``name``, ``description``, ``coordinate_names``,
    ``coordinate_units``, ``parameters``, ``parameter_names``, ``loads`` and ``observables``
    (names and units), ``n_constraints``, the ``default_*`` initial values, ``key``
    (the generated code's key, :func:`csim.model.cache.definition_key`) and
    ``constraint_units`` (the unit of each constraint row where the mechanism declares them,
    :func:`csim.io.units.declared_constraint_units`; else None). Every other attribute is the full definition's
    (:meth:`full`).
    """

    def __init__(self, data: dict, factory: Callable[[], MechanismDefinition],
                 full: MechanismDefinition | None = None):
        self.name: str = data["name"]
        self.description: str = data["description"]
        self.coordinate_names: list[str] = list(data["coordinate_names"])
        self.coordinate_units: list[str] = list(data["coordinate_units"])
        self.parameters = [Parameter(**p) for p in data["parameters"]]
        self.loads = [LoadInfo(**{**x, "window": tuple(x["window"])}) for x in data["loads"]]
        self.observables = [ObservableInfo(**x) for x in data["observables"]]
        self.n_constraints: int = int(data["n_constraints"])
        self.default_independent: dict[str, float] = dict(data["default_independent"])
        self.default_independent_velocities: dict[str, float] = dict(data["default_independent_velocities"])
        self.default_guess: dict[str, float] = dict(data["default_guess"])
        self.key: str = data["key"]
        units = data.get("constraint_units")
        self.constraint_units: list[str] | None = None if units is None else [str(u) for u in units]
        self._factory = factory
        self._full = None
        if full is not None:
            self.attach(full)

    def __setattr__(self, name: str, value) -> None:
        super().__setattr__(name, value)
        if name in CASE_FIELDS and self.__dict__.get("_full") is not None:
            setattr(self._full, name, value)

    def attach(self, full: MechanismDefinition) -> None:
        """Take ``full`` as the symbolic definition, with the values of :data:`CASE_FIELDS` set
        here (a case's, :func:`csim.case._drive_start`), so that both answer the same."""
        self._full = full
        for name in CASE_FIELDS:
            if getattr(full, name) != getattr(self, name):
                setattr(full, name, getattr(self, name))

    @property
    def parameter_names(self) -> list[str]:
        return [p.name for p in self.parameters]

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def full(self) -> MechanismDefinition:
        """The symbolic definition (built, with sympy, on the first call)."""
        if self._full is None:
            self.attach(self._factory())
        return self._full

    def __getattr__(self, attr: str):
        # only for what is not set above: the symbolic parts
        if attr.startswith("_"):
            raise AttributeError(attr)
        return getattr(self.full(), attr)


def full_definition(definition: MechanismDefinition | LightDefinition) -> MechanismDefinition:
    """The symbolic definition behind ``definition``."""
    return definition.full() if isinstance(definition, LightDefinition) else definition


def snapshot(definition: MechanismDefinition) -> dict:
    """The plain data of ``definition`` (JSON-serializable)."""
    from csim.model.cache import definition_key

    return {
        "version": SNAPSHOT_VERSION,
        "name": definition.name,
        "description": definition.description,
        "coordinate_names": definition.coordinate_names,
        "coordinate_units": list(definition.coordinate_units),
        "parameters": [asdict(p) for p in definition.parameters],
        "loads": [asdict(LoadInfo(ld.name, ld.unit, ld.coordinate_unit, ld.description,
                                  ld.has_law, ld.magnitude, list(ld.window), ld.velocity))
                  for ld in definition.loads],
        "observables": [asdict(ObservableInfo(o.name, o.unit, o.rate_unit, o.description))
                        for o in definition.observables],
        "n_constraints": definition.n_constraints,
        "default_independent": dict(definition.default_independent),
        "default_independent_velocities": dict(definition.default_independent_velocities),
        "default_guess": dict(definition.default_guess),
        "key": definition_key(definition),
        "constraint_units": declared_constraint_units(definition),
    }


#: when this process loaded the model layer [s since the epoch]: a source file changed after
#: it may differ from the code this process runs, and its snapshot is not written
_LOADED_AT = time.time()


def _source_files(module: str) -> list[Path]:
    """The mechanism's module file and the model layer's sources."""
    here = Path(__file__).parent
    return [Path(importlib.util.find_spec(module).origin), *(here / name for name in MODEL_SOURCES)]


def _source_key(module: str) -> str:
    """Hash of the mechanism's module file and of the model layer's sources."""
    digest = hashlib.sha256(SNAPSHOT_VERSION.encode())
    for path in _source_files(module):
        digest.update(path.read_bytes())
    return digest.hexdigest()[:24]


def _sources_changed_since_loaded(module: str) -> bool:
    """Whether a source file was written after this process loaded csim (an upgrade or an
    edit while it runs): the snapshot it would write, filed under the new sources' key,
    would hold what the old code derived."""
    try:
        return any(path.stat().st_mtime > _LOADED_AT for path in _source_files(module))
    except OSError:
        return True


def light_definition(name: str, module: str, factory: Callable[[], MechanismDefinition]) -> LightDefinition:
    """The light definition of the mechanism ``name`` built by ``factory`` in ``module``.

    Read from the snapshot when one exists for these sources; otherwise the full definition
    is built (sympy) and its snapshot written (a cache that cannot be written is no error).
    """
    from csim.model.cache import cache_dir

    path = cache_dir() / "definitions" / f"{name}-{_source_key(module)}.json"
    try:
        data = json.loads(path.read_text())
        if data.get("version") == SNAPSHOT_VERSION:
            return LightDefinition(data, factory)
    except (OSError, ValueError, KeyError, TypeError):
        pass
    full = factory()
    data = snapshot(full)
    if _sources_changed_since_loaded(module):
        return LightDefinition(data, factory, full)
    with contextlib.suppress(OSError):  # a cache that cannot be written is not an error
        write_atomically(path, json.dumps(data, indent=1).encode())
    return LightDefinition(data, factory, full)
