"""``csim.compare.table`` and ``csim.compare.files``: the report's tables and the file's columns, from Runs
made by hand."""
from __future__ import annotations

import io
import math

from rich.console import Console

from csim.compare.comparison import Comparison
from csim.compare.files import table_columns
from csim.compare.plan import ReferenceSettings
from csim.compare.runs import Run
from csim.compare.table import run_table
from csim.report import Fields

NAN = math.nan


def run(method, tolerance=1e-6, **figures) -> Run:
    figures = dict(status="success", message="reached t_end", wall_time=0.25, nfev=100, nsteps=20, max_phi=1e-8,
                   final_phi=1e-9, max_phi_dot=1e-7, motion_error=1e-5, final_error=1e-6, error_until=1.0) | figures
    return Run(method, tolerance, **figures)


def comparison(runs, tolerances=None, reference=None) -> Comparison:
    return Comparison(source="case.yaml", case_yaml="", mechanism="pendulum", coordinate_units=["m", "m"],
                      methods=list(dict.fromkeys(r.method for r in runs)), tolerances=tolerances,
                      tolerance_kind="rtol=atol", integrator="DOP853", reference=ReferenceSettings(),
                      reference_run=reference or run("projection", 1e-12), runs=runs,
                      setting="rtol = atol = 1e-06")


def test_a_row_per_run_with_its_figures_under_their_headers():
    table = run_table([run("none"), run("sliding_mode", nfev=12345)], with_tol=False)
    assert table.headers == ["method", "status", "max|Phi|", "final|Phi|", "max|Phi_q qd|", "motion err", "final err",
                             "wall [s]", "RHS evals", "steps"]
    assert [c.justify for c in table.columns[:3]] == ["left", "left", "right"]  # names left, numbers right
    assert table.rows[1] == ["sliding_mode", "success", "1.00e-08", "1.00e-09", "1.00e-07", "1.00e-05",
                             "1.00e-06", "2.50e-01", "12345", "20"]
    assert table.column("method") == ["none", "sliding_mode"] and table.notes == []
    assert table.record("none")["RHS evals"] == "100"


def test_a_partial_motion_error_is_marked_and_a_missing_one_is_a_dash():
    early = run("none", status="failed", final_error=NAN,
                error_note="motion error over t <= 0.5 s only (the run stopped early)")
    missing = run("baumgarte", status="failed", motion_error=NAN, final_error=NAN, error_note="no samples to measure")
    table = run_table([early, missing], with_tol=True)
    assert table.headers[1] == "setting" and table.column("setting") == ["rtol=atol 1e-06"] * 2
    assert table.record("none")["motion err"] == "1.00e-05*" and table.record("none")["final err"] == "-"
    assert [table.record("baumgarte")[h] for h in ("motion err", "final err")] == ["-", "-"]
    assert table.notes == ["* over the output times before the run stopped"]
    assert table.plain()[-1] == "* over the output times before the run stopped"


def test_the_report_has_settings_a_table_and_notes():
    failed = run("baumgarte", status="failed", message="blow-up at t = 0.3 s")
    c = comparison([run("none"), failed])
    report = c.report()
    settings = report.blocks[0]
    assert isinstance(settings, Fields)
    assert settings.items[:2] == [("case", "case.yaml (pendulum, DOP853)"),
                                  ("reference", "projection, DOP853, rtol = atol = 1e-12: success")]
    (table,) = report.tables()
    assert table.column("method") == ["none", "baumgarte"] and table.column("status") == ["success", "failed"]
    text = c.table()  # the plain text: what a pipe or a CI log gets
    assert text == report.plain()
    assert text.splitlines()[:2] == ["case:       case.yaml (pendulum, DOP853)",
                                     "reference:  projection, DOP853, rtol = atol = 1e-12: success"]
    assert "per method (rtol = atol = 1e-06, as in the case):" in text
    assert text.splitlines()[-1] == "baumgarte: failed: blow-up at t = 0.3 s"


def test_a_study_has_a_work_precision_table_and_labels_runs_by_setting():
    runs = [run("none", 1e-4), run("none", 1e-6, status="failed", message="boom")]
    c = comparison(runs, tolerances=[1e-4, 1e-6])
    assert c.method_runs == {"none": runs[1]}  # the tightest
    per_method, study = c.report().tables()
    assert per_method.column("setting") == ["rtol=atol 1e-06"]
    assert study.column("setting") == ["rtol=atol 1e-04", "rtol=atol 1e-06"]
    assert study.column("status") == ["success", "failed"]
    text = c.table()
    assert "work-precision (rtol = atol = 1e-04, 1e-06):" in text
    assert text.splitlines()[-1] == "none (rtol=atol 1e-06): failed: boom"


def test_the_plain_text_is_the_tables_rows_aligned_and_the_rich_one_holds_the_same_cells():
    c = comparison([run("none", status="failed", message="boom"), run("sliding_mode", nfev=12345)])
    (table,) = c.report().tables()
    lines = c.table().splitlines()
    head = lines.index(next(line for line in lines if line.startswith("method")))
    assert lines[head + 1] == "-" * len(lines[head])
    assert [line.split() for line in lines[head + 2:head + 4]] == table.rows  # one line per row, cells split by spaces
    console = Console(file=io.StringIO(), force_terminal=True, color_system=None, width=60)
    c.report().print(console)
    drawn = console.file.getvalue()
    assert "12345" in drawn and "sliding_mode" in drawn and "…" not in drawn  # a narrow terminal cuts no cell
    assert "wall [s]" in drawn  # a header is text, not rich markup
    assert any(line.split()[:2] == ["sliding_mode", "success"] for line in drawn.splitlines())


def test_the_file_columns_have_one_entry_per_run():
    columns = table_columns([run("none"), run("ggl:Radau", 1e-8)])
    assert columns["method"] == ["none", "ggl:Radau"] and columns["tolerance"] == [1e-6, 1e-8]
    assert columns["backend"] == ["", ""]  # no result
    assert {len(v) for v in columns.values()} == {2}
