"""Which runs a comparison makes: every (method, tolerance) case and the reference's, validated.

:func:`plan_comparison` checks the options (methods, tolerances, reference, jobs), applies
the ``--set`` overrides to the case, chooses the methods (by default every registered one
the case allows), keeps one study to one kind of value (tolerances or steps), validates the
case of every (method, tolerance) combination before anything runs, puts every run on one
backend, and builds the reference run's case. Nothing here runs a simulation; every problem
is a :class:`csim.errors.CaseError` raised before a run.
"""
from __future__ import annotations

import copy
from collections.abc import Sequence
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path

from csim.case import Case, apply_overrides, load_case, validate_case
from csim.compare.specs import (
    check_methods,
    check_tolerances,
    default_methods,
    method_sets,
    split_method,
    tol_text,
    tolerance_kind,
    tolerance_label,
    tolerance_sets,
)
from csim.errors import CaseError
from csim.fast import resolve_backend
from csim.fast.support import INTEGRATORS as COMPILED_INTEGRATORS
from csim.solver.integrators import INTEGRATORS
from csim.solver.methods import STABILIZERS

#: a case as :func:`csim.compare.compare` takes it: a file, a dict as read from YAML, or a Case
CaseInput = str | Path | dict | Case


@dataclass(frozen=True)
class ReferenceSettings:
    """How the reference run differs from the case: a tight, stabilized setting.

    Parameters
    ----------
    method : str
        ``stabilization.method`` of the reference run (default ``projection``: exact
        constraints at every step), optionally as ``METHOD:INTEGRATOR``.
    integrator : str
        ``simulation.integrator`` of the reference run (unless ``method`` names one).
    tol : float
        rtol = atol of the reference run (``simulation.step`` [s] for a fixed-step
        integrator).
    """

    method: str = "projection"
    integrator: str = "DOP853"
    tol: float = 1e-12

    @property
    def run_method(self) -> str:
        """The stabilization method (``method`` may be given as ``METHOD:INTEGRATOR``)."""
        return split_method(self.method)[0]

    @property
    def run_integrator(self) -> str:
        """The integrator: the one ``method`` names, else ``integrator``."""
        return split_method(self.method)[1] or self.integrator

    def describe(self) -> str:
        """The settings as text, e.g. ``"projection, DOP853, rtol = atol = 1e-12"``."""
        integrator = self.run_integrator
        return f"{self.run_method}, {integrator}, {tolerance_label(integrator)} = {tol_text(self.tol)}"


@dataclass
class Plan:
    """The validated cases of a comparison, before any of them runs.

    Attributes
    ----------
    base : Case
        The case with the overrides applied (each run's case differs from it in method,
        integrator, tolerance or backend).
    integrator : str
        The case's own integrator.
    methods : list of str
        The methods that run, in order (specs ``METHOD`` or ``METHOD:INTEGRATOR``).
    tolerances : list of float or None
        The values of a work-precision study, loosest first; None without a study.
    values : list of float
        The value of each method's runs: ``tolerances``, or the case's own setting alone.
    cases : dict of (str, float) -> Case
        (method, value) -> the validated case of that run.
    reference_case : Case
        The reference run's validated case.
    skipped : dict of str -> str
        Methods left out of a default comparison -> why.
    backend_note : str
        Why every run was put on the Python backend ("" when each runs on its own).
    """

    base: Case
    integrator: str
    methods: list[str]
    tolerances: list[float] | None
    values: list[float]
    cases: dict[tuple[str, float], Case]
    reference_case: Case
    skipped: dict[str, str] = field(default_factory=dict)
    backend_note: str = ""

    def run_cases(self) -> list[tuple[str, Case]]:
        """(method, case) of every run: method by method, each at ``values`` in order."""
        return [(m, self.cases[m, v]) for m, v in product(self.methods, self.values)]


def plan_comparison(case: CaseInput, methods: Sequence[str] | None, tolerances: Sequence[float] | None,
                    overrides: Sequence[str], reference: ReferenceSettings, jobs: int | None) -> Plan:
    """Validate the options and the case of every run of a comparison.

    Parameters are those of :func:`csim.compare.compare` (``reference`` given).

    Returns
    -------
    Plan

    Raises
    ------
    CaseError
        For bad options (all at once), a case that does not validate, a study that mixes
        steps with tolerances, a (method, value) combination the case rejects (the message
        names the method and, where it matters, the value), or a reference case it rejects.
    """
    overrides = list(overrides)
    chosen, tols = _check_options(methods, tolerances, reference, jobs)
    base = make_case(case, overrides)
    integrator = base.simulation.integrator
    chosen = chosen if chosen is not None else default_methods(integrator)
    skipped: dict[str, str] = {}
    if tols is not None:
        chosen = _one_kind_of_value(chosen, integrator, default=methods is None, skipped=skipped)
    values = tols if tols is not None else [own_tolerance(base)[0]]
    runs = _RunCases(case, overrides, integrator, study=tols is not None)
    cases, chosen = _validate_runs(runs, chosen, values, default=methods is None, skipped=skipped)
    cases, backend_note = _one_backend(runs, cases, chosen)
    return Plan(base=base, integrator=integrator, methods=chosen, tolerances=tols, values=values, cases=cases,
                reference_case=_reference_case(case, overrides, reference), skipped=skipped,
                backend_note=backend_note)


def _check_options(methods: Sequence[str] | None, tolerances: Sequence[float] | None, reference: ReferenceSettings,
                   jobs: int | None) -> tuple[list[str] | None, list[float] | None]:
    """The checked methods and tolerances (None where not given); every bad option at once."""
    problems = []
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        problems.append(f"jobs: got {jobs!r}; expected a whole number >= 1")
    chosen = tols = None
    try:
        chosen = check_methods(methods) if methods is not None else None
    except CaseError as exc:
        problems += exc.problems
    try:
        tols = check_tolerances(tolerances) if tolerances is not None else None
    except CaseError as exc:
        problems += exc.problems
    for check, value, option in ((check_tolerances, reference.tol, "reference tolerance"),
                                 (check_methods, reference.method, "reference method")):
        try:
            check([value], option)
        except CaseError as exc:
            problems += exc.problems
    if problems:
        raise CaseError(problems)
    return chosen, tols


def _one_kind_of_value(chosen: list[str], integrator: str, default: bool, skipped: dict[str, str]) -> list[str]:
    """The methods of a study whose integrators all take the kind of value the case's takes.

    One study sets one kind of value: tolerances of adaptive integrators, or steps [s] of
    fixed-step ones. A default comparison leaves out (into ``skipped``) the methods whose
    own integrator takes the other kind; methods asked for by name make it an error.
    """
    kind = tolerance_kind(integrator)
    other = {m: i for m in chosen if tolerance_kind(i := split_method(m)[1] or integrator) != kind}
    if not other:
        return chosen
    if default:
        for m, i in other.items():
            skipped[m] = (f"its integrator {i} takes {tolerance_label(i)}, the case's {integrator} "
                          f"{tolerance_label(integrator)}: one study sets one kind")
        return [m for m in chosen if m not in other]
    same = [m for m in chosen if m not in other]
    raise CaseError([f"tolerances: the values set {tolerance_label(integrator)} for "
                     f"{', '.join(same) or integrator} but the step or tolerance of another kind for "
                     f"{', '.join(other)}; compare adaptive and fixed-step integrators in separate studies"])


@dataclass(frozen=True)
class _RunCases:
    """Makes the validated case of one run: the case, the overrides, then the run's own sets."""

    case: CaseInput
    overrides: list[str]
    integrator: str
    study: bool

    def make(self, method: str, value: float, extra: Sequence[str] = ()) -> Case:
        """The case of ``method`` at ``value`` (``extra``: overrides after the common ones)."""
        # the tolerance (or step) of a study is that of the method's own integrator, when it names one
        value_sets = tolerance_sets(split_method(method)[1] or self.integrator, value) if self.study else []
        return make_case(self.case, [*self.overrides, *extra, *method_sets(method), *value_sets])


def _validate_runs(runs: _RunCases, chosen: list[str], values: list[float], default: bool,
                   skipped: dict[str, str]) -> tuple[dict[tuple[str, float], Case], list[str]]:
    """Validate every (method, value) case before anything runs.

    Returns the cases and the methods that run: a default comparison leaves out (into
    ``skipped``) the methods this case does not allow, unless it allows none of them.

    Raises
    ------
    CaseError
        One message per problem, prefixed by the runs it concerns (see :func:`_prefix`).
    """
    cases: dict[tuple[str, float], Case] = {}
    failures: dict[str, dict[str, list[float]]] = {}  # problem -> method -> values
    for method in chosen:
        for value in values:
            try:
                cases[method, value] = runs.make(method, value)
            except CaseError as exc:
                for p in exc.problems:
                    failures.setdefault(p, {}).setdefault(method, []).append(value)
    bad = {m for per_method in failures.values() for m in per_method}
    if failures and default and bad != set(chosen):
        for method in [m for m in chosen if m in bad]:
            skipped[method] = "; ".join(p for p, per_method in failures.items() if method in per_method)
        return cases, [m for m in chosen if m not in bad]
    if failures:
        raise CaseError([_prefix(per_method, chosen, values, runs.study, runs.integrator) + p
                         for p, per_method in failures.items()])
    return cases, chosen


def _prefix(per_method: dict[str, list[float]], methods: list[str], values: list[float], study: bool,
            integrator: str) -> str:
    """Which runs a validation problem concerns, e.g. ``"method projection: "``."""
    parts = []
    if set(per_method) != set(methods) or len(methods) == 1:
        parts.append("method " + ", ".join(per_method))
    tols = sorted({v for vs in per_method.values() for v in vs}, reverse=True)
    if study and (len(tols) != len(values) or len(values) == 1):
        parts.append(f"{tolerance_label(integrator)} " + ", ".join(f"{v:g}" for v in tols))
    return (", ".join(parts) + ": ") if parts else ""


def _own_integrator(case: Case) -> bool:
    """Whether the case's integrator only Python has: one the compiled backend lacks, or a
    method's own (``ggl``'s Radau IIA for DAEs, the augmented Lagrangian method's trapezoidal
    rule: a method that declares its integrators and that the kernels do not run)."""
    method = STABILIZERS.get(case.stabilization.method)
    return (case.simulation.integrator not in COMPILED_INTEGRATORS
            or (method is not None and not method.compiled and method.integrators is not None))


def _one_backend(runs: _RunCases, cases: dict[tuple[str, float], Case],
                 chosen: list[str]) -> tuple[dict[tuple[str, float], Case], str]:
    """The cases on one backend, so that wall times compare methods, not backends, and why.

    Under ``backend: auto``, a method that the compiled backend could run but does not (no
    compiled path for it with a compiled integrator) puts every run on Python; the note says
    so. A method whose own integrator only Python has (``ggl:Radau``, an implicit DAE solver)
    runs there alone, and the note says that its wall time is the Python path's. The note is
    "" when every run is on one backend as it is.
    """
    on_python = {m for (m, _), c in cases.items() if resolve_backend(c) == "python"}
    own = sorted({m for (m, _), c in cases.items() if m in on_python and _own_integrator(c)}, key=chosen.index)
    python_only = sorted(on_python - set(own), key=chosen.index)
    if len(on_python) >= len(chosen) or not on_python:
        return cases, ""
    if not python_only:
        others = sorted({resolve_backend(c) for (m, _), c in cases.items() if m not in on_python})
        return cases, (f"python for {', '.join(own)} (no compiled path for its integrator), {'/'.join(others)} for "
                       f"the others: compare wall times within one backend")
    moved = {(m, v): runs.make(m, v, extra=["simulation.backend=python"]) for (m, v) in cases}
    return moved, (f"python for every run ({', '.join(python_only)} has no compiled path; one backend keeps "
                   f"the wall times comparable)")


def _reference_case(case: CaseInput, overrides: list[str], reference: ReferenceSettings) -> Case:
    """The reference run's validated case; a problem names the reference settings."""
    try:
        return make_case(case, [*overrides, f"stabilization.method={reference.run_method}",
                                f"simulation.integrator={reference.run_integrator}",
                                *tolerance_sets(reference.run_integrator, reference.tol)])
    except CaseError as exc:
        raise CaseError([f"reference run ({reference.describe()}): {p}" for p in exc.problems]) from None


def make_case(case: CaseInput, sets: list[str]) -> Case:
    """Validate ``case`` (a file, a dict as read from YAML, or a Case) with the overrides ``sets``."""
    if isinstance(case, (str, Path)):
        return load_case(case, sets)
    data, source = (case.data, case.source) if isinstance(case, Case) else (case, "<dict>")
    return validate_case(apply_overrides(copy.deepcopy(data), sets), source=source)


def own_tolerance(case: Case) -> tuple[float, str]:
    """A case's own (tolerance, tolerance kind): its rtol, or its step [s] for a fixed-step integrator."""
    sim = case.simulation
    if not INTEGRATORS[sim.integrator].adaptive:
        return float(sim.step), "step"
    return float(sim.rtol), "rtol=atol" if sim.rtol == sim.atol else "rtol"


def setting_text(case: Case) -> str:
    """The tolerances (or step) of a case, e.g. ``"rtol = atol = 1e-08"``."""
    sim = case.simulation
    if not INTEGRATORS[sim.integrator].adaptive:
        return f"step = {sim.step:.2e} s"
    if sim.rtol == sim.atol:
        return f"rtol = atol = {tol_text(sim.rtol)}"
    return f"rtol = {tol_text(sim.rtol)}, atol = {tol_text(sim.atol)}"
