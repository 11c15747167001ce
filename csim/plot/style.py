"""One look for every figure: fonts, sizes, colours, axis labels; Agg canvases only.

Figures are made with :class:`matplotlib.figure.Figure` on an Agg canvas, never through
``pyplot``: nothing opens a window, nothing is kept in a global figure list, and the
process's matplotlib backend is left as it is.
"""
from __future__ import annotations

import functools
import textwrap
from collections.abc import Callable
from pathlib import Path

import matplotlib
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: output formats of ``csim plot --format``
FORMATS = ("png", "pdf", "svg")

#: matplotlib settings of every figure (applied while a figure is built and saved)
RC: dict = {
    "font.size": 10,
    "axes.titlesize": 10,
    "axes.labelsize": 10,
    "xtick.labelsize": 9,
    "ytick.labelsize": 9,
    "legend.fontsize": 9,
    "figure.titlesize": 11,
    "axes.grid": True,
    "grid.alpha": 0.35,
    "grid.linewidth": 0.6,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "lines.linewidth": 1.4,
    "legend.frameon": False,
    "savefig.dpi": 150,
    "pdf.fonttype": 42,
    "svg.fonttype": "none",
    "axes.formatter.useoffset": False,
    "mathtext.default": "regular",
}

#: width, height [inch] of a figure with one panel
SIZE = (6.4, 3.6)

#: colour of each stabilization method (the same in every figure); others take the cycle
METHOD_COLORS = {
    "none": "black",
    "baumgarte": "tab:blue",
    "sliding_mode": "tab:red",
    "projection": "tab:green",
    "ggl": "tab:purple",
    "minimal": "tab:orange",
}
_CYCLE = ["tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:gray"]

#: marker of each stabilization method in charts with points (work-precision): distinct
#: shapes keep methods with equal costs apart
METHOD_MARKERS = {"none": "o", "baumgarte": "s", "sliding_mode": "^", "projection": "D", "ggl": "v", "minimal": "P"}
_MARKER_CYCLE = ["X", "*", "p", "h", "<"]


def styled(build: Callable) -> Callable:
    """Decorator: run a figure builder inside the style's rc settings."""

    @functools.wraps(build)
    def wrapper(*args, **kwargs):
        with matplotlib.rc_context(RC):
            return build(*args, **kwargs)

    return wrapper


def new_figure(nrows: int = 1, ncols: int = 1, *, height: float | None = None, width: float | None = None,
               sharex: bool = True, squeeze: bool = False, **subplot_kw) -> tuple[Figure, object]:
    """A figure on an Agg canvas with constrained layout and a grid of axes.

    Returns
    -------
    fig : Figure
    axes : ndarray of Axes, shape (nrows, ncols) (or one Axes with ``squeeze``)
    """
    w = width or SIZE[0]
    h = height or (SIZE[1] if nrows == 1 else 1.0 + 2.3 * nrows)
    fig = Figure(figsize=(w, h), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, sharex=sharex, squeeze=squeeze, subplot_kw=subplot_kw or None)
    return fig, axes


def method_color(method: str, index: int = 0) -> str:
    """Colour of a method (``ggl:Radau`` takes ggl's); unknown methods take a fixed cycle."""
    base = method.split(":", 1)[0]
    return METHOD_COLORS.get(base, _CYCLE[index % len(_CYCLE)])


_SUPERSCRIPTS = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")


def unit_text(unit: str) -> str:
    """A unit as printed on an axis: powers as superscripts (``m/s^2`` -> ``m/s²``)."""
    out, rest = [], unit
    while "^" in rest:
        head, _, tail = rest.partition("^")
        digits = ""
        while tail and (tail[0].isdigit() or (tail[0] == "-" and not digits)):
            digits, tail = digits + tail[0], tail[1:]
        out.append(head + (digits.translate(_SUPERSCRIPTS) if digits else "^"))
        rest = tail
    return "".join(out) + rest


def method_marker(method: str, index: int = 0) -> str:
    """Marker of a method (``ggl:Radau`` takes ggl's)."""
    return METHOD_MARKERS.get(method.split(":", 1)[0], _MARKER_CYCLE[index % len(_MARKER_CYCLE)])


#: marker of a method's second series with another integrator (``projection:Vern7`` beside ``projection``)
INTEGRATOR_MARKERS = {"DOP853": "D", "RK45": "h", "Tsit5": "p", "Vern7": "*", "RK4": "X", "Radau": "v", "BDF": "<",
                      "LSODA": ">"}


def method_styles(methods: list[str]) -> dict[str, tuple[str, str]]:
    """(colour, marker) of each series of a chart, none alike: the first series of a method
    takes the method's own (:data:`METHOD_COLORS`, :data:`METHOD_MARKERS`); another series
    of the same method with another integrator (``projection`` and ``projection:Vern7``)
    takes the next colour of the cycle and its integrator's marker."""
    styles, seen, spare = {}, set(), 0
    for k, m in enumerate(methods):
        base, _, integrator = m.partition(":")
        if base in METHOD_COLORS and base not in seen:
            styles[m] = (method_color(m, k), method_marker(m, k))
        else:
            marker = INTEGRATOR_MARKERS.get(integrator) or method_marker(m, k)
            styles[m] = (_CYCLE[spare % len(_CYCLE)], marker)
            spare += 1
        seen.add(base)
    return styles


def label_with_unit(name: str, unit: str) -> str:
    """``"crank angle [rad]"``, ``"relative error [-]"`` for a dimensionless one (unit ``1``);
    no brackets for an empty (unknown) unit."""
    if unit == "1":
        return f"{name} [-]"
    return f"{name} [{unit_text(unit)}]" if unit else name


def wrap(text: str, fig: Figure, fontsize: float) -> str:
    """``text`` broken into lines that fit the width of ``fig`` (existing breaks kept)."""
    chars = max(20, int(fig.get_figwidth() * 72 / (0.58 * fontsize)))
    text = text.replace("fig. ", "fig.\u00a0")  # keep "fig. H.8" on one line
    return "\n".join(textwrap.fill(line, chars, break_on_hyphens=False) for line in text.split("\n"))


def title(fig: Figure, text: str, subtitle: str = "") -> None:
    """Figure title, with an optional subtitle (the run it shows), wrapped to the figure's
    width so that no line is cut off."""
    size = RC["figure.titlesize"] - (1 if subtitle else 0)
    fig.suptitle(wrap(f"{text}\n{subtitle}" if subtitle else text, fig, size), fontsize=size, linespacing=1.5)


def save(fig: Figure, path: Path, dpi: float | None = None) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix) with the style's settings;
    ``dpi`` [dots per inch] for raster formats (default ``RC["savefig.dpi"]``)."""
    with matplotlib.rc_context(RC):
        fig.savefig(path, dpi=dpi or RC["savefig.dpi"])
    return path
