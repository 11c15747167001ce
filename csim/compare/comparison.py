"""A comparison: :func:`compare` runs one, :class:`Comparison` is what it returns.

:func:`compare` reads top to bottom: plan the runs (:mod:`csim.compare.plan`), run them
with the reference (:mod:`csim.compare.pool`), measure each against the reference
(:mod:`csim.compare.metrics`), and gather them in a :class:`Comparison`, which prints as a
table (:mod:`csim.compare.table`) and writes the comparison file (:mod:`csim.compare.files`).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from csim.case import Case
from csim.compare.files import table_columns, write_file
from csim.compare.plan import CaseInput, Plan, ReferenceSettings, own_tolerance, plan_comparison, setting_text
from csim.compare.pool import Progress, job_count, run_tasks
from csim.compare.runs import Run, run_setting
from csim.compare.specs import tolerance_kind
from csim.compare.table import comparison_report, format_table
from csim.report import Report


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
    repeat: int = 1
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
        return f"{run.method} ({run_setting(run)})"

    def table_columns(self, runs: Sequence[Run]) -> dict[str, list]:
        """The columns of a table of ``runs`` (see :data:`csim.io.hdf5.COMPARISON_UNITS`)."""
        return table_columns(runs)

    def write(self, path: str | Path) -> None:
        """Write the comparison file (atomically; layout in :mod:`csim.io.hdf5`)."""
        write_file(self, path)

    def table(self) -> str:
        """The comparison as plain aligned text: settings, one row per method (and one per
        method and tolerance of a study), and the failures below."""
        return format_table(self)

    def report(self) -> Report:
        """The comparison as a report (:mod:`csim.report`): what ``csim compare`` prints,
        as rich tables on a terminal and as :meth:`table` otherwise."""
        return comparison_report(self)


def compare(case: CaseInput, methods: Sequence[str] | None = None,
            tolerances: Sequence[float] | None = None, overrides: Sequence[str] = (),
            reference: ReferenceSettings | None = None, jobs: int | None = None,
            progress: Progress | None = None, warn: Callable[[str], None] | None = None,
            repeat: int = 1) -> Comparison:
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
    repeat : int
        Run each case this many times (the reference's too) and keep the median wall time.
    warn : callable, optional
        Called before the runs with each warning of the runs' cases (a stabilizer gain times
        a fixed step outside the integrator's stability region, :attr:`csim.case.Case.warnings`),
        once per method and setting: ``"baumgarte at step = 1.00e-03 s: stabilization.w *
        simulation.step = 10 lies outside ..."``.

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
    plan = plan_comparison(case, methods, tolerances, overrides, reference, jobs)
    if warn is not None:
        for warning in case_warnings(plan, reference.method):
            warn(warning)
    ref_run = _new_run(reference.method, plan.reference_case)
    # the reference first (in a pool it is the longest); then method by method, loosest value first
    tasks = [(ref_run, plan.reference_case), *((_new_run(m, c), c) for m, c in plan.run_cases())]
    runs = [run for run, _ in tasks[1:]]
    n_jobs = job_count(jobs, len(tasks))
    interrupted = run_tasks(tasks, n_jobs, progress, repeat=repeat)
    for run in runs:
        run.measure_against(ref_run)
    comparison = _gather(plan, reference, ref_run, runs, n_jobs, interrupted)
    comparison.repeat = repeat
    return comparison


def case_warnings(plan: Plan, reference_method: str) -> list[str]:
    """The warnings of the cases of ``plan``'s runs (the reference's first), each once, led by
    the method and setting it concerns."""
    runs = [(reference_method, plan.reference_case), *plan.run_cases()]
    return list(dict.fromkeys(f"{method} at {setting_text(case)}: {warning}"
                              for method, case in runs for warning in case.warnings))


def _new_run(method: str, case: Case) -> Run:
    """A run not made yet (a failed row until it is): ``method`` on its validated ``case``, at
    the case's own setting (the study's value, or the case's or its own integrator's)."""
    return Run(method, *own_tolerance(case), case_yaml=case.to_yaml())


def _gather(plan: Plan, reference: ReferenceSettings, ref_run: Run, runs: list[Run], n_jobs: int,
            interrupted: bool) -> Comparison:
    """The Comparison of the finished (or interrupted) runs of ``plan``."""
    base = plan.base
    study_kind = tolerance_kind(plan.integrator) if plan.tolerances is not None else own_tolerance(base)[1]
    return Comparison(
        source=base.source, case_yaml=base.to_yaml(), mechanism=base.mechanism.name,
        coordinate_units=list(base.mechanism.coordinate_units), methods=plan.methods,
        tolerances=plan.tolerances, tolerance_kind=study_kind, integrator=plan.integrator,
        reference=reference, reference_run=ref_run, runs=runs, jobs=n_jobs, skipped=plan.skipped,
        interrupted=interrupted, setting=setting_text(base), backend_note=plan.backend_note,
    )
