"""The summaries csim prints, as structures that render two ways.

A :class:`Report` is a list of blocks: :class:`Fields` (``key: value`` lines, e.g. a run's
summary), :class:`Table` (a header and rows of text cells) and :class:`Lines` (notes, and
the titles above tables). It renders

- as **plain, aligned text** (:meth:`Report.plain`) where stdout is not a terminal (a pipe,
  a file, a CI log): every line is ``grep``-able, a table row is one line whose cells are
  separated by at least two spaces, numbers right-aligned under their header, a ``-`` for a
  missing number;
- as **rich tables** (:meth:`Report.print` on a terminal): the same cells, in boxed columns,
  with the status coloured. A table wider than the terminal is drawn whole (the terminal
  wraps its lines) rather than with cells cut short.

:func:`emit` picks one by ``sys.stdout.isatty()``. Tests check a report's structure, the
cells of :attr:`Table.rows`, rather than character columns.
"""
from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Literal

if TYPE_CHECKING:  # rich is imported only to draw: a run with piped output pays nothing for it
    from rich.console import Console, RenderableType

__all__ = ["Column", "Fields", "Lines", "Report", "Table", "emit"]

#: colours of status and pass/fail cells on a terminal
_STYLES = {"success": "green", "pass": "green", "failed": "bold red", "FAIL": "bold red", "pending": "yellow"}


@dataclass
class Column:
    """A table column: its header and how its cells line up (numbers ``right``, names ``left``)."""

    header: str
    justify: Literal["left", "right"] = "right"


@dataclass
class Table:
    """A header and rows of text cells, one cell per column, with footnotes below.

    Attributes
    ----------
    columns : list of Column
    rows : list of list of str
        Each as long as ``columns``; a missing number is ``"-"``.
    notes : list of str
        Footnotes printed under the rows (e.g. what a ``*`` marks).
    """

    columns: list[Column]
    rows: list[list[str]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def headers(self) -> list[str]:
        return [c.header for c in self.columns]

    def column(self, header: str) -> list[str]:
        """The cells of the column ``header``, top to bottom."""
        j = self.headers.index(header)
        return [row[j] for row in self.rows]

    def record(self, first: str) -> dict[str, str]:
        """The first row whose first cell is ``first``, as {header: cell}."""
        row = next(r for r in self.rows if r[0] == first)
        return dict(zip(self.headers, row))

    def plain(self) -> list[str]:
        """A header, a rule of ``-`` and one line per row; each column as wide as its widest
        cell, two spaces between columns; then the notes."""
        widths = [max([len(c.header), *(len(r[j]) for r in self.rows)]) for j, c in enumerate(self.columns)]

        def line(cells: Sequence[str]) -> str:
            parts = [f"{cell:<{w}}" if c.justify == "left" else f"{cell:>{w}}"
                     for cell, w, c in zip(cells, widths, self.columns)]
            return "  ".join(parts).rstrip()

        head = line(self.headers)
        return [head, "-" * len(head), *(line(r) for r in self.rows), *self.notes]

    def rich(self) -> RenderableType:
        """The table as a rich renderable: boxed columns, coloured status cells, notes below."""
        from rich import box
        from rich.console import Group
        from rich.table import Table as RichTable
        from rich.text import Text

        table = RichTable(box=box.SIMPLE_HEAD, pad_edge=False, show_edge=False)
        for j, c in enumerate(self.columns):  # each column as wide as its widest cell: none is cut short
            width = max([len(c.header), *(len(r[j]) for r in self.rows)])
            table.add_column(Text(c.header), justify=c.justify, no_wrap=True, header_style="bold", min_width=width)
        for row in self.rows:
            table.add_row(*(Text(cell, style=_STYLES.get(cell, "")) for cell in row))
        return Group(table, *(Text(n, style="dim") for n in self.notes)) if self.notes else table


@dataclass
class Fields:
    """``key: value`` lines with the values lined up, as a run's summary.

    Attributes
    ----------
    items : list of (str, str)
        Key (without the colon) and value.
    width : int
        Column where the values start in plain text; a longer key is followed by one space.
    """

    items: list[tuple[str, str]]
    width: int = 12

    def value(self, key: str) -> str:
        """The value of ``key`` (the first, where a key repeats)."""
        return next(v for k, v in self.items if k == key)

    def plain(self) -> list[str]:
        return [f"{key + ':':<{self.width - 1}} {value}" for key, value in self.items]

    def rich(self) -> RenderableType:
        from rich.table import Table as RichTable
        from rich.text import Text

        grid = RichTable.grid(padding=(0, 2))
        grid.add_column(style="bold cyan", no_wrap=True)
        grid.add_column()
        for key, value in self.items:
            first = value.split(" ", 1)[0]
            grid.add_row(Text(key), Text(value, style=_STYLES.get(first, "")) if key == "status" else Text(value))
        return grid


@dataclass
class Lines:
    """Lines of text as they are (notes, a title above a table, an empty line)."""

    lines: list[str]

    def plain(self) -> list[str]:
        return list(self.lines)

    def rich(self) -> RenderableType:
        from rich.text import Text

        return Text("\n".join(self.lines))


Block = Fields | Table | Lines


@dataclass
class Report:
    """Blocks printed one after the other (see the module's docstring)."""

    blocks: list[Block] = field(default_factory=list)

    def add(self, *blocks: Block) -> Report:
        self.blocks.extend(blocks)
        return self

    def tables(self) -> list[Table]:
        """The tables, in order."""
        return [b for b in self.blocks if isinstance(b, Table)]

    def fields(self) -> dict[str, str]:
        """The values of every :class:`Fields` block by key (the first, where a key repeats)."""
        out: dict[str, str] = {}
        for b in self.blocks:
            if isinstance(b, Fields):
                for k, v in b.items:
                    out.setdefault(k, v)
        return out

    def plain(self) -> str:
        """The report as plain, aligned text (no colour codes, no box characters)."""
        return "\n".join(line for b in self.blocks for line in b.plain())

    def print(self, console: Console) -> None:
        """Draw the report with rich on ``console``; a table wider than it is drawn whole."""
        for b in self.blocks:
            renderable = b.rich()
            # the narrowest the block can be without cutting a cell (a text value wraps instead)
            need = console.measure(renderable, options=console.options.update(width=10_000)).minimum
            width = console.width
            if need > width:
                console.width = need
            try:
                console.print(renderable, crop=False)
            finally:
                console.width = width


def emit(report: Report, console: Console | None = None) -> None:
    """Print ``report`` on stdout: rich tables on a terminal, plain aligned text otherwise.

    Parameters
    ----------
    report : Report
    console : rich.console.Console, optional
        Draw on this console with rich whatever it is (tests); default: a console on
        stdout where stdout is a terminal, else plain text.
    """
    if console is None:
        if not sys.stdout.isatty():
            sys.stdout.write(report.plain() + "\n")
            sys.stdout.flush()
            return
        from rich.console import Console

        console = Console(highlight=False)
    report.print(console)
