"""Figures of a comparison file (``csim compare``): constraint errors of the methods on one
logarithmic axis (the paper's H.8 and H.9), motion errors against the reference, and the
work-precision charts of a tolerance study.

Every builder takes a :class:`csim.plot.source.ComparisonData` and returns a
:class:`matplotlib.figure.Figure` on an Agg canvas. One line per method, in the same colour
in every figure (:data:`csim.plot.style.METHOD_COLORS`).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import LogFormatter

from csim.plot.errors import PlotError
from csim.plot.run_figures import TIME_LABEL, log_axis
from csim.plot.source import ComparisonData
from csim.plot.style import label_with_unit, method_styles, new_figure, styled, title

#: x axes of the work-precision charts: cost column -> axis label
COSTS = {"wall_time": "wall time [s]", "nfev": "right-hand-side evaluations"}


def _legend(fig: Figure, ax, n: int) -> None:
    if n <= 3:
        ax.legend(loc="best")
    else:
        fig.legend(loc="outside lower center", ncols=min(n, 3))


def _base(method: str) -> str:
    return method.split(":", 1)[0]


def methods_named(data: ComparisonData, *bases: str) -> list[str]:
    """The methods of the file whose name (before any ``:INTEGRATOR``) is one of ``bases``,
    in the order of ``bases``."""
    return [m for b in bases for m in data.runs if _base(m) == b]


def _run_label(method: str, ok: bool, n_samples: int) -> str:
    if n_samples == 0:
        return f"{method} (failed before the first sample)"
    return method if ok else f"{method} (failed)"


@styled
def constraint_errors_figure(data: ComparisonData, methods: Sequence[str] | None = None, velocity: bool = False,
                             heading: str = "", reference: str = "") -> Figure:
    """max_i |Phi_i| (or max_i |(Phi_q qd)_i|) against time, one line per method, log scale.

    Parameters
    ----------
    data : ComparisonData
    methods : sequence of str, optional
        Methods to draw (default: every method of the file).
    velocity : bool
        Plot the velocity-level residual Phi_q qd instead of Phi.
    heading, reference : str
        Title, and where the figure comes from (e.g. ``"paper fig. H.9"``).
    """
    methods = list(methods) if methods is not None else list(data.runs)
    missing = [m for m in methods if m not in data.runs]
    if missing:
        raise PlotError(f"{data.path}: no run of method(s) {missing}; methods: {', '.join(data.runs)}")
    fig, axes = new_figure(1, 1)
    ax = axes[0, 0]
    arrays, units = [], []
    styles = method_styles(methods)
    for m in methods:
        run = data.runs[m]
        r = run.result
        residual = r.phi_dot if velocity else r.phi
        y = np.max(np.abs(residual), axis=1) if residual.size else np.zeros(r.t.size)
        arrays.append(y)
        units += run.constraint_units
        ax.plot(r.t, y, color=styles[m][0], label=_run_label(m, r.ok, r.t.size),
                linewidth=1.8 if _base(m) == "none" else 1.4, zorder=3 if _base(m) == "none" else 2)
    unit = units[0] if units and len(set(units)) == 1 else ""
    if velocity:
        ax.set_ylabel(label_with_unit(r"velocity constraint error $\mathrm{max}_i\,|(\Phi_q \dot q)_i|$",
                                      f"{unit}/s" if unit else "1/s"))
    else:
        ax.set_ylabel(label_with_unit(r"constraint error $\mathrm{max}_i\,|\Phi_i|$", unit))
    log_axis(ax, arrays)
    ax.set_xlabel(TIME_LABEL)
    ends = [data.runs[m].result.t for m in methods if data.runs[m].result.t.size]
    if ends:
        ax.set_xlim(min(t[0] for t in ends), max(t[-1] for t in ends))
    _legend(fig, ax, len(methods))
    default = "Velocity constraint error of each method" if velocity else "Constraint error of each method"
    title(fig, (heading or default) + (f" ({reference})" if reference else ""), data.describe())
    return fig


def stabilized_figure(data: ComparisonData) -> Figure:
    """The paper's H.8: no stabilization against the stabilized methods (every method of
    the file, ``none`` drawn on top in black)."""
    if "none" in map(_base, data.runs) and len(data.runs) > 1:
        order = methods_named(data, "none") + [m for m in data.runs if _base(m) != "none"]
        return constraint_errors_figure(data, order, heading="Constraint error: no stabilization against "
                                                             "the stabilized methods", reference="paper fig. H.8")
    return constraint_errors_figure(data)


def baumgarte_sliding_figure(data: ComparisonData) -> Figure:
    """The paper's H.9: Baumgarte against sliding-mode stabilization."""
    methods = methods_named(data, "baumgarte", "sliding_mode")
    return constraint_errors_figure(data, methods, heading="Constraint error: Baumgarte against sliding mode",
                                    reference="paper fig. H.9")


def motion_error(data: ComparisonData, method: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(t, max_i |q_i - q_ref_i|) over the samples a run shares with the reference, or None
    when there is no usable reference or the output times differ."""
    ref = data.reference
    if ref is None or not ref.result.ok or ref.result.t.size == 0:
        return None
    r, rr = data.runs[method].result, ref.result
    n = min(r.t.size, rr.t.size)
    if n == 0 or r.q.shape[1] != rr.q.shape[1]:
        return None
    if not np.allclose(r.t[:n], rr.t[:n], rtol=0.0, atol=1e-9 * max(float(rr.t[-1]), 1.0)):
        return None
    return r.t[:n], np.max(np.abs(r.q[:n] - rr.q[:n]), axis=1)


@styled
def motion_errors_figure(data: ComparisonData) -> Figure:
    """max_i |q_i - q_ref_i| against time, one line per method, log scale."""
    fig, axes = new_figure(1, 1)
    ax = axes[0, 0]
    arrays, times, units = [], [], set()
    styles = method_styles(list(data.runs))
    for m in data.runs:
        err = motion_error(data, m)
        if err is None:
            continue
        times.append(err[0])
        arrays.append(err[1])
        units.update(data.runs[m].coordinate_units)
        r = data.runs[m].result
        ax.plot(*err, color=styles[m][0], label=_run_label(m, r.ok, r.t.size))
    if not arrays:
        raise PlotError(f"{data.path}: no motion errors to plot (no successful reference run with the "
                        f"methods' output times)")
    ax.set_ylabel(label_with_unit(r"motion error $\mathrm{max}_i\,|q_i - q_{\mathrm{ref},i}|$",
                                  ", ".join(sorted(units))))
    ax.set_xlabel(TIME_LABEL)
    ax.set_xlim(min(float(t[0]) for t in times), max(float(t[-1]) for t in times))
    log_axis(ax, arrays)
    _legend(fig, ax, len(arrays))
    a = data.file.attrs
    ref = (f"reference: {a.get('reference_method', '')}, {a.get('reference_integrator', '')}, "
           f"tol {float(a.get('reference_tol', float('nan'))):g}")
    title(fig, "Motion error against the reference run", f"{data.describe()}; {ref}")
    return fig


@styled
def work_precision_figure(data: ComparisonData, cost: str = "wall_time") -> Figure:
    """Work-precision chart: motion error and max constraint error against the cost of each
    run of the tolerance study, one line per method (loosest tolerance first), log-log.

    Parameters
    ----------
    data : ComparisonData
    cost : {"wall_time", "nfev"}
        The x axis: wall time [s] or right-hand-side evaluations.

    Notes
    -----
    Failed runs are left out of the lines (their errors cover only part of the run); the
    legend counts them.
    """
    if cost not in COSTS:
        raise PlotError(f"work-precision cost {cost!r}; valid: {', '.join(COSTS)}")
    table = data.file.work_precision
    if table is None:
        raise PlotError(f"{data.path}: no tolerance study (run csim compare with --tolerances)")
    fig, axes = new_figure(2, 1, height=6.0)
    method_col = np.asarray(table["method"], dtype=object)
    order = list(dict.fromkeys(method_col))
    backend_col = np.asarray(table.get("backend", [""] * len(method_col)), dtype=object)
    mixed = len({b for b in backend_col if b}) > 1  # marked: filled compiled, hollow Python
    tol_col = np.asarray(table["tolerance"], dtype=float)
    x_all, err_all, phi_all = [], [], []
    styles = method_styles(list(order))
    for m in order:
        rows = np.flatnonzero(method_col == m)
        rows = rows[np.argsort(-np.asarray(table["tolerance"], dtype=float)[rows], kind="stable")]
        ok = np.asarray(table["status"], dtype=object)[rows] == "success"
        failed = int(np.count_nonzero(~ok))
        rows = rows[ok]
        x = np.asarray(table[cost], dtype=float)[rows]
        err = np.asarray(table["motion_error"], dtype=float)[rows]
        phi = np.asarray(table["max_phi"], dtype=float)[rows]
        backends = sorted({b for b in backend_col[rows] if b})
        label = m + (f" ({'/'.join(backends)})" if mixed else "") + (f" ({failed} failed, not shown)" if failed
                                                                   else "")
        color, marker = styles[m]
        style = dict(color=color, marker=marker, markersize=7 if marker == "*" else 6, markeredgewidth=1.4,
                     markerfacecolor=color if mixed and backends == ["compiled"] else "none")
        axes[0, 0].plot(x, err, label=label, **style)
        axes[1, 0].plot(x, phi, **style)
        # the top panel only (the residuals of stabilized runs coincide), and of many series only
        # the loosest and tightest points of each (all labelled, they overlap)
        shown = range(len(rows)) if len(order) <= 3 else sorted({0, len(rows) - 1})
        for i in shown if len(rows) else ():
            xi, yi = x[i], err[i]
            if np.isfinite(xi) and np.isfinite(yi) and xi > 0 and yi > 0:
                axes[0, 0].annotate(f"{tol_col[rows][i]:g}", (xi, yi), xytext=(4, 3), textcoords="offset points",
                                    fontsize=7, color=color)
        x_all.append(x)
        err_all.append(err)
        phi_all.append(phi)
    for ax, arrays in ((axes[0, 0], err_all), (axes[1, 0], phi_all)):
        log_axis(ax, arrays)
        positive = [x[np.isfinite(x) & (x > 0)] for x in x_all]
        if any(p.size for p in positive):
            ax.set_xscale("log", nonpositive="mask")
            ax.xaxis.set_major_formatter(PlainLogFormatter())
            # minor labels only on an axis spanning less than a decade (they would overlap)
            ax.xaxis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(1, 0.4)))
    if not any(np.isfinite(e).any() for e in err_all):
        axes[0, 0].text(0.5, 0.5, "no motion errors: the reference run failed", transform=axes[0, 0].transAxes,
                        ha="center", va="center", color="0.4")
    units = sorted({u for run in data.runs.values() for u in run.coordinate_units})
    c_units = {u for run in data.runs.values() for u in run.constraint_units}
    axes[0, 0].set_ylabel(label_with_unit("motion error", ", ".join(units)))
    axes[1, 0].set_ylabel(label_with_unit(r"constraint error $\mathrm{max}\,|\Phi_i|$",
                                          c_units.pop() if len(c_units) == 1 else ""))
    axes[1, 0].set_xlabel(COSTS[cost])
    fig.align_ylabels(axes[:, 0])
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncols=min(len(order), 2 if mixed else 3))
    a = data.file.attrs
    tols = ", ".join(f"{t:g}" for t in data.tolerances)
    kind = str(a.get("tolerance_kind", "rtol=atol")).replace("=", " = ")
    jobs = int(a.get("jobs", 1))
    sub = f"{a.get('mechanism', '')}, {a.get('integrator', '')}, {kind} = {tols}"
    repeat = int(a.get("repeat", 1))
    if cost == "wall_time":
        how = f"median of {repeat} runs" if repeat > 1 else "one run each (csim compare --repeat N: median of N)"
        sub += f"\nwall time: {how}" + (f", {jobs} processes sharing the CPU" if jobs > 1 else "")
    sub += ("; top: points labelled with their tolerance" if len(order) <= 3 else
            "; top: each line's loosest and tightest points labelled with their tolerance")
    if mixed:
        sub += "\nbackends differ: filled markers compiled, hollow Python"
    title(fig, f"Work-precision: errors against {COSTS[cost].split(' [')[0]}", sub)
    return fig


class PlainLogFormatter(LogFormatter):
    """Log-axis labels as plain numbers (``0.6``, ``2``, ``3000``), not ``6 x 10^-1``."""

    def _num_to_string(self, x, vmin, vmax):
        return f"{x:g}"
