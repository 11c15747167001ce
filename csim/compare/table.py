"""The comparison as a report (:mod:`csim.report`), as ``csim compare`` prints it.

:func:`comparison_report` holds, top to bottom: the settings (case, reference, what the
errors and timings mean, backend, skipped methods), a table with one row per method, one
with a row per method and tolerance of a study, and the notes (failures, partial errors).
:func:`format_table` is its plain text (stdout not a terminal; the file's ``table``).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from csim.compare.runs import Run, run_setting, shorten
from csim.compare.specs import TOLERANCE_LABELS, tol_text
from csim.report import Column, Fields, Lines, Report, Table

if TYPE_CHECKING:
    from csim.compare.comparison import Comparison

#: (header, Run attribute) of the columns of numbers, before RHS evaluations and steps
_NUMBER_COLUMNS = [("max|Phi|", "max_phi"), ("final|Phi|", "final_phi"), ("max|Phi_q qd|", "max_phi_dot"),
                   ("motion err", "motion_error"), ("final err", "final_error"), ("wall [s]", "wall_time")]

#: the footnote of a motion error marked ``*``
_EARLY_STOP = "stopped early"


def format_table(c: Comparison) -> str:
    """The comparison as plain aligned text (see :func:`comparison_report`)."""
    return comparison_report(c).plain()


def comparison_report(c: Comparison) -> Report:
    """The comparison: settings, a table with one row per method (and one with a row per
    method and tolerance of a study), and the failures below."""
    report = Report([Fields(_settings(c), width=12)])
    report.add(*_method_section(c))
    if c.tolerances is not None:
        label = TOLERANCE_LABELS[c.tolerance_kind]
        report.add(Lines(["", f"work-precision ({label} = " + ", ".join(tol_text(t) for t in c.tolerances) + "):"]),
                   run_table(c.runs, with_tol=True))
    notes = _notes(c)
    if notes:
        report.add(Lines(["", *notes]))
    return report


def _settings(c: Comparison) -> list[tuple[str, str]]:
    """The fields above the rows: the case, the reference, what the numbers mean, and why
    runs are on one backend, left out, or unfinished."""
    ref = c.reference_run
    ref_text = f"{c.reference.describe()}: {ref.status}"
    if ref.result is not None:
        ref_text += f", {ref.nfev} RHS evals, {ref.wall_time:.2e} s"
    items = [("case", f"{c.source} ({c.mechanism}, {c.integrator})"), ("reference", ref_text),
             ("errors", "motion = max over the output times and coordinates of |q - q_ref| [rad or m]; "
                        "final = the same at t_end"),
             ("timing", f"wall time of each run in its own process, jobs = {c.jobs} (parallel runs share the CPU)"
                        if c.jobs > 1 else "wall time of each run, one at a time in this process (jobs = 1)")]
    if c.backend_note:
        items.append(("backend", c.backend_note))
    for method, reason in c.skipped.items():
        items.append(("skipped", f"{method}: {shorten(reason, 160)}"))
    if c.interrupted:
        items.append(("interrupted", "Ctrl-C stopped the comparison; unfinished runs are marked failed"))
    return items


def _method_section(c: Comparison) -> list:
    """The table of the runs in the file's method groups, under a title that says their setting."""
    per_method = list(c.method_runs.values())
    # a method that names its own integrator may run at another setting than the case's
    own_settings = c.tolerances is None and len({run_setting(r) for r in per_method}) > 1
    if own_settings:
        title = f"per method (the case: {c.setting}; a method's own integrator: its own setting):"
    elif c.tolerances is None:
        title = f"per method ({c.setting}, as in the case):"
    else:
        title = f"per method (the tightest {TOLERANCE_LABELS[c.tolerance_kind]}: the runs in the file's method groups):"
    return [Lines(["", title]), run_table(per_method, with_tol=c.tolerances is not None or own_settings)]


def _notes(c: Comparison) -> list[str]:
    """The lines below the rows: the failures, and the errors missing or partial."""
    ref = c.reference_run
    notes = []
    if not ref.ok:
        notes.append(f"reference: failed: {shorten(ref.message, 200)}; motion errors are unavailable (-)")
    for r in c.runs:
        name = c.label(r)
        if not r.ok:
            notes.append(f"{name}: failed: {shorten(r.message, 200)}")
        if r.error_note and ref.ok:
            notes.append(f"{name}: {r.error_note}")
    return notes


def run_table(runs: Sequence[Run], with_tol: bool) -> Table:
    """One row per run: method, (setting, when ``with_tol``), status, the errors, wall time,
    RHS evaluations and steps.

    A motion error over part of the run (it stopped early) is marked ``*``, with a footnote;
    a missing number is ``-``.
    """
    columns = [Column("method", "left"), *([Column("setting", "left")] if with_tol else []), Column("status", "left"),
               *(Column(label) for label, _ in _NUMBER_COLUMNS), Column("RHS evals"), Column("steps")]
    table = Table(columns)
    for r in runs:
        row = [r.method, *([run_setting(r)] if with_tol else []), r.status]
        for _, attr in _NUMBER_COLUMNS:
            value = getattr(r, attr)
            text = "-" if math.isnan(value) else f"{value:.2e}"
            if attr == "motion_error" and _EARLY_STOP in r.error_note:
                text += "*"
            row.append(text)
        table.rows.append([*row, str(r.nfev), str(r.nsteps)])
    if any(_EARLY_STOP in r.error_note for r in runs):
        table.notes.append("* over the output times before the run stopped")
    return table

