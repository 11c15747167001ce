"""Plot a result file: choose its figures, build them, write one file per figure."""
from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from matplotlib.figure import Figure

from csim.io.atomic import atomic_path
from csim.plot.errors import PlotError, check_dpi
from csim.plot.registry import COMPARISON_FIGURES, SWEEP_FIGURES, run_figure_kinds, select
from csim.plot.source import COMPARISON, SWEEP, file_kind, load_comparison, load_run
from csim.plot.style import FORMATS, save
from csim.study.sweep_file import read_sweep


@dataclass
class PlotReport:
    """What :func:`plot_file` did.

    Attributes
    ----------
    written : list of Path
        The figure files, in the order made.
    skipped : dict of str -> str
        Figures the file has no data for (name -> why); only when ``only`` was not given.
    """

    written: list[Path] = field(default_factory=list)
    skipped: dict[str, str] = field(default_factory=dict)


def check_format(fmt: str) -> str:
    """``fmt`` lower-cased, when it is one of :data:`csim.plot.style.FORMATS`."""
    f = fmt.lower().lstrip(".")
    if f not in FORMATS:
        raise PlotError(f"--format: got {fmt!r}; valid formats: {', '.join(FORMATS)}")
    return f


def parse_only(text: str | None) -> list[str] | None:
    """``"a,b"`` -> ``["a", "b"]`` (None for None)."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise PlotError(f"--only: got {text!r}; expected figure names separated by commas")
    return names


def figures(path: str | Path, only: Sequence[str] | None = None, group: str | None = None
            ) -> tuple[list[str], dict[str, str], Iterator[tuple[str, Figure]]]:
    """The figures of a result or comparison file, built one at a time.

    Parameters
    ----------
    path : str or Path
        A ``csim run`` result file, a ``csim compare`` comparison file or a ``csim sweep`` file.
    only : sequence of str, optional
        Figure names (default: every figure the file has the data for).
    group : str, optional
        A method group of a comparison file (or ``reference``), plotted as a single run.

    Returns
    -------
    names : list of str
        The figures that will be built, in order.
    skipped : dict of str -> str
        The figures left out, with the reason.
    built : iterator of (name, Figure)

    Raises
    ------
    ResultFileError
        Missing or unreadable file, or a missing group.
    PlotError
        An unknown figure name, a figure the file cannot give, a run without samples.
    """
    path = Path(path)
    kind = file_kind(path)
    if kind == SWEEP:
        if group:
            raise PlotError(f"--group: {path} is a sweep file, which has no groups")
        data = read_sweep(path)
        kinds, what = SWEEP_FIGURES, f"sweep file {path}"
    elif kind == COMPARISON and not group:
        data = load_comparison(path)
        kinds, what = COMPARISON_FIGURES, f"comparison file {path}"
    else:
        data = load_run(path, group)
        if data.result.t.size == 0:
            raise PlotError(f"{path}{f' (group {group})' if group else ''}: the run has no samples to plot "
                            f"(status {data.result.status}: {data.result.message})")
        kinds = run_figure_kinds(data)
        what = f"this {data.result.mechanism} run ({path}{f', group {group}' if group else ''})"
    chosen, skipped = select(kinds, data, only, what)

    def build():
        for kind in chosen:
            yield kind.name, kind.build(data)

    return [k.name for k in chosen], skipped, build()


def plot_file(path: str | Path, out_dir: str | Path, fmt: str = "png", only: Sequence[str] | None = None,
              group: str | None = None, dpi: float | None = None) -> PlotReport:
    """Write the figures of ``path`` into ``out_dir`` as ``NAME.FORMAT``.

    Each figure goes through a temporary file beside it (:func:`csim.io.atomic.atomic_path`):
    a failure leaves no partial figure, and a symbolic link at ``NAME.FORMAT`` is replaced by
    the figure, never written through.

    Parameters
    ----------
    path : str or Path
        Result file (``csim run``) or comparison file (``csim compare``).
    out_dir : str or Path
        Folder for the figures (created when missing).
    fmt : {"png", "pdf", "svg"}
    only : sequence of str, optional
        Figure names; default every figure the file has the data for.
    group : str, optional
        A method group of a comparison file, plotted as a single run.
    dpi : float, optional
        Resolution of PNG figures [dots per inch]; default 150.

    Raises
    ------
    ResultFileError, PlotError
        See :func:`figures`; PlotError also when ``out_dir`` cannot be written.
    """
    fmt = check_format(fmt)
    if dpi is not None:
        check_dpi(dpi)
    names, skipped, built = figures(path, only, group)
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise PlotError(f"--output {out_dir}: cannot write there, {out_dir} is a file, not a folder; expected "
                        f"a folder for the figures")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PlotError(f"--output {out_dir}: cannot create the folder ({exc.strerror or exc})") from None
    report = PlotReport(skipped=skipped)
    for name, fig in built:
        target = out_dir / f"{name}.{fmt}"
        try:
            with atomic_path(target) as tmp:
                save(fig, tmp, dpi)
        except OSError as exc:
            raise PlotError(f"cannot write {target}: {exc.strerror or exc}") from None
        report.written.append(target)
    return report
