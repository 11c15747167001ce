"""``csim.compare.table`` and ``csim.compare.files``: the text table and the file's columns, from Runs made by hand."""
from __future__ import annotations

import math

from csim.compare.comparison import Comparison
from csim.compare.files import table_columns
from csim.compare.plan import ReferenceSettings
from csim.compare.runs import Run
from csim.compare.table import format_rows

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


def test_rows_are_aligned_under_their_header():
    lines = format_rows([run("none"), run("sliding_mode", nfev=12345)], with_tol=False)
    head, rule, *rows = lines
    assert head.split()[:3] == ["method", "status", "max|Phi|"] and set(rule) == {"-"}
    assert len({len(line) for line in lines}) == 1
    assert rows[1].split() == ["sliding_mode", "success", "1.00e-08", "1.00e-09", "1.00e-07", "1.00e-05",
                               "1.00e-06", "2.50e-01", "12345", "20"]


def test_a_partial_motion_error_is_marked_and_a_missing_one_is_a_dash():
    early = run("none", status="failed", final_error=NAN,
                error_note="motion error over t <= 0.5 s only (the run stopped early)")
    missing = run("baumgarte", status="failed", motion_error=NAN, final_error=NAN, error_note="no samples to measure")
    lines = format_rows([early, missing], with_tol=True)
    assert lines[0].split()[1] == "setting" and lines[2].split()[1:3] == ["rtol=atol", "1e-06"]
    assert lines[2].split()[7:9] == ["1.00e-05*", "-"] and lines[3].split()[7:9] == ["-", "-"]
    assert lines[-1] == "* over the output times before the run stopped"


def test_the_table_has_settings_rows_and_notes():
    failed = run("baumgarte", status="failed", message="blow-up at t = 0.3 s")
    text = comparison([run("none"), failed]).table()
    assert text.splitlines()[:2] == ["case:       case.yaml (pendulum, DOP853)",
                                     "reference:  projection, DOP853, rtol = atol = 1e-12: success"]
    assert "per method (rtol = atol = 1e-06, as in the case):" in text
    assert text.splitlines()[-1] == "baumgarte: failed: blow-up at t = 0.3 s"


def test_a_study_has_a_work_precision_section_and_labels_runs_by_setting():
    runs = [run("none", 1e-4), run("none", 1e-6, status="failed", message="boom")]
    c = comparison(runs, tolerances=[1e-4, 1e-6])
    assert c.method_runs == {"none": runs[1]}  # the tightest
    text = c.table()
    assert "work-precision (rtol = atol = 1e-04, 1e-06):" in text
    assert text.splitlines()[-1] == "none (rtol=atol 1e-06): failed: boom"


def test_the_file_columns_have_one_entry_per_run():
    columns = table_columns([run("none"), run("ggl:Radau", 1e-8)])
    assert columns["method"] == ["none", "ggl:Radau"] and columns["tolerance"] == [1e-6, 1e-8]
    assert columns["backend"] == ["", ""]  # no result
    assert {len(v) for v in columns.values()} == {2}
