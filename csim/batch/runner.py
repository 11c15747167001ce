"""Running a batch: every entry of a manifest, in parallel processes, each checked against
its expectations.

:func:`run_batch` hands the entries to :func:`csim.compare.pool.run_tasks` (the worker
pool of ``csim compare``: spawned workers with one BLAS thread each, reused from run to
run; Ctrl-C stops them all, and an exception in a run becomes that run's failure) and
returns a :class:`Batch`, which prints as a pass/fail table and writes result files and a
JUnit report (:mod:`csim.batch.junit`).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from csim.batch.expectations import Outcome
from csim.batch.manifest import Entry, Manifest
from csim.compare.pool import job_count, run_tasks
from csim.compare.runs import INTERRUPTED, shorten
from csim.report import Column, Fields, Lines, Report, Table
from csim.result import Result


@dataclass
class CaseRun:
    """One entry's run and the outcome of each of its expectations.

    Until it has run (or when Ctrl-C kept it from finishing) it is a failed run without
    samples whose message is :data:`csim.compare.runs.INTERRUPTED`.

    Attributes
    ----------
    entry : Entry
    result : Result or None
        The run; None until it ran (see :attr:`record` for a result in every case).
    message : str
        Why there is no result (the exception a run raised), or ``""``.
    outcomes : list of Outcome
        One per expectation of the entry, in its order.
    """

    entry: Entry
    result: Result | None = None
    message: str = INTERRUPTED
    outcomes: list[Outcome] = field(default_factory=list)

    def __post_init__(self):
        self.outcomes = [e.check(self.record) for e in self.entry.expectations]

    def set_result(self, result: Result | None, message: str = "") -> None:
        """Take the run's result (None: the run raised ``message``) and check the expectations."""
        self.result, self.message = result, message
        self.outcomes = [e.check(self.record) for e in self.entry.expectations]

    @property
    def record(self) -> Result:
        """The run's result, or, for a run that raised or never ran, a failed result without
        samples whose message says why (what ``-o DIR`` writes for it)."""
        if self.result is not None:
            return self.result
        c = self.entry.case
        m = c.mechanism
        return Result.empty(m.name, m.coordinate_names, [ld.name for ld in m.loads], [ob.name for ob in m.observables],
                            m.n_constraints, c.to_yaml(), message=self.message,
                            failure="interrupted" if self.message == INTERRUPTED else "",
                            run_kind="kinematic" if c.kinematic else "simulation")

    @property
    def passed(self) -> bool:
        """Whether every expectation holds."""
        return all(o.passed for o in self.outcomes)

    @property
    def failures(self) -> list[Outcome]:
        """The expectations that do not hold."""
        return [o for o in self.outcomes if not o.passed]

    @property
    def wall_time(self) -> float:
        """The run's wall time [s] (0 for a run without a result)."""
        return float(self.result.wall_time) if self.result is not None else 0.0


@dataclass
class Batch:
    """The runs of a manifest and how they were made.

    Attributes
    ----------
    manifest : Manifest
    runs : list of CaseRun
        One per entry, in manifest order.
    jobs : int
        Processes that ran them (1: in this process).
    interrupted : bool
        Whether Ctrl-C stopped the batch (unfinished runs fail their expectations).
    """

    manifest: Manifest
    runs: list[CaseRun]
    jobs: int = 1
    interrupted: bool = False

    @property
    def passed(self) -> bool:
        """Whether every expectation of every entry holds (and nothing was interrupted)."""
        return not self.interrupted and all(r.passed for r in self.runs)

    @property
    def failed(self) -> list[CaseRun]:
        """The runs with an expectation that does not hold."""
        return [r for r in self.runs if not r.passed]

    def table(self) -> str:
        """The pass/fail table, the failed expectations below it, and a count, as plain text."""
        return format_table(self)

    def report(self) -> Report:
        """The same as a report (:mod:`csim.report`): rich tables on a terminal."""
        return batch_report(self)

    def write_results(self, folder: str | Path) -> list[Path]:
        """Write each run's result file, ``FOLDER/NAME.h5`` (a run that raised or never ran:
        a failed result without samples, its message saying why). Returns the paths."""
        from csim.io.hdf5 import write_result

        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        paths = []
        for run in self.runs:
            path = folder / f"{run.entry.name}.h5"
            write_result(path, run.record, run.entry.case.mechanism.coordinate_units)
            paths.append(path)
        return paths

    def write_junit(self, path: str | Path) -> None:
        """Write the JUnit XML report (see :func:`csim.batch.junit.write_junit`)."""
        from csim.batch.junit import write_junit

        write_junit(self, path)


def run_batch(manifest: Manifest, jobs: int | None = None,
              progress: Callable[[CaseRun, int, int], None] | None = None) -> Batch:
    """Run every entry of ``manifest`` and check its expectations.

    Parameters
    ----------
    manifest : Manifest
        From :func:`csim.batch.manifest.load_manifest`.
    jobs : int, optional
        Worker processes; default min(number of entries, CPU count). 1 runs everything in
        this process.
    progress : callable, optional
        Called as ``progress(run, done, total)`` after each run finishes.

    Returns
    -------
    Batch
        Nothing raises for a failed run or a failed expectation: they are in the Batch.

    Notes
    -----
    With more than one job the runs go to fresh ("spawn") worker processes, which import
    the calling script again: a script that calls this with jobs > 1 needs the usual
    ``if __name__ == "__main__":`` guard.
    """
    runs = [CaseRun(entry) for entry in manifest.entries]
    n_jobs = job_count(jobs, len(runs))
    interrupted = run_tasks([(run, run.entry.case) for run in schedule(runs)], n_jobs, progress)
    return Batch(manifest=manifest, runs=runs, jobs=n_jobs, interrupted=interrupted)


def schedule(runs: list[CaseRun]) -> list[CaseRun]:
    """The order to start the runs in, so that workers do not compile the same kernels twice.

    On a cold cache the first compiled run of a mechanism compiles its kernels (about 30 s);
    a second worker that starts a run of that mechanism meanwhile compiles them again. So
    the first compiled run of each mechanism goes first (different mechanisms compile side
    by side), then the runs on the Python path (which compile nothing), then the rest.
    Within each group the manifest's order is kept.
    """
    from csim.fast import resolve_backend
    from csim.model.cache import definition_key

    first, python, rest, seen = [], [], [], set()
    for run in runs:
        case = run.entry.case
        if case.kinematic or resolve_backend(case) != "compiled":
            python.append(run)
            continue
        key = definition_key(case.mechanism)
        (rest if key in seen else first).append(run)
        seen.add(key)
    return [*first, *python, *rest]


#: (header, justify, text of a run) of the table's columns after the name
_COLUMNS: list[tuple[str, str, Callable[[CaseRun], str]]] = [
    ("result", "left", lambda r: "pass" if r.passed else "FAIL"),
    ("status", "left", lambda r: r.record.status),
    ("wall [s]", "right", lambda r: f"{r.wall_time:.3f}" if r.result is not None else "-"),
    ("max|Phi|", "right", lambda r: _number(r.record.max_phi)),
    ("energy err", "right", lambda r: _energy(r.record)),
    ("events", "right", lambda r: str(len(r.record.event_times))),
    ("backend", "left", lambda r: r.record.backend if r.result is not None else "-"),
    ("checks", "right", lambda r: f"{sum(o.passed for o in r.outcomes)}/{len(r.outcomes)}"),
]


def _number(value: float) -> str:
    return "-" if math.isnan(value) else f"{value:.2e}"


def _energy(result: Result) -> str:
    if result.t.size == 0 or result.run_kind == "kinematic":
        return "-"
    value, unit = result.energy_balance
    return _number(value) + (f" {unit}" if unit else "")


def batch_table(batch: Batch) -> Table:
    """One row per entry: its name, pass/FAIL, status, wall time, max |Phi|, energy error,
    events, backend and expectations held / checked."""
    table = Table([Column("case", "left"), *(Column(h, j) for h, j, _ in _COLUMNS)])
    table.rows = [[run.entry.name, *(text(run) for _, _, text in _COLUMNS)] for run in batch.runs]
    return table


def batch_report(batch: Batch) -> Report:
    """The batch: the manifest, the table (:func:`batch_table`), the failed expectations
    (measured against expected) below it, and the count passed."""
    report = Report([Fields([("manifest", f"{batch.manifest.path} ({len(batch.runs)} cases, jobs = {batch.jobs}"
                                          + ("; wall times of parallel runs share the CPU)" if batch.jobs > 1
                                             else ")"))]),
                     Lines([""]), batch_table(batch)])
    failed = batch.failed
    lines = []
    if failed:
        lines += ["", "failed expectations:"]
        for run in failed:
            lines += [f"  {run.entry.name}: {o.message}" for o in run.failures]
    if batch.interrupted:
        lines += ["", "interrupted: Ctrl-C stopped the batch; unfinished runs fail their expectations"]
    lines += ["", f"{len(batch.runs) - len(failed)} of {len(batch.runs)} cases passed"
              + (f", {len(failed)} failed: {shorten(', '.join(r.entry.name for r in failed), 200)}" if failed else "")]
    return report.add(Lines(lines))


def format_table(batch: Batch) -> str:
    """The batch as plain aligned text (see :func:`batch_report`)."""
    return batch_report(batch).plain()
