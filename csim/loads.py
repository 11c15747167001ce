"""Force laws of the applied loads, as data from the case file.

Each load u_k of a mechanism does work along its coordinate s_k(q) (see
:class:`csim.model.definition.Load`). Its law is a magnitude switched on and off by
conditions on s_k and its rate ds_k/dt:

    u_k = magnitude   if  lo <= s_k <= hi  and  (ds_k/dt < 0 | > 0 | any)
    u_k = 0           otherwise

Each condition is a *switching function* g(s, sdot) that is positive where it holds
(s - lo, hi - s, -sdot or sdot). The solver locates the zeros of the switching functions as
events and keeps the set of conditions that hold (the *mode*) fixed in between, so the
right-hand side it integrates is smooth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

VELOCITY_CONDITIONS = ("any", "positive", "negative")


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
        g = []
        lo, hi = self.window
        if np.isfinite(lo):
            g.append(s - lo)
        if np.isfinite(hi):
            g.append(hi - s)
        if self.velocity == "positive":
            g.append(sdot)
        elif self.velocity == "negative":
            g.append(-sdot)
        return g


class LoadSet:
    """The laws of all loads of a mechanism, in the mechanism's load order.

    Parameters
    ----------
    laws : list of LoadLaw
        One per load of the mechanism (a load not named in the case file has magnitude 0).
    """

    def __init__(self, laws: list[LoadLaw]):
        self.laws = list(laws)
        self.magnitudes = np.array([law.magnitude for law in self.laws], dtype=float)
        # slices of the concatenated switching-function vector that belong to each law
        self._slices = []
        start = 0
        for law in self.laws:
            n = len(law.switch_labels)
            self._slices.append(slice(start, start + n))
            start += n
        self.n_switches = start
        self.switch_labels = [label for law in self.laws for label in law.switch_labels]

    def switching(self, s: np.ndarray, sdot: np.ndarray) -> np.ndarray:
        """All switching functions g (n_switches,) at load coordinates ``s`` (k,) and rates ``sdot`` (k,)."""
        g = []
        for k, law in enumerate(self.laws):
            g.extend(law.switching(s[k], sdot[k]))
        return np.array(g, dtype=float)

    def values(self, mode: np.ndarray) -> np.ndarray:
        """Load values u (k,) in a mode: ``mode`` (n_switches,) bool, the conditions that hold."""
        u = self.magnitudes.copy()
        for k, sl in enumerate(self._slices):
            if not np.all(mode[sl]):
                u[k] = 0.0
        return u

    def mode(self, g: np.ndarray) -> np.ndarray:
        """The mode that holds where the switching functions are ``g``: the law's own inequality."""
        return g > 0.0
