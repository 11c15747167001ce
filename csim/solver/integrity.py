"""Whether a run's motion can be trusted: removed equations, singular configurations, branches.

A run can hold its constraint equations to round-off and still be wrong, in two ways that
the integration itself cannot see. Both are checked on the samples after the run, for
either backend, against the full set of non-trivial constraint equations:

1. **Removed equations.** An overconstrained mechanism (Bricard's linkage) keeps an
   independent subset of its closure equations, chosen at the start. Where that subset's
   Jacobian later loses rank while the full set's does not, the motion can leave the
   manifold along a direction only a removed equation sees: the kept residuals stay small
   while a joint comes apart. The removed equations are evaluated at every sample; a run
   where one exceeds :func:`removed_limit` fails (kind ``"drift"``) and names it.
2. **Singular configurations.** Where Phi_q of the full set drops below its generic rank
   (every link of the N-four-bar horizontal) the mechanism can leave its assembly branch.
   The k-th singular value of Phi_q (k the generic rank), relative to the largest
   sigma_1 over the run, is taken at the samples; each local minimum below
   :data:`COARSE` is refined on the cubic Hermite interpolant of (q, qd) between the
   neighbouring samples, and one below
   :data:`SINGULAR` is recorded as a singular crossing (a warning in the summary and the
   file). Across a crossing the exact motion's velocity is continuous and smooth: where
   the samples on either side are not joined by their accelerations (the trapezoidal
   residual qd_b - qd_a - h (qdd_a + qdd_b) / 2, relative to the velocity scale, above
   :data:`JUMP`), the motion took another branch and the run fails (kind ``"branch"``).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

#: a sampled local minimum of sigma_k / max sigma_1 below this is refined between the samples
COARSE = 0.25
#: sigma_k / max sigma_1 below this (refined) is a loss of rank: a singular configuration
SINGULAR = 1e-3
#: a relative velocity jump (trapezoidal residual / velocity scale) above this across a
#: singular crossing is a change of assembly branch
JUMP = 0.05
#: a removed equation may exceed the kept ones' largest residual by this factor ...
REMOVED_FACTOR = 100.0
#: ... and never fails below this residual [unit of Phi]
REMOVED_FLOOR = 1e-8


@dataclass
class ConstraintWatch:
    """Every non-trivial constraint equation of a mechanism, and which ones the model kept.

    Attributes
    ----------
    phi : callable q (m,) -> (n_all,)
    phi_q : callable q (m,) -> (n_all, m)
    labels : list of str (n_all,)
        A name of each equation, e.g. ``"joint j0 x: (r_jm - r_ik).e_x"``.
    kept : ndarray of int (r,)
        The rows the model integrates (its Phi), in the model's order.
    removed : ndarray of int
        The rows removed as dependent at the start.
    rank : int
        The generic rank of Phi_q over all rows.
    gamma_removed : callable (q, qd) -> (len(removed),), optional
        gamma = -(dPhi_q/dt) qd of the removed rows (the model has the kept rows').
    units : list of str (n_all,), optional
        The unit of each equation (``"m"``, ``"1"``), where known.
    """

    phi: Callable
    phi_q: Callable
    labels: list[str]
    kept: np.ndarray
    removed: np.ndarray
    rank: int
    gamma_removed: Callable | None = None
    units: list[str] = field(default_factory=list)
    #: the driven coordinates of driven dynamics (:meth:`with_drives`), for the messages
    driven: list[str] = field(default_factory=list)

    def with_drives(self, driven: np.ndarray, names: list[str], m: int) -> ConstraintWatch:
        """The watch of driven dynamics, whose rows are Phi and the drives q_j - f_j(t).

        The stacked Jacobian [Phi_q; e_j^T] loses rank exactly where Phi_q restricted to the
        columns not driven does (rank = d + rank Phi_q[:, free]): that block is watched
        instead, so that a dead centre of the driven mechanism (where the drive torque is
        unbounded) is a singular crossing, judged on the mechanism's own rows and units
        (unit drive rows beside rows in metres would make the test depend on the length
        unit). The residuals and the other rows are the mechanism's.
        """
        free = np.array([i for i in range(m) if i not in set(int(j) for j in driven)], dtype=int)
        n_all = len(self.labels)
        return replace(self, phi_q=lambda q: np.asarray(self.phi_q(q)).reshape(n_all, m)[:, free],
                       driven=list(names))

    def gamma(self, gamma_kept: np.ndarray, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """gamma (n_all,) of every equation: ``gamma_kept`` (the model's, on the kept rows) and
        the removed rows' own."""
        if self.removed.size == 0:
            return gamma_kept
        out = np.empty(len(self.labels))
        out[self.kept] = gamma_kept
        out[self.removed] = self.gamma_removed(q, qd)
        return out


@dataclass
class Integrity:
    """What the samples say about the motion (see the module docstring).

    Attributes
    ----------
    removed_names : list of str (d,)
    removed_phi : ndarray (N, d)
        The removed equations' residuals at the samples [unit of Phi].
    removed_limit : float
        The largest residual a removed equation may have.
    singular_times : ndarray (S,) [s]
        The singular crossings.
    singular_sigma : ndarray (S,)
        sigma_k / max sigma_1 of the full set's Phi_q at each.
    kept_singular_times : ndarray [s]
        Where the kept subset loses rank but the full set does not.
    failure : tuple (kind, message) or None
        Why the run must not be called a success.
    warnings : list of str
    """

    removed_names: list[str]
    removed_phi: np.ndarray
    removed_limit: float
    singular_times: np.ndarray
    singular_sigma: np.ndarray
    kept_singular_times: np.ndarray
    failure: tuple[str, str] | None = None
    warnings: list[str] = field(default_factory=list)


def removed_limit(max_kept: float) -> float:
    """The largest residual a removed equation may have when the kept ones reach ``max_kept``."""
    return max(REMOVED_FACTOR * max_kept, REMOVED_FLOOR)


def relative_sigma(J: np.ndarray, k: int, scale: float | None = None) -> float:
    """sigma_k / scale of J (k: the k-th largest singular value, 1-based); ``scale`` defaults
    to sigma_1 of J itself. 1 for k = 0 or an empty J, 0 where J has fewer than k values."""
    return float(_sigma_ratios(J[None], k, scale)[0])


def _sigma_ratios(J: np.ndarray, k: int, scale: float | None = None) -> np.ndarray:
    """sigma_k / scale of each of the stacked matrices J (N, r, m), in one batched SVD
    (``scale`` None: each one's own sigma_1); NaN for a matrix with a non-finite entry."""
    N = J.shape[0]
    if k == 0 or J.shape[1] == 0 or J.shape[2] == 0:
        return np.ones(N)
    out = np.full(N, np.nan)
    finite = np.all(np.isfinite(J), axis=(1, 2))
    if not finite.any():
        return out
    s = np.linalg.svd(J[finite], compute_uv=False)
    top = s[:, 0] if scale is None else np.full(s.shape[0], scale)
    kth = s[:, k - 1] if k <= s.shape[1] else np.zeros(s.shape[0])
    with np.errstate(invalid="ignore", divide="ignore"):
        out[finite] = np.where(top > 0.0, kth / np.where(top > 0.0, top, 1.0), 1.0)
    return out


def _singular_values(J: np.ndarray) -> np.ndarray:
    """The singular values (N, min(r, m)) of the stacked Jacobians J (N, r, m), NaN where J is
    not finite. Their largest sigma_1 is the scale a singular value is measured against (a
    single equation's Jacobian loses rank by vanishing as a whole)."""
    out = np.full((J.shape[0], min(J.shape[1], J.shape[2])), np.nan)
    finite = np.all(np.isfinite(J), axis=(1, 2)) if J.size else np.zeros(J.shape[0], bool)
    if finite.any() and out.shape[1]:
        out[finite] = np.linalg.svd(J[finite], compute_uv=False)
    return out


def hermite(qa, qda, qb, qdb, h: float, tau):
    """q at tau in [0, 1] (a number, or an array (n,): then (n, m)) of the step of length h [s]
    on the cubic Hermite interpolant."""
    tau = np.asarray(tau, dtype=float)[..., None] if np.ndim(tau) else tau
    t2, t3 = tau * tau, tau * tau * tau
    return ((2 * t3 - 3 * t2 + 1) * qa + (t3 - 2 * t2 + tau) * h * qda
            + (-2 * t3 + 3 * t2) * qb + (t3 - t2) * h * qdb)


#: points per interval at which a candidate minimum is looked at before it is refined
GRID = 17


#: the golden section's smaller part, (3 - sqrt 5) / 2
GOLDEN = 0.5 * (3.0 - 5.0 ** 0.5)
#: sqrt of the double precision's epsilon
SQRT_EPS = float(np.sqrt(np.finfo(float).eps))


def bounded_minimum(f: Callable[[float], float], a: float, b: float, xatol: float,
                    max_evaluations: int = 200) -> tuple[float, float]:
    """A local minimum of f on [a, b] by Brent's method: golden-section steps, parabolic ones
    where the parabola through the last three points is trusted (R. P. Brent, Algorithms for
    Minimization without Derivatives, 1973, ch. 5; scipy's ``minimize_scalar(method="bounded")``
    runs the same, and importing scipy.optimize costs 0.4 s of a run).

    Parameters
    ----------
    f : callable float -> float
    a, b : float
        The bracket, a < b.
    xatol : float
        Absolute tolerance on the minimiser (relative sqrt(eps) |x| added).
    max_evaluations : int
        A bound on the evaluations of f.

    Returns
    -------
    (x, f(x)) : tuple of float
    """
    x = w = v = a + GOLDEN * (b - a)
    fx = fw = fv = f(x)
    d = e = 0.0
    for _ in range(max_evaluations - 1):
        m = 0.5 * (a + b)
        tol = SQRT_EPS * abs(x) + xatol / 3.0
        if abs(x - m) <= 2.0 * tol - 0.5 * (b - a):  # [a, b] within 4 tol around x
            break
        golden = True
        if abs(e) > tol:  # the parabola through (v, fv), (w, fw), (x, fx): its vertex at x + p / q
            r = (x - w) * (fx - fv)
            q = (x - v) * (fx - fw)
            p = (x - v) * q - (x - w) * r
            q = 2.0 * (q - r)
            p, q = (-p, q) if q > 0.0 else (p, -q)
            r, e = e, d
            # accepted when inside (a, b) and shorter than half the step before last
            if abs(p) < abs(0.5 * q * r) and q * (a - x) < p < q * (b - x):
                d = p / q
                if (x + d) - a < 2.0 * tol or b - (x + d) < 2.0 * tol:
                    d = tol if x < m else -tol
                golden = False
        if golden:  # into the larger of the two parts
            e = (b - x) if x < m else (a - x)
            d = GOLDEN * e
        u = x + (d if abs(d) >= tol else (tol if d > 0.0 else -tol))
        fu = f(u)
        if fu <= fx:  # u the new best: the bracket shrinks to u's side of x
            if u < x:
                b = x
            else:
                a = x
            v, w, x, fv, fw, fx = w, x, u, fw, fx, fu
        else:
            if u < x:
                a = u
            else:
                b = u
            if fu <= fw or w == x:
                v, w, fv, fw = w, u, fw, fu
            elif fu <= fv or v in (x, w):
                v, fv = u, fu
    return x, fx


def _refine(ratios: Callable[[np.ndarray], np.ndarray], t, q, qd, i: int) -> tuple[float, float]:
    """The smallest ratio on the interpolants of the intervals beside sample i: (t, ratio).

    A grid of :data:`GRID` points per interval first (one batched SVD); the bounded scalar
    minimisation only where the grid comes within ten times :data:`SINGULAR`.
    """
    best = (t[i], float(ratios(q[i][None])[0]))
    taus = np.linspace(0.0, 1.0, GRID)
    for a in (i - 1, i):
        if a < 0 or a + 1 >= t.size:
            continue
        h = t[a + 1] - t[a]
        ends = (q[a], qd[a], q[a + 1], qd[a + 1], h)
        grid = ratios(hermite(*ends, taus))
        if not np.isfinite(grid).any():
            continue
        j = int(np.nanargmin(grid))
        candidate = (t[a] + taus[j] * h, float(grid[j]))
        if candidate[1] < 10 * SINGULAR:
            # minimise the square: sigma_k is a V |s(t)| about a loss of rank, sigma_k^2 = s(t)^2
            # is smooth, on which Brent's parabolic steps converge in a few evaluations
            lo, hi = taus[max(j - 1, 0)], taus[min(j + 1, GRID - 1)]
            tau, square = bounded_minimum(lambda tau, ends=ends: float(ratios(hermite(*ends, tau)[None])[0]) ** 2,
                                          lo, hi, xatol=1e-7)
            ratio = float(np.sqrt(square))
            if ratio < candidate[1]:
                candidate = (t[a] + tau * h, ratio)
        if candidate[1] < best[1]:
            best = candidate
    return best


def _v_shaped(v: float, left: float, right: float) -> bool:
    """Whether a sampled minimum v between its neighbours may be a zero: near a loss of rank the
    singular value is |a (t - t*)|, a V whose two sides give (v + min side) = (max side - v)
    (equal sample spacing), where a smooth minimum m above zero gives (v + min side) far above
    (max side - v). Also any sample below 2 % of the scale."""
    low, high = min(left, right), max(left, right)
    if not np.isfinite(high):
        high = low
    return v < 0.02 or v + low <= 2.0 * (high - v)


def _crossings(ratios: Callable[[np.ndarray], np.ndarray], t, q, qd,
               values: np.ndarray | None = None) -> list[tuple[float, float]]:
    """The refined local minima of the ratio along the samples that fall below :data:`SINGULAR`
    (``ratios`` maps configurations (n, m) to ratios (n,); ``values``: its values at q)."""
    values = ratios(q) if values is None else values
    values = np.where(np.isfinite(values), values, np.inf)
    found = []
    for i in range(t.size):
        left = values[i - 1] if i > 0 else np.inf
        right = values[i + 1] if i + 1 < t.size else np.inf
        if values[i] < COARSE and values[i] <= left and values[i] <= right and _v_shaped(values[i], left, right):
            tc, rc = _refine(ratios, t, q, qd, i)
            if rc < SINGULAR and not (found and abs(tc - found[-1][0]) < 1e-9):
                found.append((tc, rc))
    return found


def _branch_jump(t, qd, qdd, tc: float, names: list[str]) -> str | None:
    """Why the velocities across the crossing at ``tc`` are not one smooth motion, or None."""
    b = int(np.searchsorted(t, tc, side="right"))
    a = b - 1
    if a < 0 or b >= t.size:
        return None
    h = t[b] - t[a]
    # qd_b = qd_a + h (qdd_a + qdd_b) / 2 + O(h^3) for a smooth motion
    residual = qd[b] - qd[a] - 0.5 * h * (qdd[a] + qdd[b])
    scale = max(np.max(np.abs(qd[a])), np.max(np.abs(qd[b])), 1e-12)
    j = int(np.argmax(np.abs(residual)))
    if not np.isfinite(residual[j]) or abs(residual[j]) > JUMP * scale:
        return (f"between t = {t[a]:.6g} s and {t[b]:.6g} s {names[j]}'s velocity jumped by {residual[j]:.3g} "
                f"(from {qd[a, j]:.6g} to {qd[b, j]:.6g}) beyond what the accelerations explain")
    return None


def check_integrity(watch: ConstraintWatch, t: np.ndarray, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray,
                    coordinate_names: list[str], kept_fixed: bool = True) -> Integrity:
    """Check a run's samples (see the module docstring).

    Parameters
    ----------
    watch : ConstraintWatch
    t : ndarray (N,) [s]
    q, qd, qdd : ndarray (N, m)
        The samples' coordinates, velocities and accelerations (NaN where not evaluated).
    coordinate_names : list of str (m,)
    kept_fixed : bool
        Whether the run integrated the rows kept at the start (False: it chose its rows as it
        moved, :mod:`csim.solver.redundant`, and where the first ones lose rank is no news).
    """
    N = t.size
    # the removed equations at every sample (a registered mechanism has none: nothing to evaluate)
    phi_all = (np.array([watch.phi(x) for x in q]).reshape(N, len(watch.labels)) if watch.removed.size
               else np.zeros((N, len(watch.labels))))
    kept_max = float(np.max(np.abs(phi_all[:, watch.kept]))) if N and watch.kept.size else 0.0
    limit = removed_limit(kept_max)
    removed_phi = phi_all[:, watch.removed]
    names = [watch.labels[i] for i in watch.removed]
    failure, warnings = None, []
    if removed_phi.size:
        worst = np.max(np.abs(removed_phi), axis=0)
        bad = [j for j in range(worst.size) if not worst[j] <= limit]
        if bad:
            first = min(int(np.argmax(~(np.abs(removed_phi[:, j]) <= limit))) for j in bad)
            listing = "; ".join(f"{names[j]} (max |Phi| {worst[j]:.3g})" for j in bad)
            failure = ("drift", f"constraint violation of equations removed as dependent at the start: {listing}, "
                                f"first above {limit:.3g} at t = {t[first]:.6g} s while the kept equations stay "
                                f"within {kept_max:.3g}: a joint came apart where the kept equations lost rank; "
                                f"use stabilization.method minimal or augmented_lagrangian")
    jacobians = _jacobians(watch.phi_q, q, len(watch.labels))
    sigma = _singular_values(jacobians)
    scale = float(np.nanmax(sigma[:, 0])) if sigma.size and np.isfinite(sigma[:, 0]).any() else 0.0

    def full(x):
        return _sigma_ratios(_jacobians(watch.phi_q, x, len(watch.labels)), watch.rank, scale)

    sampled = (sigma[:, watch.rank - 1] / scale if 0 < watch.rank <= sigma.shape[1] and scale > 0
               else np.ones(N))
    crossings = _crossings(full, t, q, qd, sampled) if N > 2 else []
    kept_times = np.zeros(0)
    if watch.removed.size and N > 2 and kept_fixed:
        def kept(x):
            return _sigma_ratios(_jacobians(watch.phi_q, x, len(watch.labels))[:, watch.kept], watch.kept.size, scale)

        kept_times = np.array([tc for tc, _ in _crossings(kept, t, q, qd,
                                                          _sigma_ratios(jacobians[:, watch.kept], watch.kept.size,
                                                                        scale))
                               if all(abs(tc - tf) > 1e-6 for tf, _ in crossings)])
        if kept_times.size:
            held = "" if failure else f"; they were watched and held within {limit:.3g}"
            warnings.append(f"the kept constraint equations lose rank at t = {_times(kept_times)} while the full set "
                            f"does not: the equations removed at the start ({', '.join(names)}) are needed there"
                            f"{held}")
    if crossings:
        what = (f"Phi_q over the coordinates not driven ({', '.join(watch.driven)} driven) below its rank "
                f"{watch.rank}: a dead centre of the driven mechanism, where the drive force is unbounded"
                if watch.driven else f"Phi_q below its rank {watch.rank}")
        warnings.append(f"singular configuration ({what}) at t = {_times([c[0] for c in crossings])}: the motion "
                        f"after it may follow another assembly branch")
        for tc, _ in crossings:
            jump = _branch_jump(t, qd, qdd, tc, coordinate_names)
            if jump is not None and failure is None:
                failure = ("branch", f"the motion changed assembly branch at the singular configuration near "
                                     f"t = {tc:.6g} s: {jump}")
    return Integrity(removed_names=names, removed_phi=removed_phi, removed_limit=limit,
                     singular_times=np.array([c[0] for c in crossings]),
                     singular_sigma=np.array([c[1] for c in crossings]),
                     kept_singular_times=kept_times, failure=failure, warnings=warnings)


def _jacobians(phi_q: Callable[[np.ndarray], np.ndarray], q: np.ndarray, r: int) -> np.ndarray:
    """Phi_q at each configuration q (n, m), stacked (n, r, c) (c: the columns ``phi_q`` gives,
    m or fewer); NaN at a non-finite q."""
    out = None
    for i in np.flatnonzero(np.isfinite(q).all(axis=1)):
        J = np.asarray(phi_q(q[i]), dtype=float).reshape(r, -1)
        if out is None:
            out = np.full((q.shape[0], r, J.shape[1]), np.nan)
        out[i] = J
    return np.full((q.shape[0], r, q.shape[1]), np.nan) if out is None else out


def _times(times, shown: int = 5) -> str:
    """``"1.2, 3.4, ... (7 in all)"`` [s]."""
    times = list(times)
    text = ", ".join(f"{x:.6g}" for x in times[:shown])
    return text + (f", ... ({len(times)} in all)" if len(times) > shown else "") + " s"
