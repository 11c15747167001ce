"""Compare stabilization methods on one case: accuracy, constraint errors and cost.

:func:`compare` runs a case once per method of :data:`csim.solver.stabilizers.STABILIZERS`
(``stabilization.method`` set to each), optionally at several tolerances (a work-precision
study), and one tight-tolerance reference run of the same case. The runs go to separate
processes when there are several jobs. Each run is measured against the reference:

motion error
    max over the output times t_k and the coordinates i of |q_i(t_k) - q_ref_i(t_k)|
    [rad or m, the coordinates' own units]; a run that stopped early is measured over the
    output times it reached (``error_until``).
final error
    max over i of |q_i(t_end) - q_ref_i(t_end)|; NaN for a run that did not reach t_end.
constraint errors
    max |Phi| over the run, |Phi| at its last sample, and max |Phi_q qd| over the run.
cost
    wall time [s] (measured in the worker, so parallel runs share the CPU), right-hand-side
    evaluations and accepted steps.

A run that fails (blow-up, Newton failure, an exception) becomes a row with status
``failed`` and its numbers up to the failure; the other runs go on.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import copy
import math
import multiprocessing
import os
import signal
import threading
from collections.abc import Callable, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from itertools import product
from pathlib import Path

import numpy as np

from csim.case import Case, apply_overrides, load_case, validate_case
from csim.errors import CaseError
from csim.fast import resolve_backend
from csim.io.hdf5 import COMPARISON_RESERVED, write_comparison
from csim.pipeline import numeric_model, run_case
from csim.result import Result
from csim.solver.integrators import INTEGRATORS
from csim.solver.stabilizers import STABILIZERS

NAN = float("nan")

#: message of the runs that an interrupt (Ctrl-C) kept from running or finishing
INTERRUPTED = "interrupted by the user (Ctrl-C) before this run finished"


@dataclass(frozen=True)
class ReferenceSettings:
    """How the reference run differs from the case: a tight, stabilized setting.

    Parameters
    ----------
    method : str
        ``stabilization.method`` of the reference run (default ``projection``: exact
        constraints at every step).
    integrator : str
        ``simulation.integrator`` of the reference run.
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
        integrator = self.run_integrator
        return f"{self.run_method}, {integrator}, {_tolerance_label(integrator)} = {tol_text(self.tol)}"


@dataclass
class Run:
    """One run of a comparison: a method at a tolerance, and its figures of merit.

    Attributes
    ----------
    method : str
        Stabilization method (``METHOD:INTEGRATOR`` when it names its own integrator).
    tolerance : float
        rtol (= atol) of the run, or its step [s] for a fixed-step integrator; see
        ``tolerance_kind``.
    tolerance_kind : {"rtol=atol", "rtol", "step"}
        What ``tolerance`` is for this run's integrator (``"rtol"``: atol differs, see the
        run's case).
    result : Result or None
        The full run (None when it raised before producing one, or never ran).
    status : {"success", "failed"}
    message : str
        The run's message (the cause of a failure).
    wall_time : float
        Wall time of the run [s], measured in the process that ran it.
    nfev, nsteps : int
        Right-hand-side evaluations and accepted steps.
    max_phi, final_phi : float
        max |Phi_i| over the run, and at its last sample [unit of Phi]; NaN without samples.
    max_phi_dot : float
        max |(Phi_q qd)_i| over the run [unit of Phi / s].
    motion_error : float
        max over output times and coordinates of |q - q_ref| [rad or m]; NaN without a
        reference.
    final_error : float
        max over coordinates of |q(t_end) - q_ref(t_end)| [rad or m]; NaN when the run or
        the reference did not reach t_end.
    error_until : float
        Last output time that ``motion_error`` covers [s] (t_end unless a run stopped early).
    error_note : str
        Why the errors are missing or partial ("" when complete).
    case_yaml : str
        The run's case, validated (what its group's ``case`` attribute holds).
    """

    method: str
    tolerance: float
    tolerance_kind: str = "rtol=atol"
    result: Result | None = None
    status: str = "failed"
    message: str = INTERRUPTED
    wall_time: float = NAN
    nfev: int = 0
    nsteps: int = 0
    max_phi: float = NAN
    final_phi: float = NAN
    max_phi_dot: float = NAN
    motion_error: float = NAN
    final_error: float = NAN
    error_until: float = NAN
    error_note: str = ""
    case_yaml: str = field(default="", repr=False)

    @property
    def ok(self) -> bool:
        return self.status == "success"

    def set_result(self, result: Result | None, message: str = "") -> None:
        """Take the figures of merit of ``result`` (None: the run raised ``message``)."""
        self.result = result
        if result is None:
            self.status, self.message = "failed", message
            return
        self.status, self.message = result.status, result.message
        self.wall_time, self.nfev, self.nsteps = float(result.wall_time), int(result.nfev), int(result.nsteps)
        self.max_phi = _nanmax_abs(result.phi)
        self.max_phi_dot = _nanmax_abs(result.phi_dot)
        self.final_phi = _nanmax_abs(result.phi[-1:]) if result.t.size else NAN

    def measure_against(self, ref: Run) -> None:
        """Set the motion errors against the reference run ``ref``."""
        self.motion_error = self.final_error = self.error_until = NAN
        r = self.result
        if ref.result is None or not ref.ok:
            self.error_note = f"no reference: the reference run failed ({_short(ref.message)})"
            return
        if r is None or r.t.size == 0:
            self.error_note = "no samples to measure"
            return
        rt, qt = ref.result.t, ref.result.q
        n = min(r.t.size, rt.size)
        if r.q.shape[1] != qt.shape[1] or not np.allclose(r.t[:n], rt[:n], rtol=0.0, atol=1e-9 * max(rt[-1], 1.0)):
            self.error_note = "output times differ from the reference's"
            return
        self.motion_error = _nanmax_abs(r.q[:n] - qt[:n])
        self.error_until = float(r.t[n - 1])
        if n == r.t.size == rt.size:
            self.final_error = _nanmax_abs(r.q[-1] - qt[-1])
            self.error_note = ""
        else:
            self.error_note = f"motion error over t <= {self.error_until:.6g} s only (the run stopped early)"


@dataclass
class Comparison:
    """The runs of a comparison, their reference, and how they were made.

    Attributes
    ----------
    source : str
        The case file (or ``"<dict>"``).
    case_yaml : str
        The case as validated, with the ``--set`` overrides applied, defaults filled in.
    mechanism : str
    coordinate_units : list of str
    methods : list of str
        The methods compared, in order.
    tolerances : list of float or None
        The tolerances of a work-precision study, loosest first; None for a run per method
        at the case's own tolerance.
    tolerance_kind : {"rtol=atol", "step"}
        What a tolerance sets: rtol and atol of an adaptive integrator, or the step [s] of a
        fixed-step one.
    integrator : str
    reference : ReferenceSettings
    reference_run : Run
    runs : list of Run
        Every run, method by method, loosest tolerance first.
    jobs : int
        Processes that ran them (1: in this process).
    skipped : dict of str -> str
        Registered methods left out of a default comparison because the case does not allow
        them (method -> the validator's reason).
    interrupted : bool
        Whether Ctrl-C stopped the comparison (unfinished runs are failed rows).
    backend_note : str
        Why every run was put on the Python backend ("" when each ran on its own).
    setting : str
        The case's own tolerances (or step), as text, e.g. ``"rtol = 1e-08, atol = 1e-10"``.
    """

    source: str
    case_yaml: str
    mechanism: str
    coordinate_units: list[str]
    methods: list[str]
    tolerances: list[float] | None
    tolerance_kind: str
    integrator: str
    reference: ReferenceSettings
    reference_run: Run
    runs: list[Run]
    jobs: int = 1
    skipped: dict[str, str] = field(default_factory=dict)
    interrupted: bool = False
    setting: str = ""
    backend_note: str = ""

    @property
    def method_runs(self) -> dict[str, Run]:
        """Method -> its run in the file's method group: the case's own tolerance, or the
        tightest of a study."""
        chosen: dict[str, Run] = {}
        for run in self.runs:
            if run.method not in chosen or run.tolerance < chosen[run.method].tolerance:
                chosen[run.method] = run
        return {m: chosen[m] for m in self.methods}

    @property
    def failed(self) -> list[Run]:
        """Failed runs, the reference's included."""
        return [r for r in (self.reference_run, *self.runs) if not r.ok]

    @property
    def ok(self) -> bool:
        """Every run and the reference succeeded."""
        return not self.failed

    def label(self, run: Run) -> str:
        """How messages name a run: ``reference``, ``baumgarte``, ``baumgarte (rtol=atol 1e-06)``."""
        if run is self.reference_run:
            return "reference"
        if self.tolerances is None:
            return run.method
        return f"{run.method} ({_run_setting(run)})"

    def table_columns(self, runs: Sequence[Run]) -> dict[str, list]:
        """The columns of a table of ``runs`` (see :data:`csim.io.hdf5.COMPARISON_UNITS`)."""
        return {
            "method": [r.method for r in runs],
            "tolerance": [float(r.tolerance) for r in runs],
            "tolerance_kind": [r.tolerance_kind for r in runs],
            "status": [r.status for r in runs],
            "message": [r.message for r in runs],
            "max_phi": [r.max_phi for r in runs],
            "final_phi": [r.final_phi for r in runs],
            "max_phi_dot": [r.max_phi_dot for r in runs],
            "motion_error": [r.motion_error for r in runs],
            "final_error": [r.final_error for r in runs],
            "error_until": [r.error_until for r in runs],
            "wall_time": [r.wall_time for r in runs],
            "nfev": [int(r.nfev) for r in runs],
            "nsteps": [int(r.nsteps) for r in runs],
            "backend": [r.result.backend if r.result is not None else "" for r in runs],
        }

    def write(self, path: str | Path) -> None:
        """Write the comparison file (atomically; layout in :mod:`csim.io.hdf5`)."""
        tables = {"summary": self.table_columns(list(self.method_runs.values()))}
        if self.tolerances is not None:
            tables["work_precision"] = self.table_columns(self.runs)
        ref = self.reference_run
        attrs = dict(
            case=self.case_yaml, source=self.source, mechanism=self.mechanism,
            integrator=self.integrator, tolerance_kind=self.tolerance_kind,
            tolerances=self.tolerances if self.tolerances is not None else [],
            reference_method=self.reference.method, reference_integrator=self.reference.integrator,
            reference_tol=self.reference.tol, reference_status=ref.status, reference_message=ref.message,
            jobs=self.jobs, interrupted=self.interrupted, setting=self.setting,
            skipped_methods=list(self.skipped), skipped_reasons=[self.skipped[m] for m in self.skipped],
        )
        write_comparison(path, {m: _result_or_empty(r, self) for m, r in self.method_runs.items()},
                         _result_or_empty(ref, self), attrs, tables, self.coordinate_units)

    def table(self) -> str:
        """The comparison as plain aligned text: settings, one row per method (and one per
        method and tolerance of a study), and the failures below."""
        ref = self.reference_run
        ref_line = f"reference:  {self.reference.describe()}: {ref.status}"
        if ref.result is not None:
            ref_line += f", {ref.nfev} RHS evals, {ref.wall_time:.2e} s"
        lines = [f"case:       {self.source} ({self.mechanism}, {self.integrator})", ref_line,
                 "errors:     motion = max over the output times and coordinates of |q - q_ref| [rad or m]; "
                 "final = the same at t_end",
                 f"timing:     wall time of each run in its own process, jobs = {self.jobs}"
                 + (" (parallel runs share the CPU)" if self.jobs > 1 else "")]
        if self.backend_note:
            lines.append(f"backend:    {self.backend_note}")
        for method, reason in self.skipped.items():
            lines.append(f"skipped:    {method}: {_short(reason, 160)}")
        if self.interrupted:
            lines.append("interrupted: Ctrl-C stopped the comparison; unfinished runs are marked failed")
        per_method = list(self.method_runs.values())
        label = _TOLERANCE_LABELS[self.tolerance_kind]
        # a method that names its own integrator may run at another setting than the case's
        own_settings = self.tolerances is None and len({_run_setting(r) for r in per_method}) > 1
        if own_settings:
            lines += ["", f"per method (the case: {self.setting}; a method's own integrator: its own setting):"]
        elif self.tolerances is None:
            lines += ["", f"per method ({self.setting}, as in the case):"]
        else:
            lines += ["", f"per method (the tightest {label}: the runs in the file's method groups):"]
        lines += _format_rows(per_method, with_tol=self.tolerances is not None or own_settings)
        if self.tolerances is not None:
            lines += ["", f"work-precision ({label} = " + ", ".join(tol_text(t) for t in self.tolerances) + "):",
                      *_format_rows(self.runs, with_tol=True)]
        notes = []
        if not ref.ok:
            notes.append(f"reference: failed: {_short(ref.message, 200)}; motion errors are unavailable (-)")
        for r in self.runs:
            name = self.label(r)
            if not r.ok:
                notes.append(f"{name}: failed: {_short(r.message, 200)}")
            if r.error_note and ref.ok:
                notes.append(f"{name}: {r.error_note}")
        if notes:
            lines += ["", *notes]
        return "\n".join(lines)


# --------------------------------------------------------------------------- input checks


def check_methods(methods: Sequence[str], option: str = "methods") -> list[str]:
    """Validate method names against the registry.

    Raises
    ------
    CaseError
        For an empty list, a duplicate, an unknown name (listing the valid ones), or a name
        reserved for the comparison file's own groups.
    """
    problems = []
    names = [str(m).strip() for m in methods]
    if not names or any(not n for n in names):
        problems.append(f"{option}: got {','.join(names)!r}; expected method names separated by commas, "
                        f"e.g. {','.join(list(STABILIZERS)[:2])}")
    seen = set()
    for spec in names:
        if not spec:
            continue
        if spec in seen:
            problems.append(f"{option}: method {spec!r} given twice")
        seen.add(spec)
        name, integrator = split_method(spec)
        if name not in STABILIZERS:
            problems.append(f"{option}: unknown method {name!r}; valid names: {', '.join(STABILIZERS)} "
                            f"(each optionally as METHOD:INTEGRATOR)")
        elif name in COMPARISON_RESERVED:
            problems.append(f"{option}: method {name!r} has the name of a group of the comparison file")
        if integrator is not None and integrator not in INTEGRATORS:
            problems.append(f"{option}: unknown integrator {integrator!r} in {spec!r}; valid names: "
                            f"{', '.join(INTEGRATORS)}")
    if problems:
        raise CaseError(list(dict.fromkeys(problems)))
    return names


def split_method(spec: str) -> tuple[str, str | None]:
    """``"ggl:Radau"`` -> ``("ggl", "Radau")``; ``"none"`` -> ``("none", None)``.

    A method may name its own integrator, for methods that the case's integrator cannot
    run (GGL, an index-2 DAE, needs Radau) or to compare integrators side by side.
    """
    name, _, integrator = spec.partition(":")
    return name.strip(), integrator.strip() or None


def default_methods(integrator: str) -> list[str]:
    """Every registered method; one that ``integrator`` cannot run gets its own, as ``METHOD:INTEGRATOR``."""
    return [name if cls.integrators is None or integrator in cls.integrators else f"{name}:{cls.integrators[0]}"
            for name, cls in STABILIZERS.items()]


def _method_sets(spec: str) -> list[str]:
    """``--set`` overrides that select the method (and its integrator) of ``spec``."""
    name, integrator = split_method(spec)
    return [f"stabilization.method={name}", *([f"simulation.integrator={integrator}"] if integrator else [])]


def parse_methods(text: str, option: str = "--methods") -> list[str]:
    """``"none,baumgarte"`` -> ``["none", "baumgarte"]``, checked by :func:`check_methods`."""
    return check_methods([] if not text.strip() else text.split(","), option)


def check_tolerances(values: Sequence[float], option: str = "tolerances") -> list[float]:
    """Validate tolerances (or steps): positive finite numbers, none given twice.

    Returns them loosest first. Raises :class:`CaseError` naming each bad value.
    """
    problems, out = [], []
    if not len(values):
        problems.append(f"{option}: expected at least one value, e.g. 1e-4,1e-6,1e-8")
    for v in values:
        ok = isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
        if not ok:
            problems.append(f"{option}: got {v!r}; expected positive numbers separated by commas, e.g. 1e-4,1e-6")
        elif float(v) in out:
            problems.append(f"{option}: {float(v):g} given twice")
        else:
            out.append(float(v))
    if problems:
        raise CaseError(problems)
    return sorted(out, reverse=True)


def parse_tolerances(text: str, option: str = "--tolerances") -> list[float]:
    """``"1e-4,1e-6"`` -> ``[1e-4, 1e-6]`` (loosest first), naming any bad value as given."""
    problems, values = [], []
    for item in text.split(","):
        item = item.strip()
        try:
            value = float(item)
        except ValueError:
            value = NAN
        if not (math.isfinite(value) and value > 0):
            problems.append(f"{option}: got {item!r}; expected positive numbers separated by commas, e.g. 1e-4,1e-6")
            continue
        values.append(value)
    if problems:
        raise CaseError(problems)
    return check_tolerances(values, option)


# --------------------------------------------------------------------------- cases


def tol_text(value: float) -> str:
    """A tolerance or step as short text: ``1e-06``, or ``2.5e-07`` where one digit is not enough."""
    short = f"{value:.0e}"
    return short if float(short) == value else f"{value:.6g}"


#: tolerance kind -> how text names it
_TOLERANCE_LABELS = {"rtol=atol": "rtol = atol", "rtol": "rtol", "step": "step"}


def _tolerance_kind(integrator: str) -> str:
    """What a study's tolerance sets for ``integrator``: ``"rtol=atol"`` or ``"step"`` [s]."""
    return "rtol=atol" if INTEGRATORS[integrator].adaptive else "step"


def _tolerance_label(integrator: str) -> str:
    return _TOLERANCE_LABELS[_tolerance_kind(integrator)]


def _own_tolerance(case: Case) -> tuple[float, str]:
    """A case's own (tolerance, tolerance kind): its rtol, or its step for a fixed-step integrator."""
    sim = case.data["simulation"]
    if not INTEGRATORS[sim["integrator"]].adaptive:
        return float(sim["step"]), "step"
    return float(sim["rtol"]), "rtol=atol" if sim["rtol"] == sim["atol"] else "rtol"


def _run_setting(run: Run) -> str:
    """A run's setting as short text: ``rtol=atol 1e-08``, ``step 1e-03``."""
    return f"{run.tolerance_kind} {tol_text(run.tolerance)}"


def _setting_text(case: Case) -> str:
    """The tolerances (or step) of a case, e.g. ``"rtol = atol = 1e-08"``."""
    sim = case.data["simulation"]
    if not INTEGRATORS[sim["integrator"]].adaptive:
        return f"step = {sim['step']:.2e} s"
    if sim["rtol"] == sim["atol"]:
        return f"rtol = atol = {tol_text(sim['rtol'])}"
    return f"rtol = {tol_text(sim['rtol'])}, atol = {tol_text(sim['atol'])}"


def _tolerance_sets(integrator: str, value: float) -> list[str]:
    """``--set`` overrides that give a run the tolerance (or step) ``value``."""
    if INTEGRATORS[integrator].adaptive:
        return [f"simulation.rtol={value!r}", f"simulation.atol={value!r}"]
    return [f"simulation.step={value!r}"]


def _make_case(case: str | Path | dict | Case, sets: list[str]) -> Case:
    """Validate ``case`` (a file, a dict as read from YAML, or a Case) with overrides."""
    if isinstance(case, (str, Path)):
        return load_case(case, sets)
    data, source = (case.data, case.source) if isinstance(case, Case) else (case, "<dict>")
    return validate_case(apply_overrides(copy.deepcopy(data), sets), source=source)


def _nanmax_abs(a) -> float:
    a = np.abs(np.asarray(a, dtype=float))
    if a.size == 0 or np.all(np.isnan(a)):
        return NAN
    return float(np.nanmax(a))


def _short(message: str, n: int = 120) -> str:
    message = " ".join(str(message).split())
    return message if len(message) <= n else message[:n - 3] + "..."


def _result_or_empty(run: Run, comparison: Comparison) -> Result:
    """The run's result, or an empty failed one (a run that raised or never ran)."""
    if run.result is not None:
        return run.result
    return Result(
        mechanism=comparison.mechanism, coordinate_names=[], load_names=[], observable_names=[],
        case_yaml=run.case_yaml, t=np.zeros(0), q=np.zeros((0, 0)), qd=np.zeros((0, 0)), qdd=np.zeros((0, 0)),
        lam=np.zeros((0, 0)), phi=np.zeros((0, 0)), phi_dot=np.zeros((0, 0)), kinetic=np.zeros(0),
        potential=np.zeros(0), work=np.zeros((0, 0)), loads=np.zeros((0, 0)),
        generalized_forces=np.zeros((0, 0)), observables=np.zeros((0, 0)), observable_rates=np.zeros((0, 0)),
        status="failed", message=run.message, wall_time=0.0 if math.isnan(run.wall_time) else run.wall_time,
    )


def _format_rows(runs: Sequence[Run], with_tol: bool) -> list[str]:
    width = max([6, *(len(r.method) for r in runs)])
    tol_width = max([7, *(len(_run_setting(r)) for r in runs)])
    cols = [("max|Phi|", "max_phi"), ("final|Phi|", "final_phi"), ("max|Phi_q qd|", "max_phi_dot"),
            ("motion err", "motion_error"), ("final err", "final_error"), ("wall [s]", "wall_time")]
    head = f"{'method':<{width}}" + (f"  {'setting':<{tol_width}}" if with_tol else "") + f"  {'status':<7}"
    head += "".join(f"  {label:>{max(len(label), 9)}}" for label, _ in cols) + f"  {'RHS evals':>9}  {'steps':>8}"
    lines = [head, "-" * len(head)]
    for r in runs:
        line = f"{r.method:<{width}}" + (f"  {_run_setting(r):<{tol_width}}" if with_tol else "") + f"  {r.status:<7}"
        for label, attr in cols:
            value = getattr(r, attr)
            text = "-" if math.isnan(value) else f"{value:.2e}"
            if attr == "motion_error" and r.error_note and "stopped early" in r.error_note:
                text += "*"
            line += f"  {text:>{max(len(label), 9)}}"
        line += f"  {r.nfev:>9d}  {r.nsteps:>8d}"
        lines.append(line)
    if any("stopped early" in r.error_note for r in runs):
        lines.append("* over the output times before the run stopped")
    return lines


# --------------------------------------------------------------------------- running


def _execute(case_data: dict, source: str) -> tuple[Result | None, str]:
    """Run one validated case in this process; an exception becomes (None, message).

    The numeric model is built (or loaded from the cache) before the run, so that the run's
    wall time is the simulation's alone.
    """
    try:
        case = validate_case(copy.deepcopy(case_data), source=source)
        numeric_model(case)
        return run_case(case), ""
    except Exception as exc:  # a bug or an unexpected numerical error: a failed row, not a crash
        return None, f"{type(exc).__name__}: {exc}"


def _worker_init() -> None:
    """Workers ignore Ctrl-C: the parent process stops them."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class _InterruptFlag:
    """Records Ctrl-C in the main thread while passing it on (as KeyboardInterrupt).

    The driver turns a KeyboardInterrupt inside an integration into a failed run; the flag
    tells the comparison to stop there instead of going on with the next run.
    """

    def __init__(self):
        self.set = False
        self._old = None

    def __enter__(self):
        old = signal.getsignal(signal.SIGINT)
        if threading.current_thread() is threading.main_thread() and callable(old):
            self._old = old

            def handler(signum, frame):
                self.set = True
                self._old(signum, frame)
            signal.signal(signal.SIGINT, handler)
        return self

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        return False


def compare(case: str | Path | dict | Case, methods: Sequence[str] | None = None,
            tolerances: Sequence[float] | None = None, overrides: Sequence[str] = (),
            reference: ReferenceSettings | None = None, jobs: int | None = None,
            progress: Callable[[Run, int, int], None] | None = None) -> Comparison:
    """Run ``case`` with each stabilization method (and tolerance), and a reference run.

    Parameters
    ----------
    case : path, dict or Case
        The case file, the case as read from YAML, or a validated case.
    methods : sequence of str, optional
        Stabilization methods (names of :data:`csim.solver.stabilizers.STABILIZERS`).
        Default: every registered method that the case allows (the others are listed in
        ``Comparison.skipped``); methods named here must all be allowed.
    tolerances : sequence of float, optional
        A work-precision study: each method runs at each value, which sets rtol = atol of an
        adaptive integrator, or ``simulation.step`` [s] of a fixed-step one (RK4). Default:
        one run per method at the case's own setting.
    overrides : sequence of str
        ``key.path=value`` overrides applied to the case first (as ``--set``).
    reference : ReferenceSettings, optional
        The reference run's method, integrator and tolerance (default projection, DOP853,
        rtol = atol = 1e-12).
    jobs : int, optional
        Worker processes; default min(number of runs, CPU count). 1 runs everything in this
        process.
    progress : callable, optional
        Called as ``progress(run, done, total)`` after each run finishes.

    Returns
    -------
    Comparison
        Runs that failed are rows with status ``failed``; nothing but bad input raises.

    Raises
    ------
    CaseError
        Before any run, for an unknown or duplicate method, a bad tolerance, a bad jobs
        count, or a (method, tolerance) combination the case validation rejects (the
        message names the method).

    Notes
    -----
    With more than one job the runs go to fresh ("spawn") worker processes, which import
    the calling script again: a script that calls this function with jobs > 1 needs the
    usual ``if __name__ == "__main__":`` guard. Ctrl-C stops the comparison: the runs not
    finished are returned as failed rows and ``Comparison.interrupted`` is set.
    """
    reference = reference or ReferenceSettings()
    overrides = list(overrides)
    problems = []
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        problems.append(f"jobs: got {jobs!r}; expected a whole number >= 1")
    try:
        chosen = check_methods(methods) if methods is not None else None
    except CaseError as exc:
        problems += exc.problems
        chosen = []
    try:
        tols = check_tolerances(tolerances) if tolerances is not None else None
    except CaseError as exc:
        problems += exc.problems
        tols = None
    for check, value, option in ((check_tolerances, reference.tol, "reference tolerance"),
                                 (check_methods, reference.method, "reference method")):
        try:
            check([value], option)
        except CaseError as exc:
            problems += exc.problems
    if problems:
        raise CaseError(problems)

    base = _make_case(case, overrides)
    integrator = base.data["simulation"]["integrator"]
    chosen = chosen if chosen is not None else default_methods(integrator)
    skipped = {}
    if tols is not None:
        # one study sets one kind of value: tolerances of adaptive integrators, or steps [s]
        kind = _tolerance_kind(integrator)
        other = {m: i for m in chosen if _tolerance_kind(i := split_method(m)[1] or integrator) != kind}
        if other and methods is None:
            for m, i in other.items():
                skipped[m] = (f"its integrator {i} takes {_tolerance_label(i)}, the case's {integrator} "
                              f"{_tolerance_label(integrator)}: one study sets one kind")
            chosen = [m for m in chosen if m not in other]
        elif other:
            same = [m for m in chosen if m not in other]
            raise CaseError([f"tolerances: the values set {_tolerance_label(integrator)} for "
                             f"{', '.join(same) or integrator} but the step or tolerance of another kind for "
                             f"{', '.join(other)}; compare adaptive and fixed-step integrators in separate studies"])
    values = tols if tols is not None else [_own_tolerance(base)[0]]

    def value_sets(method, value):
        # the tolerance (or step) of a method's own integrator, when it names one
        return _tolerance_sets(split_method(method)[1] or integrator, value) if tols is not None else []

    # every (method, tolerance) case, validated before anything runs
    cases: dict[tuple[str, float], Case] = {}
    failures: dict[str, dict[str, list[float]]] = {}  # problem -> method -> tolerances
    for method in chosen:
        for value in values:
            try:
                cases[method, value] = _make_case(case, [*overrides, *_method_sets(method), *value_sets(method, value)])
            except CaseError as exc:
                for p in exc.problems:
                    failures.setdefault(p, {}).setdefault(method, []).append(value)
    if failures and methods is None:
        # a default comparison leaves out the methods this case does not allow
        bad = {m for per_method in failures.values() for m in per_method}
        if bad != set(chosen):
            for method in [m for m in chosen if m in bad]:
                skipped[method] = "; ".join(p for p, per_method in failures.items() if method in per_method)
            chosen = [m for m in chosen if m not in bad]
            failures = {}
    if failures:
        raise CaseError([_prefix(per_method, chosen, values, tols is not None, integrator) + p
                         for p, per_method in failures.items()])
    # one backend for every run, so that wall times compare methods, not backends: under
    # `backend: auto`, a method without a compiled path (minimal, ggl) puts all on Python
    python_only = sorted({m for (m, _), c in cases.items() if resolve_backend(c.data) == "python"}, key=chosen.index)
    backend_note = ""
    if python_only and len(python_only) < len(chosen):
        on_python = [*overrides, "simulation.backend=python"]
        cases = {(m, v): _make_case(case, [*on_python, *_method_sets(m), *value_sets(m, v)]) for (m, v) in cases}
        backend_note = (f"python for every run ({', '.join(python_only)} has no compiled path; one backend keeps "
                        f"the wall times comparable)")
    try:
        ref_case = _make_case(case, [*overrides, f"stabilization.method={reference.run_method}",
                                     f"simulation.integrator={reference.run_integrator}",
                                     *_tolerance_sets(reference.run_integrator, reference.tol)])
    except CaseError as exc:
        raise CaseError([f"reference run ({reference.describe()}): {p}" for p in exc.problems]) from None

    ref_run = Run(reference.method, *_own_tolerance(ref_case), case_yaml=ref_case.to_yaml())
    # each run's own setting: the study's value, or the case's (or its own integrator's) setting
    runs = [Run(m, *_own_tolerance(cases[m, v]), case_yaml=cases[m, v].to_yaml()) for m in chosen for v in values]
    tasks = [(ref_run, ref_case), *((run, cases[m, v]) for run, (m, v) in zip(runs, product(chosen, values)))]
    n_jobs = min(jobs, len(tasks)) if jobs is not None else max(1, min(len(tasks), os.cpu_count() or 1))
    with _InterruptFlag() as flag:
        interrupted = (_run_serial if n_jobs == 1 else _run_parallel)(tasks, n_jobs, progress, flag)

    for run in runs:
        run.measure_against(ref_run)
    return Comparison(
        source=base.source, case_yaml=base.to_yaml(), mechanism=base.mechanism.name,
        coordinate_units=list(base.mechanism.coordinate_units), methods=chosen,
        tolerances=tols, tolerance_kind=_own_tolerance(base)[1] if tols is None else _tolerance_kind(integrator),
        integrator=integrator,
        reference=reference, reference_run=ref_run, runs=runs, jobs=n_jobs, skipped=skipped,
        interrupted=interrupted, setting=_setting_text(base), backend_note=backend_note,
    )


def _prefix(per_method: dict[str, list[float]], methods: list[str], values: list[float], study: bool,
            integrator: str) -> str:
    """Which runs a validation problem concerns, e.g. ``"method projection: "``."""
    parts = []
    if set(per_method) != set(methods) or len(methods) == 1:
        parts.append("method " + ", ".join(per_method))
    tols = sorted({v for vs in per_method.values() for v in vs}, reverse=True)
    if study and (len(tols) != len(values) or len(values) == 1):
        parts.append(f"{_tolerance_label(integrator)} " + ", ".join(f"{v:g}" for v in tols))
    return (", ".join(parts) + ": ") if parts else ""


def _run_serial(tasks, n_jobs, progress, flag) -> bool:
    total = len(tasks)
    for done, (run, case) in enumerate(tasks, start=1):
        try:
            result, message = _execute(case.data, case.source)
        except KeyboardInterrupt:
            flag.set = True
            result, message = None, INTERRUPTED
        run.set_result(result, message)  # a run that Ctrl-C stopped says so itself
        if flag.set:  # the remaining runs keep their message INTERRUPTED
            return True
        if progress is not None:
            progress(run, done, total)
    return False


#: environment variables that set the thread count of numpy's linear algebra
_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


@contextmanager
def _worker_environment():
    """Worker processes started inside the block get one BLAS thread (unless the user chose
    a number: the runs' matrices are small, the processes are the parallelism, and idle BLAS
    threads spinning on shared cores slow every run down several times) and ignore Ctrl-C."""
    saved = {name: os.environ.get(name) for name in _BLAS_THREADS}
    for name in _BLAS_THREADS:
        os.environ.setdefault(name, "1")
    # Ctrl-C at a terminal reaches every process of the group: workers start with SIGINT
    # blocked (the mask survives exec), so that only this process handles it; a Ctrl-C
    # during the few milliseconds of the block is delivered here when it ends.
    block = hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()
    if block:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        if block:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _run_parallel(tasks, n_jobs, progress, flag) -> bool:
    # derive (and cache on disk) the model once, not in every worker at the same time; should
    # that fail, each worker reports the failure as its run's
    with contextlib.suppress(Exception):
        numeric_model(tasks[0][1])
    total, done = len(tasks), 0
    context = multiprocessing.get_context("spawn")  # no fork of a threaded process; same on every OS
    executor = cf.ProcessPoolExecutor(max_workers=n_jobs, mp_context=context, initializer=_worker_init)
    futures = {}
    try:
        with _worker_environment():  # the workers start while the first runs are submitted
            for run, case in tasks:  # the reference first: it is the longest
                futures[executor.submit(_execute, case.data, case.source)] = run
        for future in cf.as_completed(futures):
            run = futures[future]
            try:
                result, message = future.result()
            except Exception as exc:  # the worker died, or its result could not come back
                result, message = None, f"worker process failed: {type(exc).__name__}: {exc}"
            run.set_result(result, message)
            done += 1
            if progress is not None:
                progress(run, done, total)
    except KeyboardInterrupt:
        for future, run in futures.items():  # runs that finished before the interrupt keep their results
            if run.result is None and future.done() and not future.cancelled() and future.exception() is None:
                run.set_result(*future.result())
        processes = list((getattr(executor, "_processes", None) or {}).values())
        executor.shutdown(wait=False, cancel_futures=True)
        for process in processes:
            process.terminate()
        for process in processes:
            process.join(5)
        for future, run in futures.items():
            if run.result is None and (not future.done() or future.cancelled()):
                run.set_result(None, INTERRUPTED)
        return True
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
    return False


__all__ = ["Comparison", "ReferenceSettings", "Run", "check_methods", "check_tolerances", "compare",
           "parse_methods", "parse_tolerances"]
