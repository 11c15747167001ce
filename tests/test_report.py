"""``csim.report``: a report's plain text (aligned, greppable) and its rich drawing hold the same cells."""
from __future__ import annotations

import io
import re
import sys

from rich.console import Console

from csim.report import Column, Fields, Lines, Report, Table, emit


def table() -> Table:
    return Table([Column("name", "left"), Column("status", "left"), Column("value"), Column("n")],
                 rows=[["a", "success", "1.00e-08", "3"], ["longer_name", "failed", "-", "12345"],
                       ["b", "step 1e-03", "2.0 J", "0"]],
                 notes=["* a note"])


def test_plain_columns_line_up_under_their_headers():
    head, rule, *rows, note = table().plain()
    assert rule == "-" * len(head) and note == "* a note"
    assert {len(r) for r in rows} == {len(head)}  # right-justified last column: every row as wide as the header
    # a left column starts where its header starts, a right one ends where its header ends
    assert [r.index(cell) for r, cell in zip(rows, ("success", "failed", "step"))] == [head.index("status")] * 3
    for r, cell in zip(rows, ("1.00e-08", "-", "2.0 J")):
        assert r.index(cell) + len(cell) == head.index("value") + len("value")
    assert [re.split(r"  +", r.strip()) for r in rows] == table().rows  # one line per row, cells split by 2+ spaces


def test_a_table_finds_cells_by_header_and_rows_by_their_first_cell():
    t = table()
    assert t.column("n") == ["3", "12345", "0"] and t.record("longer_name")["status"] == "failed"


def test_fields_line_up_their_values_and_a_long_key_keeps_one_space():
    f = Fields([("case", "x.yaml"), ("interrupted", "yes"), ("max |Phi_q qd|", "1")], width=12)
    assert f.plain() == ["case:       x.yaml", "interrupted: yes", "max |Phi_q qd|: 1"]
    assert f.value("interrupted") == "yes"


def test_the_rich_drawing_holds_every_cell_uncut_and_no_markup():
    report = Report([Fields([("status", "failed ([red] is text)")]), Lines(["", "title [b]"]), table()])
    console = Console(file=io.StringIO(), force_terminal=True, color_system=None, width=30)
    report.print(console)
    drawn = console.file.getvalue()
    assert "…" not in drawn and "[red] is text" in drawn and "title [b]" in drawn
    rows = [line.split() for line in drawn.splitlines()]
    assert ["longer_name", "failed", "-", "12345"] in rows and ["name", "status", "value", "n"] in rows
    assert console.width == 30  # drawn wider than the terminal for the table, then as before


def test_emit_writes_plain_text_when_stdout_is_not_a_terminal(monkeypatch):
    out = io.StringIO()
    monkeypatch.setattr(sys, "stdout", out)
    report = Report([Fields([("case", "x.yaml")]), table()])
    emit(report)
    assert out.getvalue() == report.plain() + "\n"
    assert "─" not in out.getvalue() and "\x1b" not in out.getvalue()  # no box characters, no colour codes


def test_emit_draws_with_rich_on_a_terminal(monkeypatch):
    class Tty(io.StringIO):
        def isatty(self):
            return True

    out = Tty()
    monkeypatch.setattr(sys, "stdout", out)
    monkeypatch.setenv("COLUMNS", "100")
    emit(Report([table()]))
    assert "─" in out.getvalue() and "longer_name" in out.getvalue()
