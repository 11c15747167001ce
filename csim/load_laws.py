"""Force laws of the applied loads, as data from the case file.

Each load u_k of a mechanism does work along its coordinate s_k(q) (see
:class:`csim.model.definition.Load`). Its law is a magnitude switched on and off by
conditions on s_k and its rate ds_k/dt:

    u_k = magnitude * f_k   if  lo <= s_k <= hi  and  (ds_k/dt < 0 | > 0 | any)
    u_k = 0                 otherwise

where f_k(q, qd, t) is the load's law in the mechanism (1 for a switched constant; a force
element of a link-coupling mechanism may give an expression, e.g. a damper's c ldot).

Each condition is a *switching function* g(s, sdot) that is positive where it holds
(s - lo, hi - s, -sdot or sdot). The solver locates the zeros of the switching functions as
events and keeps the set of conditions that hold (the *mode*) fixed in between, so the
right-hand side it integrates is smooth.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from csim.physics import loads as core
from csim.quantities import convert, is_quantity
from csim.schema import describe, finite_number

VELOCITY_CONDITIONS = ("any", "positive", "negative")

#: a window bound whose unit could not be converted (the problem is reported)
REPORTED = object()


def window_bound(path: str, value, unit: str, problems: list[str]):
    """One bound of a load window (``loads.NAME.window``, a force element's ``window``) as a
    float: +-.inf allowed (an open end), ``30 deg`` converted to ``unit`` (the unit of the
    coordinate the load switches on); None for anything else (not a number, .nan, an integer
    beyond the float range); :data:`REPORTED` for a value whose unit cannot be converted
    (``path``, the bound's key, and why are appended to ``problems``)."""
    if isinstance(value, float) and math.isinf(value):
        return value
    if is_quantity(value):
        number, problem = convert(value, unit)
        if problem is not None:
            problems.append(f"{path}: got {describe(value)}; {problem}")
            return REPORTED
        value = number
    return float(value) if finite_number(value) else None


@dataclass(frozen=True)
class LoadLaw:
    """Law of one load: ``magnitude`` while ``s`` is in ``window`` and ``ds/dt`` has ``velocity``'s sign.

    Parameters
    ----------
    name : str
        Load name (a key of ``loads`` in the case file).
    magnitude : float
        Value of the load while active [N or N m].
    window : (float, float)
        Closed interval of s where the load may be active [m or rad]; infinite bounds allowed.
    velocity : {"any", "positive", "negative"}
        Sign of ds/dt required for the load to be active.
    """

    name: str
    magnitude: float
    window: tuple[float, float] = (-np.inf, np.inf)
    velocity: str = "any"

    @property
    def switch_labels(self) -> list[str]:
        """One label per switching function, e.g. ``"cutting_force: s = 1.2"``."""
        labels = []
        lo, hi = self.window
        if np.isfinite(lo):
            labels.append(f"{self.name}: s = {lo:g} (lower window bound)")
        if np.isfinite(hi):
            labels.append(f"{self.name}: s = {hi:g} (upper window bound)")
        if self.velocity != "any":
            labels.append(f"{self.name}: ds/dt = 0 (velocity sign)")
        return labels

    def switching(self, s: float, sdot: float) -> list[float]:
        """Switching functions at (s, ds/dt); each is > 0 where its condition holds."""
        return LoadSet([self]).switching(np.array([s], dtype=float), np.array([sdot], dtype=float)).tolist()

    def conditions(self) -> list[tuple[int, float]]:
        """Its switching functions as (kind, value) pairs of :mod:`csim.physics.loads`, in label order."""
        out = []
        lo, hi = self.window
        if np.isfinite(lo):
            out.append((core.LOWER, float(lo)))
        if np.isfinite(hi):
            out.append((core.UPPER, float(hi)))
        if self.velocity == "positive":
            out.append((core.RISING, 0.0))
        elif self.velocity == "negative":
            out.append((core.FALLING, 0.0))
        return out


class LoadSet:
    """The laws of all loads of a mechanism, in the mechanism's load order.

    Parameters
    ----------
    laws : list of LoadLaw
        One per load of the mechanism (a load not named in the case file has magnitude 0).

    Attributes
    ----------
    magnitudes : ndarray (k,)
    sw_load, sw_kind, sw_value : ndarray (n_switches,)
        The switching functions packed for :mod:`csim.physics.loads`: the load each
        belongs to, its kind and its bound.
    """

    def __init__(self, laws: list[LoadLaw]):
        self.laws = list(laws)
        self.magnitudes = np.array([law.magnitude for law in self.laws], dtype=float)
        packed = [(k, kind, value) for k, law in enumerate(self.laws) for kind, value in law.conditions()]
        self.sw_load = np.array([p[0] for p in packed], dtype=np.int64)
        self.sw_kind = np.array([p[1] for p in packed], dtype=np.int64)
        self.sw_value = np.array([p[2] for p in packed], dtype=float)
        self.n_switches = len(packed)
        self.switch_labels = [label for law in self.laws for label in law.switch_labels]

    def switching(self, s: np.ndarray, sdot: np.ndarray) -> np.ndarray:
        """All switching functions g (n_switches,) at load coordinates ``s`` (k,) and rates ``sdot`` (k,)."""
        g = np.empty(self.n_switches)
        core.switching_functions(np.asarray(s, dtype=float), np.asarray(sdot, dtype=float), self.sw_load,
                                 self.sw_kind, self.sw_value, g)
        return g

    def values(self, mode: np.ndarray, law: np.ndarray | None = None) -> np.ndarray:
        """Load values u (k,) in a mode: ``mode`` (n_switches,) bool, the conditions that hold.

        ``law`` (k,): the loads' laws f(q, qd, t) at the state (None: 1, switched constants).
        """
        u = np.empty(len(self.laws))
        law = np.ones(len(self.laws)) if law is None else np.asarray(law, dtype=float)
        core.load_values(self.magnitudes, np.asarray(mode, dtype=np.bool_), self.sw_load, law, u)
        return u

    def mode(self, g: np.ndarray) -> np.ndarray:
        """The mode that holds where the switching functions are ``g``: the law's own inequality."""
        mode = np.empty(len(g), dtype=np.bool_)
        core.mode_of(np.asarray(g, dtype=float), mode)
        return mode
