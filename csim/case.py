"""Case files: load the YAML, apply ``--set`` overrides, validate, fill defaults.

A case file has these sections (every key but ``mechanism.name`` has a default)::

    mechanism:      name, parameters (defaults from the mechanism's table)
    initial:        q, qd (independent coordinates and velocities), guess (dependent)
    loads:          one law per load of the mechanism (absent loads are zero)
    formulation:    method (kkt | elimination), independent, max_condition
    stabilization:  method and the settings of every method (each reads only its own)
    simulation:     t_end, integrator, rtol, atol, step, max_step, first_step, events,
                    max_events, chatter_events, max_steps, event_samples, max_phi, min_step
    output:         dt

Units are SI throughout (m, kg, s, rad, N, N m, J); see ``csim.io.units``.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import re
from collections.abc import Hashable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from csim.errors import CaseError
from csim.io.units import per_time
from csim.load_laws import REPORTED, VELOCITY_CONDITIONS, LoadLaw, LoadSet, window_bound
from csim.mechanisms import MECHANISMS, light_mechanism
from csim.model.definition import MechanismDefinition
from csim.quantities import JSON_QUANTITY, JSON_QUANTITY_DEFINITION, SI_BASE, convert, is_quantity
from csim.schema import (
    REQUIRED,
    Field,
    Section,
    check_value,
    closest,
    describe,
    described,
    field_json_schema,
    field_paths,
    finite_number,
    section_json_schema,
    typed_section,
    unknown_key,
    validate_section,
)
from csim.solver.formulations import FORMULATIONS
from csim.solver.integrators import DAE_INTEGRATORS, INTEGRATORS
from csim.solver.methods import STABILIZERS
from csim.solver.methods import schema_fields as stabilization_fields
from csim.solver.settings import IntegrationSettings

if TYPE_CHECKING:
    from csim.linkage.plan import LightLinkage

EPS = float(np.finfo(float).eps)
#: the smallest simulation.atol: below it no state can be held to it in double precision
#: (1e-20 is round-off, EPS |y|, of a state of size 1e-4), and the step size collapses
MIN_ATOL = 1e-20
#: the most simulation.event_samples: each is an evaluation of the switching functions per step
#: (and per step a row of workspace), so a huge count only exhausts time and memory
MAX_EVENT_SAMPLES = 1000


#: the most nodes a YAML document may hold with its aliases expanded (a case file has a few
#: hundred; an "alias bomb" of a few lines expands to billions)
MAX_YAML_NODES = 200_000
#: the longest YAML text csim reads, in characters (a case file of a 100-link chain has about
#: 15,000; the YAML reader takes about a second per 25,000)
MAX_YAML_CHARS = 100_000
#: the deepest nesting of lists and mappings a YAML document may have, aliases expanded (a
#: case file nests 6 deep: mechanism.links[i].joints[j][1][k])
MAX_YAML_DEPTH = 32


class YamlTooLarge(yaml.YAMLError):
    """A YAML document nested deeper than :data:`MAX_YAML_DEPTH`, holding more than
    :data:`MAX_YAML_NODES` nodes with its aliases expanded, or an alias inside itself."""


try:  # the YAML events from libyaml where PyYAML was built with it (0.02 s against 0.13 s for
    # the 81-link N-four-bar's tables); the nodes are composed and resolved in Python either way
    from yaml.cyaml import CParser as _EventParser
except ImportError:  # pragma: no cover - a PyYAML without libyaml
    class _EventParser(yaml.reader.Reader, yaml.scanner.Scanner, yaml.parser.Parser):
        """PyYAML's own reader, scanner and parser: YAML text to events."""

        def __init__(self, stream):
            yaml.reader.Reader.__init__(self, stream)
            yaml.scanner.Scanner.__init__(self)
            yaml.parser.Parser.__init__(self)


class CaseLoader(yaml.composer.Composer, _EventParser, yaml.constructor.SafeConstructor, yaml.resolver.Resolver):
    """YAML loader that reads ``1e-8`` as a number (YAML 1.1 needs ``1.0e-8``), rejects
    duplicate keys instead of silently keeping the last one, and measures a document
    before building it: its nesting depth while it is read, then its size with aliases
    expanded (:data:`MAX_YAML_DEPTH`, :data:`MAX_YAML_NODES`), so that a few bytes cannot
    make every later step walk billions of values. Otherwise PyYAML's ``SafeLoader``, with
    its events parsed by libyaml where available."""

    _depth = 0

    def __init__(self, stream):
        _EventParser.__init__(self, stream)
        yaml.composer.Composer.__init__(self)
        yaml.constructor.SafeConstructor.__init__(self)
        yaml.resolver.Resolver.__init__(self)

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_YAML_DEPTH:
                event = self.peek_event()
                raise YamlTooLarge(f"nested more than {MAX_YAML_DEPTH} lists or mappings deep (line "
                                   f"{event.start_mark.line + 1}); expected at most {MAX_YAML_DEPTH}")
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_data(self):
        try:
            node = self.get_single_node()
        except yaml.MarkedYAMLError as exc:
            # libyaml scans a flow collection to its end before the composer sees its first
            # event, and stops at its own bound (1,000 levels) before the composer at this one
            if exc.problem != "exceeded maximum nesting depth":
                raise
            raise YamlTooLarge(f"nested more than {MAX_YAML_DEPTH} lists or mappings deep (line "
                               f"{exc.problem_mark.line + 1}); expected at most {MAX_YAML_DEPTH}") from None
        if node is None:
            return None
        measure_node(node)
        return self.construct_document(node)


def measure_node(root: yaml.Node) -> None:
    """Check a composed YAML document's size and depth with its aliases expanded.

    Each node is visited once (an alias is the node it names), so the cost is that of
    the text, whatever the expansion.

    Raises
    ------
    YamlTooLarge
        More than :data:`MAX_YAML_NODES` nodes or :data:`MAX_YAML_DEPTH` levels once
        expanded, or a list or mapping that contains itself.
    """
    size: dict[int, tuple[int, int]] = {}  # id(node) -> (nodes, depth), expanded
    on_path: set[int] = set()
    stack = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children = [] if isinstance(node, yaml.ScalarNode) else \
            [n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode) else list(node.value)
        if done:
            on_path.discard(key)
            nodes = 1 + sum(size[id(c)][0] for c in children)
            depth = 1 + max((size[id(c)][1] for c in children), default=0)
            if nodes > MAX_YAML_NODES:
                raise YamlTooLarge(f"{nodes:,} values or more once its aliases (*name) are expanded (line "
                                   f"{node.start_mark.line + 1}); expected at most {MAX_YAML_NODES:,}")
            if depth > MAX_YAML_DEPTH:
                raise YamlTooLarge(f"nested {depth} lists or mappings deep once its aliases (*name) are expanded "
                                   f"(line {node.start_mark.line + 1}); expected at most {MAX_YAML_DEPTH}")
            size[key] = (nodes, depth)
            continue
        if key in size:
            continue
        if key in on_path:
            raise YamlTooLarge(f"an alias inside the value it names (line {node.start_mark.line + 1}); expected a "
                               f"value that does not contain itself")
        on_path.add(key)
        stack.append((node, True))
        stack.extend((c, False) for c in children if id(c) not in size)


CaseLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


#: YAML 1.1 booleans that are words when written as a key (``on: C_x``, a switching law's
#: coordinate): no key of a case file is a boolean
WORD_KEYS = ("on", "off", "yes", "no")


def _construct_mapping(loader, node, deep=False):
    """Construct a mapping, rejecting duplicate keys; a key ``on``, ``off``, ``yes`` or
    ``no`` is that word (:data:`WORD_KEYS`), not a boolean.

    Merge keys (``<<: *anchor``) may be overridden by explicit keys as usual; only
    explicit keys are checked against each other.
    """
    seen = {}
    for key_node, _ in node.value:
        if key_node.tag == "tag:yaml.org,2002:merge":
            continue
        # a plain scalar's style: None from PyYAML's parser, '' from libyaml's
        if (key_node.tag == "tag:yaml.org,2002:bool" and isinstance(key_node, yaml.ScalarNode)
                and not key_node.style and key_node.value.lower() in WORD_KEYS):
            key_node.tag = "tag:yaml.org,2002:str"  # `on: C_x` is the key 'on', not True
        key = loader.construct_object(key_node, deep=deep)
        if not isinstance(key, Hashable):
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping", node.start_mark, "found unhashable key", key_node.start_mark
            )
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r} (first at line {seen[key] + 1})", key_node.start_mark
            )
        seen[key] = key_node.start_mark.line
    return yaml.SafeLoader.construct_mapping(loader, node, deep=deep)


CaseLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


#: values of ``mechanism.drive_mode``: kinematic analysis, or driven dynamics
DRIVE_MODES = ("kinematic", "dynamic")

#: The case-file schema (mechanism-specific parts are checked by :func:`validate_case`).
SCHEMA = Section({
    "mechanism": Section({
        # Either a registered mechanism (name), or a link-coupling description (links,
        # couplings; see csim/linkage/ and docs/link-coupling.md), checked by csim.linkage.tables.
        "name": Field("string", None, "registered mechanism", choices=lambda: sorted(MECHANISMS)),
        "parameters": Field("mapping", {}, "parameter values overriding the mechanism's defaults",
                             nullable=True),
        "label": Field("string", None, "link coupling: the mechanism's name in results", nullable=True),
        "links": Field("list", None, "link coupling: the links table, one row per link (0 = fixed)",
                       nullable=True),
        "couplings": Field("list", None, "link coupling: the couplings table, rows [i, k, j, m]", nullable=True),
        "gravity": Field("list", None, "link coupling: gravity [gx, gy, gz] in the fixed frame", "m/s^2",
                         nullable=True),
        "drive": Field("mapping", None, "link coupling: prescribed driving joint variables, joint: value or "
                       "expression of t (a kinematic analysis, or driven dynamics: see drive_mode)", nullable=True),
        "drive_mode": Field("string", None, "link coupling with drive: kinematic (default: the motion alone) or "
                            "dynamic (driven dynamics: the drives are constraints, their torques and forces are "
                            "recorded)", nullable=True, choices=DRIVE_MODES),
        "forces": Field("list", None, "force elements (spring, joint_spring, actuator, force, torque) on the "
                        "links, or on a registered mechanism's bodies and joints; checked by csim.linkage.forces",
                        nullable=True),
    }, "the mechanism and its parameters"),
    "initial": Section({
        "q": Field("mapping", None, "independent coordinates, name: value [rad or m]", nullable=True),
        "qd": Field("mapping", None, "velocities of the independent coordinates [rad/s or m/s]", nullable=True),
        "guess": Field("mapping", {}, "Newton start values of dependent coordinates (choose the assembly branch)",
                        nullable=True),
        "tol": Field("number", 1e-12, "Newton tolerance on max |Phi|", gt=0.0),
        "max_iter": Field("integer", 50, "Newton iteration limit", ge=1),
        "q_offset": Field("mapping", {}, "added to the consistent q0 (a perturbed start, Phi(0) != 0)",
                          nullable=True),
        "qd_offset": Field("mapping", {}, "added to the consistent qd0", nullable=True),
    }, "initial conditions; dependent coordinates and velocities are solved for"),
    "loads": Field("mapping", {}, "load laws by load name; a number is a constant load", nullable=True),
    "formulation": Section({
        "method": Field("string", "kkt", "how the DAE becomes an ODE", choices=lambda: list(FORMULATIONS)),
        "independent": Field("list", None, "independent coordinates of the elimination (null: chosen and "
                             "re-chosen automatically)", nullable=True),
        "max_condition": Field("number", 1e8, "re-partition when cond(Phi_v) exceeds this", gt=1.0),
    }),
    # method, then every method's settings, generated from its Options (csim/solver/methods/).
    # Each method reads only its own, so one case file can be run with each (csim compare).
    "stabilization": Section({
        "method": Field("string", "none", "constraint stabilization", choices=lambda: list(STABILIZERS)),
        **stabilization_fields(),
    }),
    "simulation": Section({
        "t_end": Field("number", 5.0, "end time", "s", gt=0.0),
        "integrator": Field("string", "DOP853", "time integrator", choices=lambda: list(INTEGRATORS)),
        "rtol": Field("number", 1e-8, "relative tolerance (adaptive integrators)", ge=100 * EPS, le=1.0),
        "atol": Field("number", 1e-8, "absolute tolerance (adaptive integrators)", ge=MIN_ATOL),
        "step": Field("number", 1e-3, "step of the fixed-step integrators", "s", gt=0.0),
        "max_step": Field("number", None, "largest step of the adaptive integrators", "s", gt=0.0, nullable=True),
        "first_step": Field("number", None, "first step of the adaptive integrators", "s", gt=0.0, nullable=True),
        "events": Field("boolean", True, "locate switching instants of the load laws and restart there"),
        "max_events": Field("integer", 100_000, "fail after this many switching events", ge=1),
        "chatter_events": Field("integer", 20, "fail (chattering load law) when this many consecutive switching "
                                "events come closer together, on average, than min_step", ge=2),
        "max_steps": Field("integer", 1_000_000, "fail after this many integration steps", ge=1),
        "event_samples": Field("integer", 4, "interior points of each step where switching functions are checked "
                               "(catches a zero crossed twice within one step)", ge=0, le=MAX_EVENT_SAMPLES),
        "max_phi": Field("number", 0.1, "fail when max |Phi| exceeds this after a step (joints torn apart)",
                         "unit of Phi", gt=0.0),
        "min_step": Field("number", 1e-10, "fail when an adaptive integrator accepts a shorter step "
                          "(step-size collapse)", "s", gt=0.0),
        "backend": Field("string", "auto", "compiled (numba kernels), interpreted (the kernels' source run by "
                         "Python: the same steps, no numba), python (the reference path) or auto (compiled where "
                         "supported, python otherwise); see csim.fast.support",
                         choices=("auto", "python", "compiled", "interpreted")),
    }),
    "output": Section({
        "dt": Field("number", 0.01, "output sampling interval", "s", gt=0.0),
    }),
})

#: Key paths that ``--set`` may change, with their schema fields.
SETTABLE = field_paths(SCHEMA)

LOAD_SCHEMA = Section({
    "magnitude": Field("number", REQUIRED, "value while active [N or N m]"),
    "window": Field("list", None, "[lo, hi]: active only while the load coordinate is inside", nullable=True),
    "velocity": Field("string", "any", "active only while the load coordinate moves this way",
                      choices=VELOCITY_CONDITIONS),
})


@dataclass
class Case:
    """A validated case.

    Attributes
    ----------
    data : dict
        The full case with defaults filled in (what ``csim`` writes into result files).
    mechanism : MechanismDefinition
    source : str
        Where it came from (a path, or ``"<dict>"``).
    linkage : csim.linkage.plan.LightLinkage or None
        What was derived from a link-coupling description (None for a registered mechanism).
    warnings : list of str
        Valid settings that will probably make the run fail, each naming the keys (a
        stabilizer gain times a fixed step beyond the integrator's stability region).
    """

    data: dict
    mechanism: MechanismDefinition
    source: str = "<dict>"
    linkage: LightLinkage | None = None
    warnings: list[str] = field(default_factory=list)

    # ---- the validated sections as typed, frozen objects (attributes from the case schema)
    @functools.cached_property
    def simulation(self):
        """``simulation``: t_end [s], integrator, rtol, atol, step [s], ..., backend."""
        return typed_section("simulation", SCHEMA.fields["simulation"], self.data["simulation"])

    @functools.cached_property
    def output(self):
        """``output``: dt [s]."""
        return typed_section("output", SCHEMA.fields["output"], self.data["output"])

    @functools.cached_property
    def initial(self):
        """``initial``: q, qd, guess, tol, max_iter, q_offset, qd_offset."""
        return typed_section("initial", SCHEMA.fields["initial"], self.data["initial"])

    @functools.cached_property
    def formulation(self):
        """``formulation``: method, independent, max_condition."""
        return typed_section("formulation", SCHEMA.fields["formulation"], self.data["formulation"])

    @functools.cached_property
    def stabilization(self):
        """``stabilization``: method, and every registered method's settings."""
        return typed_section("stabilization", SCHEMA.fields["stabilization"], self.data["stabilization"])

    @property
    def kinematic(self) -> bool:
        """True for a link-coupling case with prescribed drives and ``drive_mode: kinematic`` (a
        kinematic analysis)."""
        return self.linkage is not None and bool(self.linkage.drive_names) and not self.driven

    @property
    def driven(self) -> bool:
        """True for a link-coupling case with prescribed drives and ``drive_mode: dynamic``
        (driven dynamics, :mod:`csim.solver.driven`)."""
        return (self.linkage is not None and bool(self.linkage.drive_names)
                and self.data["mechanism"].get("drive_mode") == "dynamic")

    @property
    def parameters(self) -> dict[str, float]:
        return {p.name: self.data["mechanism"]["parameters"].get(p.name, p.default) for p in self.mechanism.parameters}

    def load_set(self) -> LoadSet:
        laws = []
        for load in self.mechanism.loads:
            # a load the case does not name keeps the mechanism's law (0 for a registered one)
            spec = self.data["loads"].get(load.name)
            if spec is None:
                laws.append(LoadLaw(load.name, load.magnitude, tuple(load.window), load.velocity))
            elif isinstance(spec, dict):
                window = spec["window"] or [-np.inf, np.inf]
                bounds = (float(window[0]), float(window[1]))
                laws.append(LoadLaw(load.name, spec["magnitude"], bounds, spec["velocity"]))
            else:
                laws.append(LoadLaw(load.name, float(spec)))
        return LoadSet(laws)

    def integration_settings(self) -> IntegrationSettings:
        s = self.simulation
        return IntegrationSettings(
            integrator=s.integrator, t_end=s.t_end, rtol=s.rtol, atol=s.atol, step=s.step,
            max_step=np.inf if s.max_step is None else s.max_step, first_step=s.first_step,
            events=s.events, max_events=s.max_events, max_steps=s.max_steps,
            event_samples=s.event_samples, max_phi=s.max_phi, min_step=s.min_step,
            chatter_events=s.chatter_events, output_dt=self.output.dt,
        )

    def to_yaml(self) -> str:
        """The validated case, every default filled in, as YAML (libyaml's emitter where installed)."""
        dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
        return yaml.dump(self.data, Dumper=dumper, sort_keys=False, default_flow_style=None)


def parse_yaml(text: str, source: str) -> Any:
    """YAML text to Python data, with syntax errors, and a text or document beyond the bounds
    (:data:`MAX_YAML_CHARS`, :class:`CaseLoader`), as :class:`CaseError`."""
    if len(text) > MAX_YAML_CHARS:
        raise CaseError([f"{source}: {len(text):,} characters long; expected at most {MAX_YAML_CHARS:,} (a case "
                         f"file of a 100-link chain has about 15,000)"])
    try:
        return yaml.load(text, Loader=CaseLoader)
    except YamlTooLarge as exc:
        raise CaseError([f"{source}: {exc}"]) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise CaseError([f"{source}: not valid YAML{where}: {problem}"]) from None
    except ValueError as exc:  # a scalar of an impossible value: 2001-02-30, !!int abc, a huge integer
        raise CaseError([f"{source}: not valid YAML: {exc}"]) from None


def apply_overrides(data: dict, overrides: list[str]) -> dict:
    """Apply ``key.path=value`` overrides (values parsed as YAML) to ``data`` in place.

    Raises
    ------
    CaseError
        Listing every malformed override, unknown key path, or path leading through a
        value that is not a mapping.
    """
    problems = []
    for item in overrides:
        if "=" not in item:
            problems.append(f"--set {item!r}: expected key=value, e.g. --set simulation.t_end=10")
            continue
        path, text = (part.strip() for part in item.split("=", 1))
        if path not in SETTABLE and not path.startswith(("mechanism.parameters.", "loads.", "initial.")):
            close = closest(path, SETTABLE) or next(
                (p for p in SETTABLE if p.split(".")[-1] == path.split(".")[-1]), None)
            hint = f" (did you mean {close!r}?)" if close else ""
            problems.append(f"--set {path}: unknown key{hint}; settable keys: {', '.join(SETTABLE)}, "
                            f"mechanism.parameters.NAME, loads.NAME[.FIELD], initial.q.NAME, ...")
            continue
        try:
            value = yaml.load(text, Loader=CaseLoader) if text else None
        except YamlTooLarge as exc:
            problems.append(f"--set {path}: the value is {exc}")
            continue
        except (yaml.YAMLError, ValueError):
            value = text
        node = data
        keys = path.split(".")
        for depth, key in enumerate(keys[:-1]):
            if node.get(key) is None:
                node[key] = {}
            elif not isinstance(node[key], dict):
                where = ".".join(keys[:depth + 1])
                problems.append(f"--set {path}: cannot set a key inside {where}, which is "
                                f"{describe(node[key])} in the case file; expected a mapping there")
                break
            node = node[key]
        else:
            node[keys[-1]] = value
    if problems:
        raise CaseError(problems)
    return data


def load_case(path: str | Path, overrides: list[str] | None = None) -> Case:
    """Read, override and validate the case file at ``path``.

    Raises
    ------
    CaseError
        Listing every problem found (missing file, YAML syntax, unknown keys, wrong
        types, impossible values).
    """
    return validate_case(read_case_file(path, overrides), source=str(Path(path)))


def read_text(path: Path, what: str, error: type[CaseError]) -> str:
    """The text of the file at ``path``; ``error`` (a CaseError class) saying which ``what``
    (``"case file"``) is missing or unreadable."""
    try:
        return path.read_text()
    except FileNotFoundError:
        raise error([f"{path}: no such {what}"]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error([f"{path}: cannot read the {what} ({exc})"]) from None


def read_case_file(path: str | Path, overrides: list[str] | None = None) -> dict:
    """The case file at ``path`` as a dict, with the ``--set`` overrides applied (not validated).

    Raises
    ------
    CaseError
        A missing or unreadable file, bad YAML, or not a mapping at the top level.
    """
    path = Path(path)
    data = parse_yaml(read_text(path, "case file", CaseError), str(path))
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise CaseError([f"{path}: got {describe(data)} at the top level; expected a mapping of sections "
                         f"({', '.join(SCHEMA.fields)})"])
    apply_overrides(data, overrides or [])
    return data


def validate_case(data: dict, source: str = "<dict>") -> Case:
    """Validate a case given as a dict (as read from YAML); see :func:`load_case`."""
    problems: list[str] = []
    out = validate_section("", data, SCHEMA, problems)
    section = out.get("mechanism", {})
    name = section.get("name")
    linkage = None
    if name is None and not _is_linkage(section):
        raw = data.get("mechanism")
        if raw is None or (isinstance(raw, dict) and "name" not in raw):
            problems.append(f"mechanism.name: missing; expected one of {', '.join(sorted(MECHANISMS))}")
        raise CaseError(problems)
    if name is not None:
        for key in LINKAGE_KEYS:
            if key == "forces":  # force elements on the registered mechanism's sites
                continue
            if section.get(key) is not None:
                problems.append(f"mechanism.{key}: given with mechanism.name {name!r}; expected either a registered "
                                f"mechanism (name, parameters) or a link-coupling description (links, couplings, "
                                f"...), not both")
            section.pop(key, None)
        if name not in MECHANISMS:
            raise CaseError(problems)
        mech = light_mechanism(name)
        _parameter_units(section, mech, problems)
        if section.get("forces") is not None:
            from csim.mechanisms.sites import with_forces

            mech = with_forces(mech, section["forces"], section.get("parameters") or {}, problems)
            if mech is None:
                raise CaseError(problems)
    else:
        section.pop("name", None)
        if problems:
            raise CaseError(problems)
        linkage = _build_linkage(out, problems)
        mech = linkage.definition
    _validate_parameters(out, mech, problems)
    notes = _angle_notes(out["initial"], mech)
    _validate_initial(out, mech, problems)
    _validate_loads(out, mech, problems)
    _validate_formulation(out, mech, problems)
    _validate_gains(out, mech, problems)
    _validate_resolution(out, problems)
    case = Case(data=out, mechanism=mech, source=source, linkage=linkage)  # typed sections for the checks below
    _validate_combination(case, problems)
    if problems:
        raise CaseError(problems)
    case.warnings = notes + _stability_warnings(case)
    return case


#: a plain number beyond this many radians in initial.q or initial.guess is noted (degrees written without deg?)
ANGLE_NOTE_RAD = 2 * math.pi


def _angle_notes(initial: dict, mech) -> list[str]:
    """Warnings for angles written as plain numbers beyond a full turn in ``initial.q`` and
    ``initial.guess`` (``q1: 172``: 27 turns, most likely meant as 172 deg). Only a note: an
    angle may lie beyond a turn, and a value written with its unit is never noted."""
    units = dict(zip(mech.coordinate_names, mech.coordinate_units))
    notes = []
    for key in ("q", "guess"):
        values = initial.get(key)
        for name, value in (values.items() if isinstance(values, dict) else ()):
            if units.get(str(name)) == "rad" and finite_number(value) and abs(value) > ANGLE_NOTE_RAD:
                notes.append(f"initial.{key}.{name}: {value:g} rad is {abs(value) / (2 * math.pi):.3g} turns; a plain "
                             f"number is in rad; if you meant degrees, write '{value:g} deg'")
    return notes


def _stability_warnings(case: Case) -> list[str]:
    """Stabilizer gains times a fixed step at or beyond the integrator's stability region
    (:func:`csim.solver.stability.stability_warnings`)."""
    from csim.solver.methods import stabilizer_from
    from csim.solver.stability import stability_warnings

    return stability_warnings(stabilizer_from(case.stabilization), case.simulation.integrator, case.simulation.step)


#: Keys of ``mechanism`` that belong to a link-coupling description.
LINKAGE_KEYS = ("label", "links", "couplings", "gravity", "drive", "drive_mode", "forces")


def _is_linkage(section: dict) -> bool:
    return section.get("links") is not None or section.get("couplings") is not None


def _build_linkage(out: dict, problems: list[str]) -> LightLinkage:
    """Derive the model of a link-coupling description; check what it needs to run.

    With ``mechanism.drive`` the run is a kinematic analysis: ``initial.q`` and ``qd`` come
    from the drive at t = 0 and may not be given. Without it the run is a simulation,
    which needs mass on some link.
    """
    from csim.linkage.plan import load_linkage  # (no sympy where the linkage's plan is in the cache)

    ini = out["initial"]
    linkage = load_linkage(out["mechanism"], ini, tol=ini.get("tol") or 1e-12, max_iter=ini.get("max_iter") or 50)
    given = out["mechanism"].get("parameters")
    if isinstance(given, dict):  # as the tables read them: written with a unit (50 mm), converted (0.05)
        out["mechanism"]["parameters"] = {k: linkage.parameters.get(str(k), v) for k, v in given.items()}
    if linkage.drive_names:
        _drive_start(out, linkage, problems)
        if out["mechanism"].get("drive_mode") is None:
            out["mechanism"]["drive_mode"] = "kinematic"
        # drive_mode dynamic: its combinations are checked on the typed case (_validate_combination)
        if out["mechanism"]["drive_mode"] != "dynamic" and out["mechanism"].get("forces"):
            problems.append("mechanism.forces: given with mechanism.drive and mechanism.drive_mode 'kinematic'; a "
                            "kinematic analysis prescribes the motion and computes no forces; expected "
                            "mechanism.drive_mode: dynamic (driven dynamics: the drive torques under these forces), "
                            "or mechanism.forces or mechanism.drive, not both")
    elif out["mechanism"].get("drive_mode") is not None:
        problems.append(f"mechanism.drive_mode: got {describe(out['mechanism']['drive_mode'])} without "
                        f"mechanism.drive; expected mechanism.drive (the prescribed joint variables) with it, or "
                        f"no drive_mode (forward dynamics)")
    elif not linkage.has_mass:
        problems.append("mechanism.links: no link has mass or inertia, and there is no mechanism.drive; expected "
                        "mechanism.drive (a kinematic analysis) or mass and inertia on the moving links (dynamics)")
    return linkage


def _drive_start(out: dict, linkage: LightLinkage, problems: list[str]) -> None:
    """The start of a driven linkage: the drives at t = 0 set their variables and rates.

    With one drive per degree of freedom ``initial.q`` and ``qd`` are left out (a stored,
    validated case holds the drives' own values, which may stay). Driven dynamics with
    fewer drives (``drive_mode: dynamic``) takes the free joints' start from ``initial.q``
    and ``qd`` as a simulation does (default: the assembled values, at rest); they may not
    name a driven variable except with its drive's value.
    """
    ini, mech, names = out["initial"], linkage.definition, linkage.drive_names
    try:
        u, ud, udd = linkage.drive_function(linkage.parameters)(0.0)
        finite = bool(np.all(np.isfinite(np.concatenate((u, ud, udd)))))
    except (ArithmeticError, ValueError):  # e.g. 0.0 ** -0.5: the acceleration of t^1.5
        finite = False
    if not finite:
        problems.append(f"mechanism.drive: got drives of {', '.join(names)} whose value, rate or acceleration is not "
                        f"finite at t = 0; expected drives twice differentiable at t = 0 (t^1.5 is not: its "
                        f"acceleration 0.75 t^-0.5 is infinite there; t^2 or a smooth start is)")
        return
    at_start = {"q": dict(zip(names, u.tolist())), "qd": dict(zip(names, ud.tolist()))}
    partial = len(names) < linkage.dof
    for key in ("q", "qd"):
        given = ini.get(key)
        if given is None:
            continue
        driven = {k: v for k, v in given.items() if str(k) in names} if isinstance(given, dict) else given
        if partial and isinstance(given, dict) and (not driven or _same_values(driven, at_start[key])):
            free = {k: v for k, v in given.items() if str(k) not in names}
            needed = linkage.dof - len(names)
            if key == "q" and len(free) != needed:  # counted here, not with the drives the user did not write
                others = [n for n in linkage.variable_names if n not in names]
                named = ", ".join(map(str, free)) or "none"
                problems.append(f"initial.q: got {len(free)} free joint variable(s) ({named}); "
                                f"expected exactly {needed} of the joint variables not driven ({', '.join(others)}), "
                                f"or initial.q left out (the assembled values); the drives set "
                                f"{', '.join(names)}")
                ini[key] = None
                continue
            ini[key] = {**at_start[key], **free}
        elif partial:
            values = ", ".join(f"{name} = {value:.10g}" for name, value in at_start[key].items())
            problems.append(f"initial.{key}: got {describe(given)} with mechanism.drive; the drives set "
                            f"{values} at t = 0; expected initial.{key} for the free joint variables only (a "
                            f"driven one only with its drive's value)")
        elif not _same_values(given, at_start[key]):
            # the drive's own values at t = 0 are what a validated (stored) case holds: they may stay
            problems.append(f"initial.{key}: got {describe(given)} with mechanism.drive; the driving joint "
                            f"variables ({', '.join(names)}) set the motion; expected initial.{key} left "
                            f"out (initial.guess chooses the assembly branch)")
    if partial and ini.get("q") is not None and ini.get("qd") is None:  # the free joints start at rest
        ini["qd"] = {**{k: 0.0 for k in ini["q"]}, **at_start["qd"]}
    mech.default_independent_velocities = {**mech.default_independent_velocities, **at_start["qd"]}


def _same_values(given, expected: dict[str, float]) -> bool:
    """Whether a mapping ``given`` holds exactly the keys of ``expected``, with equal values (to 1e-12)."""
    if not isinstance(given, dict) or set(map(str, given)) != set(expected):
        return False
    return all(isinstance(v, (int, float)) and not isinstance(v, bool)
               and abs(float(v) - expected[str(k)]) <= 1e-12 * max(1.0, abs(expected[str(k)]))
               for k, v in given.items())


def _parameter_units(section: dict, mech, problems: list[str]) -> None:
    """``mechanism.parameters`` of a registered mechanism written with a unit (``l1: 1500 mm``),
    converted before anything reads them (the force elements too): a parameter of the
    mechanism to its unit, another (a force element's own) to SI base units. One that
    cannot be converted is reported and left out (its default stays)."""
    given = section.get("parameters")
    if not isinstance(given, dict) or not any(is_quantity(v) for v in given.values()):
        return
    units = {p.name: p.unit for p in mech.parameters}
    converted = {}
    for key, value in given.items():
        if is_quantity(value):
            unit = units.get(str(key), SI_BASE)
            value, problem = convert(value, unit)
            if problem is not None:
                problems.append(f"mechanism.parameters.{key} [{unit}]: got {describe(given[key])}; {problem}")
                continue
        converted[key] = value
    section["parameters"] = converted


def _validate_parameters(out, mech, problems):
    given = out["mechanism"]["parameters"] or {}
    values = {}
    for key, value in given.items():
        try:
            p = mech.parameter(str(key))
        except KeyError:
            problems.append(unknown_key("mechanism.parameters", str(key), mech.parameter_names))
            continue
        spec = Field("number", unit=p.unit, gt=0.0 if p.strictly_positive else None, ge=p.minimum)
        checked = check_value(f"mechanism.parameters.{key} [{p.unit}]", value, spec, problems)
        if checked is not None:
            values[p.name] = checked
    out["mechanism"]["parameters"] = {p.name: values.get(p.name, p.default) for p in mech.parameters}


def _coordinate_map(path, given, allowed, problems, what, units):
    """``given`` (name: value) checked: names from ``allowed``, each a number in its unit
    (``units``: name -> unit; ``30 deg`` is converted to it)."""
    result = {}
    for key, value in (given or {}).items():
        if str(key) not in allowed:
            problems.append(f"{path}.{key}: not {what}; expected one of {', '.join(allowed) or '(none)'}")
            continue
        checked = check_value(f"{path}.{key}", value, Field("number", unit=units[str(key)]), problems)
        if checked is not None:
            result[str(key)] = checked
    return result


def _validate_initial(out, mech, problems):
    ini = out["initial"]
    names = mech.coordinate_names
    units = dict(zip(names, mech.coordinate_units))
    rates = {name: per_time(unit) for name, unit in units.items()}
    n_dof = len(names) - mech.n_constraints
    given = ini["q"] if ini["q"] is not None else dict(mech.default_independent)
    q = _coordinate_map("initial.q", given, names, problems, "a coordinate of " + mech.name, units)
    # Judge the count and the other maps by the coordinates named, valid values or not, so
    # that one bad entry gives one message.
    independent = [n for n in names if n in map(str, given)]
    if len(given) != n_dof:
        problems.append(
            f"initial.q: got {len(given)} coordinate(s) ({', '.join(map(str, given)) or 'none'}); expected "
            f"exactly {n_dof} independent coordinate(s) of {names} ({mech.name} has {len(names)} coordinates "
            f"and {mech.n_constraints} constraints)"
        )
    qd = ini["qd"] if ini["qd"] is not None else \
        {k: v for k, v in mech.default_independent_velocities.items() if k in independent}
    qd = _coordinate_map("initial.qd", qd, independent, problems, "an independent coordinate (listed in initial.q)",
                         rates)
    dependent = [n for n in names if n not in independent]
    guess = {**{k: v for k, v in mech.default_guess.items() if k in dependent}, **(ini["guess"] or {})}
    guess = _coordinate_map("initial.guess", guess, dependent, problems, "a dependent coordinate", units)
    q_offset = _coordinate_map("initial.q_offset", ini["q_offset"], names, problems, "a coordinate of " + mech.name,
                               units)
    qd_offset = _coordinate_map("initial.qd_offset", ini["qd_offset"], names, problems,
                                "a coordinate of " + mech.name, rates)
    ini.update(q=q, qd=qd, guess=guess, q_offset=q_offset, qd_offset=qd_offset)


def _validate_loads(out, mech, problems):
    load_names = [ld.name for ld in mech.loads]
    result = {}
    for key, spec in (out["loads"] or {}).items():
        path = f"loads.{key}"
        if str(key) not in load_names:
            problems.append(unknown_key("loads", str(key), load_names))
            continue
        load = mech.loads[load_names.index(key)]
        unit = load.unit
        if load.has_law:
            problems.append(f"{path}: {key!r} is a force element of mechanism.forces, whose law is set there; "
                            f"expected no loads.{key} (change the element in mechanism.forces)")
            continue
        if isinstance(spec, dict):
            law = validate_section(path, spec, _load_schema(unit), problems)
            window = law.get("window")
            if window is not None:
                bounds = [window_bound(f"{path}.window[{n}]", w, load.coordinate_unit, problems)
                          for n, w in enumerate(window)]
                if any(b is REPORTED for b in bounds):
                    continue
                if len(bounds) != 2 or None in bounds or not bounds[0] < bounds[1]:
                    problems.append(f"{path}.window: got {describe(window)}; expected [lo, hi] with lo < hi, "
                                    f"numbers in {load.coordinate_unit or '1'} or written with a unit (use .inf for "
                                    f"an open end)")
                else:
                    law["window"] = bounds
            result[key] = law
        elif (isinstance(spec, (int, float)) and not isinstance(spec, bool)) or is_quantity(spec):
            checked = check_value(f"{path} [{unit}]", spec, Field("number", unit=unit), problems)
            if checked is not None:
                result[key] = checked
        else:
            problems.append(f"{path}: got {describe(spec)}; expected a number [{unit}] (a constant load) or a "
                            f"mapping with keys {', '.join(LOAD_SCHEMA.fields)}")
    out["loads"] = result


def _load_schema(unit: str) -> Section:
    """:data:`LOAD_SCHEMA` with the magnitude in ``unit`` (the load's: N or N m)."""
    return Section({**LOAD_SCHEMA.fields, "magnitude": dataclasses.replace(LOAD_SCHEMA.fields["magnitude"], unit=unit)})


#: Most output samples, and most fixed steps, a run may ask for.
MAX_OUTPUT_SAMPLES = 10_000_000
MAX_FIXED_STEPS = 1_000_000_000


def _validate_resolution(out, problems):
    """Sampling and fixed steps that fit in memory and in floating point."""
    t_end, dt, step = out["simulation"].get("t_end"), out["output"].get("dt"), out["simulation"].get("step")
    if t_end is None:
        return
    if dt is not None and t_end / dt > MAX_OUTPUT_SAMPLES:
        problems.append(f"output.dt: got {describe(dt)} with simulation.t_end = {t_end:g} s; expected at least "
                        f"simulation.t_end / {MAX_OUTPUT_SAMPLES:.0e} = {t_end / MAX_OUTPUT_SAMPLES:.3g} s (at most "
                        f"{MAX_OUTPUT_SAMPLES:.0e} output samples), or a shorter simulation.t_end")
    for key in ("max_step", "first_step"):  # an adaptive step below min_step is a failure by definition
        value, min_step = out["simulation"].get(key), out["simulation"].get("min_step")
        if value is not None and min_step is not None and value < min_step:
            problems.append(f"simulation.{key}: got {describe(value)} with simulation.min_step = {min_step:g} s; "
                            f"expected at least simulation.min_step (a step below it stops the run as a step-size "
                            f"collapse), or a smaller simulation.min_step")
    if step is not None and out["simulation"].get("integrator") == "RK4" and t_end / step > MAX_FIXED_STEPS:
        problems.append(f"simulation.step: got {describe(step)} with simulation.t_end = {t_end:g} s; expected at "
                        f"least simulation.t_end / {MAX_FIXED_STEPS:.0e} = {t_end / MAX_FIXED_STEPS:.3g} s (at most "
                        f"{MAX_FIXED_STEPS:.0e} fixed steps), or a shorter simulation.t_end")


def _validate_combination(case: Case, problems):
    """Reject method combinations that cannot work, saying why (on the typed sections of the case being validated)."""
    method, integrator = case.stabilization.method, case.simulation.integrator
    formulation = case.formulation.method
    if method == "ggl" and integrator is not None and integrator not in DAE_INTEGRATORS:
        problems.append(f"simulation.integrator: got {describe(integrator)} with stabilization.method 'ggl'; the GGL "
                        f"equations are an index-2 DAE (Phi = 0 and Phi_q qd = 0 are equations, not derivatives), "
                        f"which only an implicit DAE integrator solves; expected one of {', '.join(DAE_INTEGRATORS)}")
    if method == "augmented_lagrangian" and integrator != "trapezoidal":
        problems.append(f"simulation.integrator: got {describe(integrator)} with stabilization.method "
                        f"'augmented_lagrangian'; the index-3 augmented Lagrangian method solves its own "
                        f"discretised equations at each step; expected 'trapezoidal'")
    if integrator == "trapezoidal" and method != "augmented_lagrangian":
        problems.append(f"simulation.integrator: got 'trapezoidal' (string) with stabilization.method "
                        f"{describe(method)}; the trapezoidal integrator is the augmented Lagrangian method's "
                        f"(ALI3-P); expected stabilization.method 'augmented_lagrangian', or another integrator")
    if method in ("ggl", "augmented_lagrangian") and formulation == "elimination":
        problems.append(f"formulation.method: got 'elimination' (string) with stabilization.method '{method}'; it "
                        f"solves for the multipliers itself, so there is no ODE for the elimination to "
                        f"form; expected 'kkt'")
    if case.driven:
        from csim.solver.driven import driven_problems

        problems += driven_problems(case)
    backend = case.simulation.backend
    if backend in ("compiled", "interpreted") and integrator is not None:  # an unknown integrator: reported
        from csim.fast.support import unsupported

        for reason in unsupported(case):
            problems.append(f"simulation.backend: got {backend!r} (string) with {reason}; or set "
                            f"simulation.backend to 'python' or 'auto'")
    if method == "projection" and integrator == "LSODA":
        problems.append("stabilization.method: got 'projection' (string) with simulation.integrator 'LSODA'; "
                        "LSODA keeps its history inside Fortran and cannot take a projected state (restarting "
                        "it after every step would make it first order); expected another integrator "
                        "(BDF or Radau for stiff problems, DOP853 or RK45 otherwise)")


def _validate_gains(out, mech, problems):
    r = mech.n_constraints
    for key in ("d", "w", "Lambda", "K", "k"):
        value = out["stabilization"].get(key)
        if isinstance(value, list) and len(value) != r:
            problems.append(f"stabilization.{key}: got {describe(value)}; expected one number, or a list of "
                            f"{r} (one per constraint of {mech.name})")


def _validate_formulation(out, mech, problems):
    independent = out["formulation"]["independent"]
    if independent is None:
        return
    n_dof = len(mech.coordinate_names) - mech.n_constraints
    names = mech.coordinate_names
    bad = [x for x in independent if x not in names]
    if bad or len(set(independent)) != n_dof or len(independent) != n_dof:
        problems.append(f"formulation.independent: got {describe(independent)}; expected {n_dof} distinct "
                        f"coordinate name(s) from {names}")


def json_schema() -> dict:
    """The case-file schema as JSON Schema (draft-07: yaml-language-server supports it in full), for ``csim schema``.

    Generated from :data:`SCHEMA` (the methods' options included), :data:`LOAD_SCHEMA`,
    the registered mechanisms' parameters, coordinates and loads (one ``if``/``then`` per
    mechanism name) and the link-coupling tables (:mod:`csim.linkage.json_schema`).
    """
    from csim.linkage.json_schema import tables_json_schema

    schema = {"$schema": "http://json-schema.org/draft-07/schema#", "title": "csim case file",
              "description": "A csim case (csim run CASE.yaml); see docs/case-files.md. Units are SI.",
              **section_json_schema(SCHEMA)}
    schema["type"] = "object"
    mechanism = schema["properties"]["mechanism"]
    mechanism["type"] = "object"  # the one section that must be there
    mechanism["anyOf"] = [{"required": ["name"]}, {"required": ["links", "couplings"]}]
    for key, extra in tables_json_schema().items():
        mechanism["properties"][key].update(extra)
    law = section_json_schema(LOAD_SCHEMA)
    law["type"] = "object"
    law["properties"]["magnitude"] = {**law["properties"]["magnitude"], "anyOf": [{"type": "number"}, JSON_QUANTITY]}
    del law["properties"]["magnitude"]["type"]
    schema["properties"]["loads"]["additionalProperties"] = {"anyOf": [{"type": "number"}, JSON_QUANTITY, law]}
    schema["required"] = ["mechanism"]
    schema["allOf"] = [_mechanism_json_schema(name) for name in sorted(MECHANISMS)]
    schema["definitions"] = {"quantity": JSON_QUANTITY_DEFINITION}  # a value with its unit (JSON_QUANTITY)
    return schema


def _mechanism_json_schema(name: str) -> dict:
    """``if mechanism.name is NAME then``: its parameters, coordinates and loads."""
    mech = light_mechanism(name)
    parameters = {p.name: field_json_schema(Field("number", p.default, p.description, p.unit,
                                                  gt=0.0 if p.strictly_positive else None, ge=p.minimum))
                  for p in mech.parameters}
    units = dict(zip(mech.coordinate_names, mech.coordinate_units))

    def coordinates(what: str, per: str) -> dict:
        return {"properties": {n: {"anyOf": [{"type": "number"}, JSON_QUANTITY],
                                   "description": described(f"{what} {n}", units[n] + per)}
                               for n in units}, "additionalProperties": False}
    loads = {ld.name: {"description": described(f"load {ld.name}", ld.unit)} for ld in mech.loads}
    return {
        "if": {"properties": {"mechanism": {"properties": {"name": {"const": name}}, "required": ["name"]}},
               "required": ["mechanism"]},
        "then": {"properties": {
            # with force elements, parameters the elements use may be added (csim.mechanisms.sites)
            "mechanism": {"properties": {"parameters": {"properties": parameters}},
                          "if": {"required": ["forces"], "properties": {"forces": {"type": "array"}}},
                          "then": {"properties": {"parameters": {"additionalProperties": {
                              "anyOf": [{"type": "number"}, JSON_QUANTITY],
                              "description": "a parameter the force elements use [SI units]"}}}},
                          "else": {"properties": {"parameters": {"properties": dict.fromkeys(parameters, True),
                                                                 "additionalProperties": False}}}},
            "initial": {"properties": {
                "q": coordinates("coordinate", ""), "qd": coordinates("velocity of", "/s"),
                "guess": coordinates("Newton start of", ""), "q_offset": coordinates("offset of", ""),
                "qd_offset": coordinates("velocity offset of", "/s")}},
            "loads": {"properties": loads, "additionalProperties": False},
        }},
    }
