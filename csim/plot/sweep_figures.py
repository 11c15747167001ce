"""Figures of a sweep file (``csim sweep``): stability maps of two varied keys, curves of one.

Two numeric keys on a grid give maps, one cell per run, the keys on the axes (log axes for
log-spaced values): ``outcome`` (stable, or failed and why, one colour per reason) and a
heatmap per figure of merit (``max_phi``, ``error``, ``energy_error``; log colour scale with
a colour bar; failed runs grey, marked with their reason's marker). Scattered designs
(random, Latin hypercube) give the same as scatter plots. One varied key gives
``curves``: each figure of merit against the value, failed runs marked on the axis.
"""
from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from matplotlib.cm import ScalarMappable
from matplotlib.colors import BoundaryNorm, ListedColormap, LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from csim.plot.errors import PlotError
from csim.plot.style import label_with_unit, new_figure, styled, title
from csim.study.sweep_file import PENDING, SweepTable

#: outcome -> (colour, marker); reasons as csim.study.metrics names them
OUTCOMES = {
    "success": ("tab:green", "o"), "drift": ("tab:red", "X"), "blow-up": ("black", "p"),
    "step collapse": ("tab:purple", "v"), "max steps": ("tab:brown", "s"), "chatter": ("tab:orange", "*"),
    "singular": ("tab:pink", "D"), "projection": ("tab:cyan", "P"), "step": ("tab:olive", "^"),
    "assembly": ("tab:gray", "h"), "invalid": ("lightgray", "8"), "interrupted": ("white", "8"),
    "other": ("tab:blue", "d"), PENDING: ("white", "8"),
}

#: the heatmaps: column -> title
METRICS = {"max_phi": "max |Phi| over the run", "error": "motion error against the reference run",
           "energy_error": "relative energy-balance error"}


def outcome(table: SweepTable, i: int) -> str:
    """``success``, a failure reason, or ``pending``."""
    s = table.status[i]
    return s if s in ("success", PENDING) else (table.reason[i] or "other")


@dataclass
class Grid:
    """Two keys' values as the axes of a map, and each run's cell (grid designs only)."""

    x: np.ndarray  # (nx,) distinct values of the first key
    y: np.ndarray  # (ny,) of the second
    cell: list[tuple[int, int]]  # per run: (iy, ix)

    def fill(self, values) -> np.ndarray:
        """(ny, nx) array of the runs' values (NaN where no run)."""
        out = np.full((self.y.size, self.x.size), np.nan)
        for (iy, ix), v in zip(self.cell, values):
            out[iy, ix] = v
        return out


def numeric_keys(table: SweepTable) -> list[str]:
    return [k for k in table.keys if table.numeric[k]]


def axis_values(table: SweepTable, key: str) -> tuple[np.ndarray, list[str] | None]:
    """Each run's position along ``key``'s axis, and the tick labels of a key whose values are
    not numbers (names, lists: one category each, in the order first met)."""
    if table.numeric[key]:
        return np.asarray(table.values[key], dtype=float), None
    labels = list(dict.fromkeys(json.dumps(v) for v in table.values[key]))
    index = {text: i for i, text in enumerate(labels)}
    return np.array([index[json.dumps(v)] for v in table.values[key]], dtype=float), [
        str(json.loads(text)) for text in labels]


def key_label(table: SweepTable, key: str) -> str:
    """A varied key as an axis label, with the unit of its values (``stabilization.w [1/s]``)."""
    unit = table.value_units.get(key, "") if table.numeric.get(key) else ""
    return label_with_unit(key, unit)


def _label_axes(ax, table: SweepTable, kx: str, ky: str) -> None:
    for key, axis, setter in ((kx, ax.xaxis, ax.set_xlabel), (ky, ax.yaxis, ax.set_ylabel)):
        _, labels = axis_values(table, key)
        if labels is not None:
            axis.set_ticks(range(len(labels)), labels)
        setter(key_label(table, key))


#: the end of the stability interval of classic RK4 on the negative real axis: Baumgarte's
#: critically damped error equation (d = 1) has the double eigenvalue -w, so RK4 is stable
#: for w h < 2.785
RK4_BOUND = 2.785


def _case_value(table: SweepTable, path: str):
    """A value of the sweep's base case (``simulation.integrator``), None where absent."""
    import yaml

    try:
        node = yaml.safe_load(table.attrs.get("case", "")) or {}
        for part in path.split("."):
            node = node[part]
        return node
    except (yaml.YAMLError, KeyError, TypeError):
        return None


def _value_set(table: SweepTable, key: str) -> set:
    if key in table.keys:
        return {json.dumps(v) for v in table.values[key]}
    return {json.dumps(_case_value(table, key))}


def draw_rk4_bound(ax, table: SweepTable, kx: str, ky: str) -> bool:
    """On a map of ``stabilization.w`` against ``simulation.step`` of Baumgarte's method with
    RK4, the curve w h = 2.785 (:data:`RK4_BOUND`) beyond which RK4 cannot be stable; True
    where drawn."""
    keys = {kx, ky}
    if keys != {"stabilization.w", "simulation.step"}:
        return False
    if _value_set(table, "simulation.integrator") != {json.dumps("RK4")} or \
            _value_set(table, "stabilization.method") != {json.dumps("baumgarte")}:
        return False
    lo, hi = sorted(ax.get_xlim() if kx == "stabilization.w" else ax.get_ylim())
    w = np.geomspace(lo if lo > 0 else hi * 1e-3, hi, 400)  # a linear axis may start below 0
    h = RK4_BOUND / w
    xy = (w, h) if kx == "stabilization.w" else (h, w)
    xlim, ylim = ax.get_xlim(), ax.get_ylim()
    ax.plot(*xy, color="white", lw=3.0, zorder=3)
    ax.plot(*xy, color="black", lw=1.4, ls="--", zorder=4, label=f"RK4 bound w h = {RK4_BOUND}")
    ax.set_xlim(xlim)
    ax.set_ylim(ylim)
    return True


def grid_of(table: SweepTable, kx: str, ky: str) -> Grid | None:
    """The map's grid, or None when the runs do not fill one (a random design, or other keys varied too)."""
    xs, ys = axis_values(table, kx)[0], axis_values(table, ky)[0]
    x, y = np.unique(xs), np.unique(ys)
    if x.size * y.size != table.n or x.size < 2 or y.size < 2:
        return None
    cells = [(int(np.searchsorted(y, b)), int(np.searchsorted(x, a))) for a, b in zip(xs, ys)]
    if len(set(cells)) != table.n:
        return None
    return Grid(x=x, y=y, cell=cells)


def _edges(v: np.ndarray) -> tuple[np.ndarray, str]:
    """Cell edges around the values ``v`` (n >= 2; geometric midpoints for log-spaced values) and the axis scale."""
    log = v.size > 2 and np.all(v > 0) and np.allclose(np.diff(np.log(v)), np.log(v[1] / v[0]), rtol=1e-6)
    w = np.log(v) if log else v
    mid = (w[1:] + w[:-1]) / 2
    edges = np.concatenate(([w[0] - (mid[0] - w[0])], mid, [w[-1] + (w[-1] - mid[-1])]))
    return (np.exp(edges), "log") if log else (edges, "linear")


def map_keys(table: SweepTable) -> list[str]:
    """The keys a map can draw: those with at least two values, numeric ones first."""
    varied = [k for k in table.keys if len({json.dumps(v) for v in table.values[k]}) > 1]
    return sorted(varied, key=lambda k: not table.numeric[k])


def _axes_keys(table: SweepTable) -> tuple[str, str]:
    keys = map_keys(table)
    if len(keys) < 2:
        raise PlotError(f"a map needs two varied keys; this sweep varies {', '.join(table.keys)}")
    return keys[0], keys[1]


def _subtitle(table: SweepTable) -> str:
    counts: dict[str, int] = {}
    for i in range(table.n):
        counts[outcome(table, i)] = counts.get(outcome(table, i), 0) + 1
    return f"{table.n} runs: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items(), key=lambda kv: -kv[1]))


@styled
def outcome_figure(table: SweepTable) -> Figure:
    """Map of each run's outcome over the first two numeric keys (stable, or the failure's reason)."""
    kx, ky = _axes_keys(table)
    fig, ax = new_figure(squeeze=True, height=4.4)
    present = [k for k in OUTCOMES if any(outcome(table, i) == k for i in range(table.n))]
    codes = np.array([present.index(outcome(table, i)) for i in range(table.n)], dtype=float)
    grid = grid_of(table, kx, ky)
    if grid is not None:
        ex, sx = _edges(grid.x)
        ey, sy = _edges(grid.y)
        cmap = ListedColormap([OUTCOMES[k][0] for k in present])
        ax.pcolormesh(ex, ey, grid.fill(codes), cmap=cmap, norm=BoundaryNorm(np.arange(len(present) + 1) - 0.5,
                                                                                  len(present)), gid="outcome")
        ax.set_xscale(sx)
        ax.set_yscale(sy)
    xs, ys = axis_values(table, kx)[0], axis_values(table, ky)[0]
    handles = []
    for j, k in enumerate(present):
        pick = codes == j
        if grid is None or k != "success":  # a failed cell also gets its reason's marker
            ax.scatter(xs[pick], ys[pick], s=14 if grid else 22, color="none" if grid else OUTCOMES[k][0],
                       marker=OUTCOMES[k][1], edgecolors="black" if grid else None, linewidths=0.5)
        handles.append(Line2D([], [], ls="none", marker="s" if k == "success" else OUTCOMES[k][1], ms=9,
                              markerfacecolor=OUTCOMES[k][0], markeredgecolor="black", markeredgewidth=0.5,
                              label=f"{k} ({int(pick.sum())})"))
    _label_axes(ax, table, kx, ky)
    if draw_rk4_bound(ax, table, kx, ky):
        handles.append(Line2D([], [], color="black", ls="--", label=f"RK4 bound\nw h = {RK4_BOUND}"))
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", title="outcome")
    title(fig, "Stability map: outcome of each run", _subtitle(table))
    return fig


@styled
def metric_figure(table: SweepTable, column: str) -> Figure:
    """Heatmap of ``column`` (log colour scale) over the first two numeric keys; failed runs grey and marked."""
    kx, ky = _axes_keys(table)
    fig, ax = new_figure(squeeze=True, height=4.4)
    values = np.asarray(table.columns[column], dtype=float)
    ok = np.array([table.status[i] == "success" for i in range(table.n)])
    shown = np.where(ok & np.isfinite(values) & (values > 0), values, np.nan)
    positive = shown[np.isfinite(shown)]
    norm = LogNorm(positive.min(), positive.max()) if positive.size and positive.min() < positive.max() else None
    grid = grid_of(table, kx, ky)
    if grid is not None:
        ex, sx = _edges(grid.x)
        ey, sy = _edges(grid.y)
        ax.set_facecolor("lightgray")  # the cells of failed runs
        mesh = ax.pcolormesh(ex, ey, grid.fill(shown), norm=norm, cmap="viridis", gid=column)
        ax.set_xscale(sx)
        ax.set_yscale(sy)
    xs, ys = axis_values(table, kx)[0], axis_values(table, ky)[0]
    if grid is None:
        mesh = ax.scatter(xs[ok], ys[ok], c=shown[ok], norm=norm, cmap="viridis", s=22, gid=column)
    fig.colorbar(mesh, ax=ax, label=label_with_unit(column, table.units.get(column, "")))
    for k in OUTCOMES:
        pick = np.array([outcome(table, i) == k for i in range(table.n)]) & ~ok
        if pick.any():
            ax.scatter(xs[pick], ys[pick], marker=OUTCOMES[k][1],
                       color=OUTCOMES[k][0], edgecolors="black", linewidths=0.4, s=20,
                       label=f"failed: {k} ({int(pick.sum())})")
    _label_axes(ax, table, kx, ky)
    draw_rk4_bound(ax, table, kx, ky)
    if (~ok).any() or ax.get_legend_handles_labels()[0]:
        fig.legend(loc="outside lower center", ncols=4, fontsize="small")
    title(fig, f"Stability map: {METRICS.get(column, column)}", _subtitle(table))
    return fig


#: more curves than this are drawn as a colour scale with a colour bar, not a legend
MAX_LEGEND = 6


@styled
def curves_figure(table: SweepTable) -> Figure:
    """Each figure of merit against the first numeric key, one line per combination of the
    other keys' values; failed runs marked at the bottom of each panel.

    More than :data:`MAX_LEGEND` lines of one other numeric key are coloured by its value
    on a colour scale with a colour bar; fewer get a legend below the panels.
    """
    key = numeric_keys(table)[0]
    others = [k for k in table.keys if k != key]
    x = np.asarray(table.values[key], dtype=float)
    groups: dict[str, list[int]] = {}
    for i in range(table.n):
        label = ", ".join(f"{k} = {_short(table.values[k][i])}" for k in others)
        groups.setdefault(label, []).append(i)
    columns = [c for c in ("max_phi", "error", "energy_error", "nfev") if np.isfinite(table.columns[c]).any()]
    fig, axes = new_figure(len(columns), 1, sharex=True)
    ok = np.array([s == "success" for s in table.status])
    scale_key = others[0] if len(others) == 1 and table.numeric[others[0]] and len(groups) > MAX_LEGEND else None
    colour = None
    if scale_key is not None:
        v = np.asarray(table.values[scale_key], dtype=float)
        log = np.all(v > 0) and v.max() / v.min() > 20
        norm = LogNorm(v.min(), v.max()) if log else Normalize(v.min(), v.max())
        colour = ScalarMappable(norm=norm, cmap="viridis")
    for ax, column in zip(axes[:, 0], columns):
        y = np.asarray(table.columns[column], dtype=float)
        for label, rows in groups.items():
            rows = np.array(rows)
            rows = rows[np.argsort(x[rows], kind="stable")]
            good = rows[ok[rows]]
            style = {} if colour is None else {"color": colour.to_rgba(float(table.values[scale_key][rows[0]]))}
            ax.plot(x[good], y[good], "o-", ms=3, gid=f"{column}|{label}",
                    label=(label or None) if colour is None else None, **style)
        ax.set_yscale("log" if np.all(y[ok & np.isfinite(y)] > 0) else "linear")
        ax.set_ylabel(label_with_unit(COLUMN_NAMES.get(column, column), table.units.get(column, "")))
        for k in OUTCOMES:
            pick = np.array([outcome(table, i) == k for i in range(table.n)]) & ~ok
            if pick.any():
                ax.plot(x[pick], np.full(pick.sum(), 0.02), OUTCOMES[k][1], color=OUTCOMES[k][0],
                        transform=ax.get_xaxis_transform(), label=f"failed: {k}" if ax is axes[0, 0] else None)
    if colour is not None:
        fig.colorbar(colour, ax=list(axes[:, 0]), label=key_label(table, scale_key), aspect=40)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="outside lower center", ncols=min(3, len(handles)), fontsize="small")
    fig.align_ylabels(axes[:, 0])
    axes[-1, 0].set_xlabel(key_label(table, key))
    if np.all(x > 0) and x.max() / x.min() > 100:
        axes[-1, 0].set_xscale("log")
    title(fig, f"Sweep of {key}", _subtitle(table))
    return fig


#: a sweep column's name on an axis
COLUMN_NAMES = {"max_phi": "max |Phi|", "error": "motion error", "energy_error": "energy error (relative)",
                "nfev": "RHS evaluations"}


def _short(value) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)
