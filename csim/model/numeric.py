"""The numeric model: fast functions of (q, qd, par) generated from the symbolic one."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from csim.model.cache import FUNCTIONS, cached_code, cached_source
from csim.model.definition import MechanismDefinition


@dataclass
class NumericModel:
    """Array-in/array-out model functions of one mechanism.

    All functions take ``q`` (m,) [rad or m], ``qd`` (m,) where listed, and ``par``
    (n_par,) in the order of ``definition.parameters``:

    ``mass(q, par)`` (m, m); ``velocity_terms(q, qd, par)`` (m,) = C qd;
    ``gravity(q, par)`` (m,) = h; ``phi(q, par)`` (r,); ``phi_q(q, par)`` (r, m);
    ``gamma(q, qd, par)`` (r,); ``load_coordinates(q, par)`` (k,);
    ``load_matrix(q, par)`` (m, k) = B; ``load_jacobian(q, par)`` (m, k) = ds/dq^T;
    ``load_law(q, qd, t, par)`` (k,) the laws f(q, qd, t) (t [s]); ``kinetic_energy``, ``potential_energy`` floats [J];
    ``observables(q, par)`` (o,); ``observable_jacobian(q, par)`` (o, m);
    ``points(q, par)`` (P, 2), or (P, 3) for a spatial drawing [m].
    """

    definition: MechanismDefinition
    source: str
    mass: Callable
    velocity_terms: Callable
    gravity: Callable
    phi: Callable
    phi_q: Callable
    gamma: Callable
    load_coordinates: Callable
    load_matrix: Callable
    load_jacobian: Callable
    load_law: Callable
    kinetic_energy: Callable
    potential_energy: Callable
    observables: Callable
    observable_jacobian: Callable
    points: Callable

    @property
    def n_coordinates(self) -> int:
        return len(self.definition.coordinate_names)

    @property
    def n_constraints(self) -> int:
        return self.definition.n_constraints

    @property
    def n_loads(self) -> int:
        return len(self.definition.loads)

    def parameter_vector(self, values: dict[str, float] | None = None) -> np.ndarray:
        """``par`` (n_par,) from defaults overridden by ``values``."""
        values = values or {}
        return np.array([float(values.get(p.name, p.default)) for p in self.definition.parameters])


def build_numeric_model(definition: MechanismDefinition, use_cache: bool = True) -> NumericModel:
    """Derive (or load from the cache) and compile the model functions of ``definition``."""
    source = cached_source(definition, use_cache=use_cache)
    namespace: dict = {}
    exec(cached_code(definition, source, use_cache=use_cache), namespace)
    functions = {name: _nan_outside_domain(namespace[name]) for name in FUNCTIONS}
    return NumericModel(definition=definition, source=source, **functions)


def _nan_outside_domain(f: Callable) -> Callable:
    """``f``, returning NaN where its arguments leave the domain of ``math`` (``math.cos(inf)``,
    ``math.sqrt(-1)`` raise ValueError): an implicit integrator's trial state then makes it
    reject the step, as a NaN would, instead of ending the run with "math domain error"."""

    def guarded(*args):
        try:
            return f(*args)
        except (ValueError, OverflowError, ZeroDivisionError):
            return _nan_like(f, args)

    guarded.__name__ = f.__name__
    guarded.__doc__ = f.__doc__
    guarded.__wrapped__ = f
    return guarded


def _nan_like(f: Callable, args: tuple):
    """NaN in the shape ``f`` returns (found at zero arguments of the same shapes)."""
    with np.errstate(all="ignore"):
        try:
            out = f(*(np.zeros_like(np.asarray(a, dtype=float)) for a in args))
        except (ValueError, OverflowError, ZeroDivisionError):
            out = f(*(np.full_like(np.asarray(a, dtype=float), 0.5) for a in args))
    if np.isscalar(out):
        return float("nan")
    return np.full(np.shape(out), np.nan)
