"""Figures of one run: time histories (declared by the mechanism, or the generic ones every
mechanism gets) and the mechanism drawn at several instants.

Every builder takes a :class:`csim.plot.source.RunData` and returns a
:class:`matplotlib.figure.Figure` on an Agg canvas; each plotted line holds exactly the
values of the result file (magnitudes on logarithmic axes).
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from csim.io.units import multiplier_unit
from csim.model.definition import DeclaredFigure, Panel
from csim.plot.drawing import MechanismArtists, geometry, setup_axes, snapshot_indices, symbol_size
from csim.plot.errors import PlotError
from csim.plot.series import resolve
from csim.plot.source import RunData
from csim.plot.style import SIZE, label_with_unit, new_figure, styled, title

TIME_LABEL = "time t [s]"


def _magnitude_label(label: str) -> str:
    """``$\\Phi_1$`` -> ``$|\\Phi_1|$``; plain text -> ``|text|``."""
    if label.startswith("$") and label.endswith("$") and label.count("$") == 2:
        return f"$|{label[1:-1]}|$"
    return f"|{label}|"


def log_axis(ax: Axes, arrays: Sequence[np.ndarray]) -> None:
    """A logarithmic y axis; values <= 0 are not drawn (masked), and an axis without any
    positive value gets a fixed range and a note instead of matplotlib's warning."""
    positive = [a[np.isfinite(a) & (a > 0)] for a in arrays]
    if any(p.size for p in positive):
        ax.set_yscale("log", nonpositive="mask")
        lo = min(float(p.min()) for p in positive if p.size)
        hi = max(float(p.max()) for p in positive if p.size)
        if hi / lo < 100:  # at least two decades, so that the axis has labelled ticks
            mid = math.sqrt(lo * hi)
            ax.set_ylim(mid / 10, mid * 10)
    else:
        ax.set_yscale("log")
        ax.set_ylim(1e-16, 1.0)
        ax.text(0.5, 0.5, "exactly zero throughout", transform=ax.transAxes, ha="center", va="center",
                color="0.4")


def legend(ax: Axes, n: int) -> None:
    """A legend beside the axes (never over the curves) when there are several lines."""
    if n > 1:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), ncols=1 if n <= 14 else 2,
                  borderaxespad=0.0, handlelength=1.6)


def _time_limits(ax: Axes, t: np.ndarray) -> None:
    if t.size > 1 and t[-1] > t[0]:
        ax.set_xlim(t[0], t[-1])


@styled
def time_history_figure(run: RunData, panels: Sequence[Panel], heading: str, reference: str = "") -> Figure:
    """Stacked panels of series against time, sharing the time axis.

    Parameters
    ----------
    run : RunData
    panels : sequence of Panel
        Series names (:mod:`csim.plot.series`), labels, y-axis name, log scale.
    heading : str
        Figure title.
    reference : str
        Shown after the title, e.g. ``"paper fig. H.2"``.

    Raises
    ------
    PlotError
        For a series name the run does not have.
    """
    if not panels:
        raise PlotError(f"figure {heading!r}: no panels to draw")
    resolved = [[resolve(name, run) for name in panel.series] for panel in panels]
    with_legend = any(len(series) > 1 for series in resolved)
    fig, axes = new_figure(len(panels), 1, width=SIZE[0] + (1.6 if with_legend else 0.0))
    t = run.result.t
    for ax, panel, series in zip(axes[:, 0], panels, resolved):
        arrays = []
        for k, s in enumerate(series):
            label = panel.labels[k] if k < len(panel.labels) and panel.labels[k] else s.label
            values = s.values
            if panel.log:
                values = np.abs(values)
                if not (k < len(panel.labels) and panel.labels[k]):
                    label = _magnitude_label(label)
            arrays.append(values)
            ax.plot(t, values, label=label)
        units = list(dict.fromkeys(s.unit for s in series))
        name = panel.ylabel or (series[0].label if len(series) == 1 else "")
        ax.set_ylabel(label_with_unit(name, ", ".join(u for u in units if u)))
        if panel.log:
            log_axis(ax, arrays)
        legend(ax, len(series))
    axes[-1, 0].set_xlabel(TIME_LABEL)
    _time_limits(axes[0, 0], t)
    fig.align_ylabels(axes[:, 0])
    title(fig, heading + (f" ({reference})" if reference else ""), run.describe())
    return fig


# --------------------------------------------------------------------------- generic panels


def _by_unit(names: Sequence[str], units: Sequence[str]) -> list[tuple[str, list[int]]]:
    groups: dict[str, list[int]] = {}
    for j, unit in enumerate(units[:len(names)]):
        groups.setdefault(unit, []).append(j)
    return list(groups.items())


_COORDINATE_WORDS = {"rad": ("angle", "angular velocity", "angular acceleration"),
                     "m": ("position", "velocity", "acceleration")}


def coordinate_panels(run: RunData, derivative: int = 0) -> list[Panel]:
    """One panel per coordinate unit: q (0), qd (1) or qdd (2)."""
    names = run.result.coordinate_names
    kind = ("q", "qd", "qdd")[derivative]
    panels = []
    for unit, cols in _by_unit(names, run.coordinate_units or [""] * len(names)):
        word = _COORDINATE_WORDS.get(unit, ("coordinate", "coordinate rate", "second derivative"))[derivative]
        panels.append(Panel(tuple(f"{kind}:{names[j]}" for j in cols), ylabel=word))
    return panels


def constraint_panels(run: RunData) -> list[Panel]:
    """|Phi_i| and |(Phi_q qd)_i|, each on a logarithmic axis."""
    r = run.result.phi.shape[1]
    return [Panel(tuple(f"phi:{i}" for i in range(1, r + 1)), ylabel="position-level residual", log=True),
            Panel(tuple(f"phi_dot:{i}" for i in range(1, r + 1)), ylabel="velocity-level residual", log=True)]


def energy_panels(run: RunData) -> list[Panel]:
    """Kinetic energy, change of potential energy and the work of each load; the balance
    error T + V - T0 - V0 - W below."""
    loads = tuple(f"work:{name}" for name in run.result.load_names)
    return [Panel(("energy:kinetic", "change:energy:potential", *loads),
                  labels=("kinetic energy $T$", "potential energy $V - V_0$"), ylabel="energy"),
            Panel(("energy:balance_error",), ylabel="$T + V - T_0 - V_0 - W$")]


def multiplier_panels(run: RunData) -> list[Panel]:
    """The Lagrange multipliers, one panel per unit."""
    r = run.result.lam.shape[1]
    units = [multiplier_unit(u) for u in (run.constraint_units or [""] * r)]
    names = [str(i) for i in range(1, r + 1)]
    return [Panel(tuple(f"lambda:{names[i]}" for i in cols), ylabel="Lagrange multiplier")
            for _, cols in _by_unit(names, units)]


def load_panels(run: RunData) -> list[Panel]:
    """The applied loads u_k, one panel per unit."""
    names = run.result.load_names
    d = run.definition
    units = [next((ld.unit for ld in d.loads if ld.name == n), "") if d else "" for n in names]
    words = {"N m": "torque", "N": "force"}
    # a panel of one load is labelled with the load's name
    return [Panel(tuple(f"load:{names[j]}" for j in cols), ylabel=words.get(unit, "load") if len(cols) > 1 else "")
            for unit, cols in _by_unit(names, units)]


@styled
def coordinates_figure(run: RunData) -> Figure:
    """Generalized coordinates q against time."""
    return time_history_figure(run, coordinate_panels(run, 0), "Generalized coordinates")


@styled
def velocities_figure(run: RunData) -> Figure:
    """Generalized velocities qd against time."""
    return time_history_figure(run, coordinate_panels(run, 1), "Generalized velocities")


@styled
def constraints_figure(run: RunData) -> Figure:
    """Constraint residuals |Phi_i| and |(Phi_q qd)_i| against time, log scale."""
    return time_history_figure(run, constraint_panels(run), "Constraint residuals")


@styled
def energy_figure(run: RunData) -> Figure:
    """Energies, work of the loads and the energy-balance error against time."""
    rel = run.result.energy_error_relative
    heading = "Energy balance" + (f": max relative error {rel:.2e}" if math.isfinite(rel) else "")
    return time_history_figure(run, energy_panels(run), heading)


@styled
def multipliers_figure(run: RunData) -> Figure:
    """Lagrange multipliers against time."""
    return time_history_figure(run, multiplier_panels(run), "Lagrange multipliers")


@styled
def loads_figure(run: RunData) -> Figure:
    """Applied loads against time."""
    return time_history_figure(run, load_panels(run), "Applied loads")


def _component_lines(ax: Axes, t: np.ndarray, values: np.ndarray, symbol: str) -> int:
    """Plot the global x, y, z components of ``values`` (N, 3) that are not zero throughout;
    returns how many were drawn."""
    drawn = 0
    for j, axis in enumerate("xyz"):
        column = values[:, j]
        if np.any(np.abs(column[np.isfinite(column)]) > 0):
            ax.plot(t, column, label=f"${symbol}_{axis}$")
            drawn += 1
    return drawn


@styled
def reactions_figure(run: RunData) -> Figure:
    """The force and torque of every cut joint (link i on link j, global axes) against time:
    one row per joint, force on the left, torque on the right; components that are zero
    throughout (the out-of-plane ones of a planar mechanism) are left out."""
    reactions = run.result.reactions
    if not reactions:
        raise PlotError(f"{run.path}: the run records no joint reactions")
    fig, axes = new_figure(len(reactions), 2, width=SIZE[0] + 3.0)
    t = run.result.t
    for row, r in zip(axes, reactions):
        for ax, values, symbol, word, unit in ((row[0], r.force_global, "F", "force", "N"),
                                               (row[1], r.torque_global, "M", "torque", "N m")):
            n = _component_lines(ax, t, values, symbol)
            if n == 0:
                ax.text(0.5, 0.5, f"no {word} component", transform=ax.transAxes, ha="center", va="center")
            ax.set_ylabel(label_with_unit(f"joint {r.name} {word}", unit))
            legend(ax, n)
        _time_limits(row[0], t)
    for ax in axes[-1]:
        ax.set_xlabel(TIME_LABEL)
    fig.align_ylabels(axes[:, 0])
    title(fig, "Joint reactions (link i on link j at the joint, global axes)", run.describe())
    return fig


@styled
def drive_figure(run: RunData) -> Figure:
    """The torque or force of every drive of a driven-dynamics run against time, one panel per unit."""
    res = run.result
    if res.drive_forces is None:
        raise PlotError(f"{run.path}: the run has no drives (mechanism.drive_mode: dynamic)")
    groups = _by_unit(res.drive_names, res.drive_units)
    fig, axes = new_figure(len(groups), 1)
    for ax, (unit, cols) in zip(axes[:, 0], groups):
        for j in cols:
            ax.plot(res.t, res.drive_forces[:, j], label=res.drive_names[j])
        word = {"N m": "drive torque", "N": "drive force"}.get(unit, "drive")
        ax.set_ylabel(label_with_unit(word if len(cols) > 1 else f"{word} on {res.drive_names[cols[0]]}", unit))
        legend(ax, len(cols))
    axes[-1, 0].set_xlabel(TIME_LABEL)
    _time_limits(axes[0, 0], res.t)
    title(fig, "Drive torques and forces of the prescribed motion", run.describe())
    return fig


# --------------------------------------------------------------------------- the mechanism drawn


@styled
def snapshots_figure(run: RunData, n: int = 6, cycle: str = "", heading: str = "The mechanism at six instants",
                     reference: str = "") -> Figure:
    """The mechanism drawn at ``n`` instants, one small panel each, on common scales.

    Parameters
    ----------
    run : RunData
    n : int
        Number of instants.
    cycle : str
        A coordinate whose first full turn is the cycle the instants split evenly
        (:func:`csim.plot.drawing.snapshot_indices`); "" or no full turn: the whole run.
    heading, reference : str

    Raises
    ------
    PlotError
        When the mechanism is unknown or declares no drawing, or the run has no finite
        sample.
    """
    res = run.result
    if run.definition is None:
        why = run.unavailable or f"mechanism {res.mechanism!r} is not known to this csim"
        raise PlotError(f"{run.path}: {why}; cannot draw it")
    geom = geometry(run.definition, run.parameters)
    col = None
    if cycle:
        if cycle not in res.coordinate_names:
            raise PlotError(f"snapshots: cycle coordinate {cycle!r} is not a coordinate "
                            f"({', '.join(res.coordinate_names)})")
        col = res.coordinate_names.index(cycle)
    idx = snapshot_indices(res.t, res.q, n, col)
    if idx.size == 0:
        raise PlotError(f"{run.path}: the run has no finite sample to draw")
    all_points = geom.points(res.q[idx])
    lo, hi = geom.bounds(all_points)
    scale = symbol_size(lo, hi)
    lo, hi = geom.bounds(all_points, scale)
    span = np.maximum(hi - lo, 1e-9)
    wide = geom.dim == 3 or span[1] < 0.7 * span[0]  # wide and 3-D drawings: two columns, larger panels
    ncols = min(2 if wide else 3, idx.size)
    nrows = math.ceil(idx.size / ncols)
    if geom.dim == 2:
        width = SIZE[0] + 0.6
        panel_w = (width - 0.8) / ncols
        panel_h = min(max(panel_w * span[1] / span[0], 1.0), 3.2)
        fig, axes = new_figure(nrows, ncols, width=width, height=nrows * (panel_h + 0.55) + 0.8, sharex=False)
    else:
        fig, axes = new_figure(nrows, ncols, width=SIZE[0] + 1.0, height=nrows * 3.4 + 0.8, sharex=False,
                               projection="3d")
    flat = axes.ravel()
    for ax, i, points in zip(flat, idx, all_points):
        MechanismArtists(ax, geom, points, scale)
        setup_axes(ax, geom, lo, hi)
        ax.set_title(f"t = {res.t[i]:.3f} s")
        if geom.dim == 2:
            ax.label_outer()
    for ax in flat[idx.size:]:
        ax.set_visible(False)
    if col is not None:
        turned = np.abs(res.q[:, col] - res.q[0, col]) >= 2 * math.pi
        note = "one revolution of " + cycle if turned.any() else f"the whole run ({cycle} does not complete a turn)"
    else:
        note = "the whole run"
    title(fig, heading + (f" ({reference})" if reference else ""), f"{run.describe()}; instants over {note}")
    return fig


def declared_figure(run: RunData, figure: DeclaredFigure) -> Figure:
    """Build a figure the mechanism declares (:class:`csim.model.definition.DeclaredFigure`)."""
    if figure.snapshots > 0:
        return snapshots_figure(run, figure.snapshots, figure.cycle, figure.title, figure.reference)
    return time_history_figure(run, figure.panels, figure.title, figure.reference)
