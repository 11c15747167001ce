"""What every stabilization method is: its options, its gamma*, the system it integrates.

A method is a subclass of :class:`Method` in a file of its own in this package:

``name``
    the registry key (``stabilization.method`` in a case file);
``Options``
    a frozen dataclass of its settings, each declared with :func:`option` (default, unit,
    bounds, one line of documentation). The case schema's ``stabilization`` section and
    the table in docs/how-it-works.md are generated from these declarations;
``system``
    the system class that integrates it (:class:`csim.solver.system.ConstrainedSystem`
    unless the method changes what is integrated);
``gamma_star_kernel``
    a core function (:func:`csim.physics.jit.kernel`) computing gamma* from
    (gamma, Phi, Phi'), with the method's gains packed by :meth:`Method.pack`. The
    Python driver and the compiled loop call this same function;
``compiled``
    whether the compiled kernels run the method (they do whenever it is expressed by
    gamma* and, optionally, the projection after every step: ``projects``).

Adding a method is adding one file here; :mod:`csim.solver.methods` registers every
subclass it finds (:func:`register` takes one defined elsewhere, e.g. in a test).
"""
from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import numpy as np

from csim.physics.linalg import as_core
from csim.schema import finite_number


def option(default: Any, doc: str, unit: str = "", *, gain: bool = False, gt: float | None = None,
           ge: float | None = None, le: float | None = None, choices: tuple | None = None):
    """A method setting: a dataclass field whose metadata the case schema is generated from.

    Parameters
    ----------
    default : float, int or str
        The value when the case file leaves the key out; its type is the key's type.
    doc : str
        One line for a person (schema help, README).
    unit : str
        SI unit, or a unit relative to the constraints ("unit of Phi/s").
    gain : bool
        A gain: a positive number, or a list of positive numbers, one per constraint.
    gt, ge, le : float, optional
        Bounds on a number.
    choices : tuple of str, optional
        The allowed strings.
    """
    meta = dict(doc=doc, unit=unit, gain=gain, gt=gt, ge=ge, le=le, choices=choices)
    return dataclasses.field(default=default, metadata=meta)


@dataclasses.dataclass(frozen=True)
class ErrorMode:
    """One mode of the constraint-error dynamics a method imposes, linearised at Phi = 0.

    The eigenvalue is ``lambda = gain * shape`` [1/s]; an explicit fixed step h is stable
    for the mode when h lambda lies in the integrator's stability region
    (:mod:`csim.solver.stability`).

    Attributes
    ----------
    keys : str
        The gain as the case-file keys that make it, e.g. ``"stabilization.w"``.
    gain : float
        Its value [1/s].
    shape : complex
        lambda / gain, e.g. -1 for Baumgarte with d = 1.
    note : str
        What else fixes ``shape`` (``"d = 1"``), or "".
    constraint : int or None
        The constraint (0-based) of a gain given one per constraint; None for one gain.
    saturates : str
        What happens beyond the region when a nonlinearity bounds the growth (a smooth
        switching function saturates); "" when the error grows without bound.
    """

    keys: str
    gain: float
    shape: complex
    note: str = ""
    constraint: int | None = None
    saturates: str = ""


@dataclasses.dataclass(frozen=True)
class NoOptions:
    """A method without settings."""


def _gain_array(value, r: int) -> np.ndarray:
    """A gain (a number, or one per constraint) as an (r,) float array."""
    return np.ascontiguousarray(np.broadcast_to(np.asarray(value, dtype=float), (r,)), dtype=float)


class Method:
    """A constraint stabilization method (see the module docstring for what a subclass declares).

    Parameters
    ----------
    **options
        Settings, by their case-file key; each must be a field of ``Options``.
    """

    name: ClassVar[str] = "abstract"
    #: position in listings (registry order, ``csim compare``'s default method order)
    rank: ClassVar[int] = 100
    Options: ClassVar[type] = NoOptions
    #: the integrators that can run the method (None: every one)
    integrators: ClassVar[tuple[str, ...] | None] = None
    #: whether the compiled kernels run it (gamma* and, with ``projects``, the projection)
    compiled: ClassVar[bool] = False
    #: whether the state is projected onto Phi = 0, Phi_q qd = 0 after every accepted step
    projects: ClassVar[bool] = False
    #: gamma_star_kernel(r, gamma, phi, phi_dot, gains, fpar, ipar, out) with :meth:`pack`'s arrays;
    #: None: gamma* = gamma
    gamma_star_kernel: ClassVar[Any] = None

    def __init__(self, **options):
        self.options = self.Options(**options)
        self._packed: dict[int, tuple] = {}

    @classmethod
    def system_class(cls):
        """The system that integrates the method (the constrained ODE unless overridden)."""
        from csim.solver.system import ConstrainedSystem

        return ConstrainedSystem

    # -- the packing the core functions read ------------------------------------------
    def gains(self, r: int) -> list[np.ndarray]:
        """Per-constraint gains, each (r,), in the order ``gamma_star_kernel`` reads them."""
        return []

    def parameters(self) -> tuple[list[float], list[int]]:
        """Scalar settings the core functions read: (floats, integers)."""
        return [], []

    def error_modes(self) -> list[ErrorMode]:
        """The modes of the constraint-error dynamics the method imposes (none: it imposes none)."""
        return []

    def pack(self, r: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(gains (G * r,), fpar (F,), ipar (I,)): the method as arrays, for ``r`` constraints.

        ``gains`` holds the G rows of :meth:`gains` one after the other (gain g of
        constraint i at g * r + i). Each array has at least one entry, so that every
        method passes arrays of the same kinds.
        """
        if r not in self._packed:
            rows = self.gains(r)
            gains = np.concatenate([*rows, [0.0]]) if rows else np.zeros(1)
            floats, ints = self.parameters()
            fpar = np.array([*floats, 0.0], dtype=float)
            ipar = np.array([*ints, 0], dtype=np.int64)
            self._packed[r] = (np.ascontiguousarray(gains, dtype=float), fpar, ipar)
        return self._packed[r]

    def gamma_star(self, gamma: np.ndarray, phi: np.ndarray, phi_dot: np.ndarray) -> np.ndarray:
        """gamma* (r,) from gamma (r,), Phi (r,) and dPhi/dt = Phi_q qd (r,)."""
        if self.gamma_star_kernel is None:
            return gamma
        gamma, phi, phi_dot = (as_core(a) for a in (gamma, phi, phi_dot))
        out = np.empty(gamma.size)
        type(self).gamma_star_kernel(gamma.size, gamma, phi, phi_dot, *self.pack(gamma.size), out)
        return out

    @classmethod
    def option_fields(cls) -> list[dataclasses.Field]:
        """The declared settings (dataclass fields with :func:`option` metadata)."""
        return list(dataclasses.fields(cls.Options))


def per_constraint(*gains) -> list[tuple[int | None, tuple[float, ...]]]:
    """The gains of each constraint, ``[(i, (g1, g2, ...)), ...]``, once per distinct tuple.

    ``i`` is None when every gain is one number (the same on every constraint).
    """
    arrays = [np.atleast_1d(np.asarray(g, dtype=float)) for g in gains]
    if all(a.size == 1 for a in arrays):
        return [(None, tuple(float(a[0]) for a in arrays))]
    r = max(a.size for a in arrays)
    rows = np.stack([np.broadcast_to(a, (r,)) for a in arrays], axis=1)
    seen: dict[tuple, int] = {}
    for i, row in enumerate(rows):
        seen.setdefault(tuple(float(v) for v in row), i)
    return [(i, values) for values, i in seen.items()]


def positive_gains(value) -> str | None:
    """None if ``value`` is a positive number or a non-empty list of them, else what was expected."""
    values = value if isinstance(value, list) else [value]
    ok = bool(values) and all(finite_number(v) and v > 0 for v in values)
    return None if ok else "a positive number, or a list of positive numbers (one per constraint)"
