"""The mechanism drawn from its geometry (:class:`csim.model.definition.Drawing`).

Links are bars (two points) or filled polygons (more), joints small circles (the points
of bars, ground points and points in no link), ground points hatched supports, guides grey
lines. Drawings whose points are (x, y) go on ordinary axes
with equal scales; drawings whose points are (x, y, z) on 3-D axes with equal scales.
The points are evaluated from the drawing's sympy expressions for the run's parameters, so
any registered mechanism can be drawn from its result file.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sympy as sp
from matplotlib.axes import Axes
from matplotlib.patches import Polygon, Rectangle

from csim.model.definition import MechanismDefinition
from csim.plot.errors import PlotError

#: colours of the links, in the order declared
LINK_COLORS = ("#4C72B0", "#DD8452", "#55A868", "#C44E52", "#8172B3", "#937860", "#DA8BC3", "#8C8C8C")
GROUND_COLOR = "0.25"
GUIDE_COLOR = "0.55"


@dataclass
class Geometry:
    """The drawing of a mechanism, evaluated for one set of parameter values.

    Attributes
    ----------
    names : list of str, length P
        Point names, in the drawing's order.
    dim : {2, 3}
        Points are (x, y) or (x, y, z) [m].
    links : list of tuple of int
        Indices into ``names`` of each link's points.
    ground : list of int
        Indices of the points fixed to the ground.
    guides : ndarray (G, 2, dim)
        Start and end of each fixed guide [m].
    """

    names: list[str]
    dim: int
    links: list[tuple[int, ...]]
    ground: list[int]
    guides: np.ndarray
    _function: Callable
    _par: list[float]

    def points(self, q: np.ndarray) -> np.ndarray:
        """Positions of the points [m].

        Parameters
        ----------
        q : ndarray (m,) or (N, m)
            Coordinates [rad or m].

        Returns
        -------
        ndarray (P, dim) or (N, P, dim)
        """
        q = np.asarray(q, dtype=float)
        single = q.ndim == 1
        Q = np.atleast_2d(q)
        values = self._function(list(Q.T), self._par)
        out = np.empty((Q.shape[0], len(self.names), self.dim))
        with np.errstate(invalid="ignore"):
            for k, v in enumerate(values):
                out[:, k // self.dim, k % self.dim] = v
        return out[0] if single else out

    def bounds(self, points: np.ndarray, scale: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corners (dim,) [m] of the configurations ``points`` (..., P, dim),
        the guides and (2-D) the ground symbols of size ``scale``."""
        parts = [points.reshape(-1, self.dim), self.guides.reshape(-1, self.dim)]
        if self.dim == 2 and self.ground and scale > 0:
            g = points.reshape(-1, len(self.names), self.dim)[:, self.ground].reshape(-1, 2)
            parts += [g + [-1.7 * scale, -2.2 * scale], g + [1.7 * scale, 0.0]]
        allp = np.concatenate(parts)
        allp = allp[np.all(np.isfinite(allp), axis=1)]
        if allp.size == 0:
            return -np.ones(self.dim), np.ones(self.dim)
        return allp.min(axis=0), allp.max(axis=0)


def geometry(definition: MechanismDefinition, parameters: dict[str, float]) -> Geometry:
    """Evaluate-ready geometry of ``definition`` for the parameter values ``parameters``.

    Raises
    ------
    PlotError
        When the mechanism declares no drawing, or its drawing is inconsistent.
    """
    drawing = definition.drawing
    if drawing is None or not drawing.points:
        raise PlotError(f"mechanism {definition.name!r} declares no drawing (MechanismDefinition.drawing); "
                        f"there is nothing to draw or animate")
    names = list(drawing.points)
    dims = {len(p) for p in drawing.points.values()}
    if len(dims) != 1 or not dims <= {2, 3}:
        raise PlotError(f"mechanism {definition.name!r}: drawing points must all be (x, y) or all (x, y, z); "
                        f"got {sorted(dims)} coordinates per point")
    dim = dims.pop()
    unknown = sorted(({p for link in drawing.links for p in link} | set(drawing.ground)) - set(names))
    if unknown:
        raise PlotError(f"mechanism {definition.name!r}: drawing names unknown point(s) {unknown}; "
                        f"points: {', '.join(names)}")
    par = [float(parameters.get(p.name, p.default)) for p in definition.parameters]
    exprs = [sp.sympify(c) for p in drawing.points.values() for c in p]
    function = sp.lambdify([definition.coordinates, definition.parameter_symbols], exprs, modules="numpy")
    guide_exprs = [sp.sympify(c) for guide in drawing.guides for end in guide for c in (*end, 0)[:dim]]
    guides = np.zeros((0, 2, dim))
    if guide_exprs:
        f = sp.lambdify([definition.parameter_symbols], guide_exprs, modules="math")
        guides = np.array(f(par), dtype=float).reshape(-1, 2, dim)
    index = {n: i for i, n in enumerate(names)}
    return Geometry(names=names, dim=dim, links=[tuple(index[p] for p in link) for link in drawing.links],
                    ground=[index[p] for p in drawing.ground], guides=guides, _function=function, _par=par)


def symbol_size(lo: np.ndarray, hi: np.ndarray) -> float:
    """Size of the ground symbols [m]: a small fraction of the drawing's extent."""
    span = float(np.max(hi - lo)) if np.all(np.isfinite(hi - lo)) else 1.0
    return 0.035 * (span if span > 0 else 1.0)


class MechanismArtists:
    """The artists of one drawn configuration, movable to another (animation).

    Parameters
    ----------
    ax : Axes (2-D) or Axes3D (3-D drawings)
    geometry : Geometry
    points : ndarray (P, dim)
        The configuration to draw [m].
    scale : float
        Size of the ground symbols [m] (:func:`symbol_size`).

    Each link's artist has the gid ``link:P1-P2-...`` (its point names), the joints' the
    gid ``joints``.
    """

    def __init__(self, ax: Axes, geometry: Geometry, points: np.ndarray, scale: float):
        self.ax, self.geometry = ax, geometry
        self.is3d = geometry.dim == 3
        for start, end in geometry.guides:
            ax.plot(*np.column_stack((start, end)), color=GUIDE_COLOR, linewidth=1.3, zorder=0.5)
        self._ground(points, scale)
        self.links: list = []
        for k, link in enumerate(geometry.links):
            color = LINK_COLORS[k % len(LINK_COLORS)]
            xyz = points[list(link)]
            gid = "link:" + "-".join(geometry.names[i] for i in link)
            if len(link) == 2 or self.is3d and len(link) < 3:
                (line,) = ax.plot(*xyz.T, color=color, linewidth=5, solid_capstyle="round", alpha=0.9, zorder=2,
                                  gid=gid)
                self.links.append(line)
            elif self.is3d:
                from mpl_toolkits.mplot3d.art3d import Poly3DCollection

                poly = Poly3DCollection([xyz], facecolor=color, edgecolor=color, alpha=0.4, linewidth=2)
                poly.set_gid(gid)
                ax.add_collection3d(poly)
                self.links.append(poly)
            else:
                poly = Polygon(xyz, closed=True, facecolor=color, edgecolor=color, alpha=0.6, linewidth=1.5,
                               zorder=3, gid=gid)
                ax.add_patch(poly)
                self.links.append(poly)
        # joints: points of bars, ground points and points of no link (polygon corners are not)
        bars = {i for link in geometry.links if len(link) == 2 for i in link}
        in_links = {i for link in geometry.links for i in link}
        self.joint_index = [i for i in range(len(geometry.names))
                            if i in bars or i in geometry.ground or i not in in_links]
        (self.joints,) = ax.plot(*points[self.joint_index].T, linestyle="none", marker="o", markersize=5,
                                 markerfacecolor="white", markeredgecolor="0.15", markeredgewidth=1.2, zorder=4,
                                 gid="joints")

    def _ground(self, points: np.ndarray, s: float) -> None:
        ax = self.ax
        for i in self.geometry.ground:
            p = points[i]
            if self.is3d:
                ax.plot(*p[:, None], marker="^", markersize=10, color=GROUND_COLOR, linestyle="none")
                continue
            x, y = p
            ax.add_patch(Polygon([(x, y), (x - s, y - 1.4 * s), (x + s, y - 1.4 * s)], closed=True,
                                 facecolor="0.85", edgecolor=GROUND_COLOR, linewidth=1.0, zorder=1))
            ax.add_patch(Rectangle((x - 1.7 * s, y - 2.2 * s), 3.4 * s, 0.8 * s, hatch="/////", facecolor="none",
                                   edgecolor=GROUND_COLOR, linewidth=0.0, zorder=1))
            ax.plot([x - 1.7 * s, x + 1.7 * s], [y - 1.4 * s] * 2, color=GROUND_COLOR, linewidth=1.2, zorder=1)

    def update(self, points: np.ndarray) -> list:
        """Move the links and joints to ``points`` (P, dim); returns the changed artists."""
        for artist, link in zip(self.links, self.geometry.links):
            xyz = points[list(link)]
            if isinstance(artist, Polygon):
                artist.set_xy(xyz)
            elif hasattr(artist, "set_verts"):
                artist.set_verts([xyz])
            elif self.is3d:
                artist.set_data_3d(*xyz.T)
            else:
                artist.set_data(*xyz.T)
        joints = points[self.joint_index]
        if self.is3d:
            self.joints.set_data_3d(*joints.T)
        else:
            self.joints.set_data(*joints.T)
        return [*self.links, self.joints]


def setup_axes(ax: Axes, geometry: Geometry, lo: np.ndarray, hi: np.ndarray, pad: float = 0.06) -> None:
    """Equal scales, limits around [lo, hi] with a margin, and axis labels in m."""
    span = np.maximum(hi - lo, 1e-9)
    margin = pad * float(np.max(span))
    lo, hi = lo - margin, hi + margin
    if geometry.dim == 2:
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.grid(True, alpha=0.25)
        return
    # 3-D: a common centre-based cube would waste room; equal scales via the box aspect
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    spans = hi - lo
    ax.set_box_aspect(tuple(np.maximum(spans, 0.05 * float(np.max(spans)))))
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")


def snapshot_indices(t: np.ndarray, q: np.ndarray, n: int, cycle: int | None = None) -> np.ndarray:
    """Indices of ``n`` output samples spread over one cycle, or over the whole run.

    Parameters
    ----------
    t : ndarray (N,) [s]
    q : ndarray (N, m)
    n : int
        Number of instants.
    cycle : int or None
        Column of q whose first full turn (|q_c - q_c(0)| >= 2 pi) ends the cycle; the
        instants then split the cycle into n equal parts. None, or no full turn: the
        instants span the whole run, both ends included.

    Returns
    -------
    ndarray (k,) of int, k <= n, increasing, distinct, rows of finite q only
    """
    ok = np.flatnonzero(np.all(np.isfinite(q), axis=1))
    if ok.size == 0:
        return ok
    t_ok = t[ok]
    times = np.linspace(t_ok[0], t_ok[-1], n)
    if cycle is not None:
        turned = np.flatnonzero(np.abs(q[ok, cycle] - q[ok[0], cycle]) >= 2 * math.pi)
        if turned.size:
            t_cycle = t_ok[turned[0]]
            times = t_ok[0] + (t_cycle - t_ok[0]) * np.arange(n) / n
    pick = np.clip(np.searchsorted(t_ok, times), 0, ok.size - 1)
    # nearest sample, not the next one
    prev = np.clip(pick - 1, 0, ok.size - 1)
    pick = np.where(np.abs(t_ok[prev] - times) < np.abs(t_ok[pick] - times), prev, pick)
    return ok[np.unique(pick)]
