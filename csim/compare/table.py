"""The comparison as plain aligned text, as ``csim compare`` prints it.

:func:`format_table` writes, top to bottom: the settings (case, reference, what the errors
and timings mean, backend, skipped methods), one row per method, one per method and
tolerance of a study, and the notes (failures, partial errors).
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from csim.compare.runs import Run, run_setting, shorten
from csim.compare.specs import TOLERANCE_LABELS, tol_text

if TYPE_CHECKING:
    from csim.compare.comparison import Comparison

#: (header, Run attribute) of the columns of numbers, before RHS evaluations and steps
_NUMBER_COLUMNS = [("max|Phi|", "max_phi"), ("final|Phi|", "final_phi"), ("max|Phi_q qd|", "max_phi_dot"),
                   ("motion err", "motion_error"), ("final err", "final_error"), ("wall [s]", "wall_time")]

#: the footnote of a motion error marked ``*``
_EARLY_STOP = "stopped early"


def format_table(c: Comparison) -> str:
    """The comparison as text: settings, one row per method (and one per method and
    tolerance of a study), and the failures below."""
    lines = _settings_lines(c)
    lines += _method_section(c)
    if c.tolerances is not None:
        label = TOLERANCE_LABELS[c.tolerance_kind]
        lines += ["", f"work-precision ({label} = " + ", ".join(tol_text(t) for t in c.tolerances) + "):",
                  *format_rows(c.runs, with_tol=True)]
    notes = _notes(c)
    if notes:
        lines += ["", *notes]
    return "\n".join(lines)


def _settings_lines(c: Comparison) -> list[str]:
    """The lines above the rows: the case, the reference, what the numbers mean, and why
    runs are on one backend, left out, or unfinished."""
    ref = c.reference_run
    ref_line = f"reference:  {c.reference.describe()}: {ref.status}"
    if ref.result is not None:
        ref_line += f", {ref.nfev} RHS evals, {ref.wall_time:.2e} s"
    lines = [f"case:       {c.source} ({c.mechanism}, {c.integrator})", ref_line,
             "errors:     motion = max over the output times and coordinates of |q - q_ref| [rad or m]; "
             "final = the same at t_end",
             f"timing:     wall time of each run in its own process, jobs = {c.jobs}"
             + (" (parallel runs share the CPU)" if c.jobs > 1 else "")]
    if c.backend_note:
        lines.append(f"backend:    {c.backend_note}")
    for method, reason in c.skipped.items():
        lines.append(f"skipped:    {method}: {shorten(reason, 160)}")
    if c.interrupted:
        lines.append("interrupted: Ctrl-C stopped the comparison; unfinished runs are marked failed")
    return lines


def _method_section(c: Comparison) -> list[str]:
    """The rows of the runs in the file's method groups, under a title that says their setting."""
    per_method = list(c.method_runs.values())
    # a method that names its own integrator may run at another setting than the case's
    own_settings = c.tolerances is None and len({run_setting(r) for r in per_method}) > 1
    if own_settings:
        title = f"per method (the case: {c.setting}; a method's own integrator: its own setting):"
    elif c.tolerances is None:
        title = f"per method ({c.setting}, as in the case):"
    else:
        title = f"per method (the tightest {TOLERANCE_LABELS[c.tolerance_kind]}: the runs in the file's method groups):"
    return ["", title, *format_rows(per_method, with_tol=c.tolerances is not None or own_settings)]


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


def format_rows(runs: Sequence[Run], with_tol: bool) -> list[str]:
    """A header, a rule and one row per run (with a ``setting`` column when ``with_tol``).

    A motion error over part of the run (it stopped early) is marked ``*``, with a footnote.
    """
    width = max([6, *(len(r.method) for r in runs)])
    tol_width = max([7, *(len(run_setting(r)) for r in runs)])
    head = f"{'method':<{width}}" + (f"  {'setting':<{tol_width}}" if with_tol else "") + f"  {'status':<7}"
    head += "".join(f"  {label:>{max(len(label), 9)}}" for label, _ in _NUMBER_COLUMNS)
    head += f"  {'RHS evals':>9}  {'steps':>8}"
    lines = [head, "-" * len(head)]
    for r in runs:
        line = f"{r.method:<{width}}" + (f"  {run_setting(r):<{tol_width}}" if with_tol else "") + f"  {r.status:<7}"
        for label, attr in _NUMBER_COLUMNS:
            value = getattr(r, attr)
            text = "-" if math.isnan(value) else f"{value:.2e}"
            if attr == "motion_error" and _EARLY_STOP in r.error_note:
                text += "*"
            line += f"  {text:>{max(len(label), 9)}}"
        line += f"  {r.nfev:>9d}  {r.nsteps:>8d}"
        lines.append(line)
    if any(_EARLY_STOP in r.error_note for r in runs):
        lines.append("* over the output times before the run stopped")
    return lines
