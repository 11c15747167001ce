"""What a mechanic writes down about a mechanism, as sympy expressions.

A :class:`MechanismDefinition` holds the generalized coordinates, the kinetic and potential
energies, the constraint functions Phi(q), the loads (each with the coordinate along which
it does work), named parameters with defaults and units, and the points used to draw the
mechanism. Nothing here is an equation of motion: :mod:`csim.model.derive` derives M, C qd,
h, Phi_q, gamma and the load matrix B from it.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp


@dataclass(frozen=True)
class Parameter:
    """A named, numeric parameter of a mechanism.

    Parameters
    ----------
    name : str
        Symbol name, also the key under ``mechanism.parameters`` in a case file.
    default : float
        Default value (SI units).
    unit : str
        Unit, e.g. ``"m"``, ``"kg"``, ``"kg m^2"``.
    description : str
        One line for a person.
    minimum : float or None
        Values must be >= this (``None``: no bound).
    strictly_positive : bool
        Values must be > 0 (lengths, masses).
    """

    name: str
    default: float
    unit: str
    description: str
    minimum: float | None = None
    strictly_positive: bool = False

    @property
    def symbol(self) -> sp.Symbol:
        return sp.Symbol(self.name, real=True)


@dataclass(frozen=True)
class Load:
    """An applied load u_k that does work along a scalar coordinate s_k(q).

    Its generalized force is Q_k = (ds_k/dq)^T u_k (virtual work), its power u_k ds_k/dt.

    Parameters
    ----------
    name : str
        Key under ``loads`` in a case file.
    coordinate : sympy expression
        s_k(q): the crank angle for a torque on the crank, the x coordinate of the point
        of application for a horizontal force, ...
    unit : str
        Unit of u_k (``"N m"`` or ``"N"``).
    coordinate_unit : str
        Unit of s_k (``"rad"`` or ``"m"``).
    description : str
        One line for a person, saying the positive sense.
    """

    name: str
    coordinate: sp.Expr
    unit: str
    coordinate_unit: str
    description: str


@dataclass(frozen=True)
class PlanarBody:
    """A rigid body moving in the x-y plane, for building T and V.

    Parameters
    ----------
    name : str
    mass, inertia : sympy expressions
        Mass [kg] and moment of inertia about the centre of mass [kg m^2].
    com : tuple of two sympy expressions
        Position of the centre of mass, (x, y) as functions of q [m].
    angle : sympy expression
        Orientation angle as a function of q [rad].
    height : sympy expression or None
        Height used for the potential energy, when it differs from ``com[1]`` (e.g. a ram
        whose weight is carried by its guide: its height is the guide's, a constant).
    """

    name: str
    mass: sp.Expr
    inertia: sp.Expr
    com: tuple[sp.Expr, sp.Expr]
    angle: sp.Expr
    height: sp.Expr | None = None

    def kinetic_energy(self, q: list[sp.Symbol], qd: list[sp.Symbol]) -> sp.Expr:
        """T = 1/2 m |v_C|^2 + 1/2 J omega^2, velocities by the chain rule in q."""
        vx = sum(sp.diff(self.com[0], qi) * qdi for qi, qdi in zip(q, qd))
        vy = sum(sp.diff(self.com[1], qi) * qdi for qi, qdi in zip(q, qd))
        omega = sum(sp.diff(self.angle, qi) * qdi for qi, qdi in zip(q, qd))
        return sp.Rational(1, 2) * self.mass * (vx**2 + vy**2) + sp.Rational(1, 2) * self.inertia * omega**2

    def potential_energy(self, g: sp.Expr) -> sp.Expr:
        """V = m g y (gravity along -y)."""
        y = self.com[1] if self.height is None else self.height
        return self.mass * g * y


@dataclass(frozen=True)
class Drawing:
    """How to draw the mechanism (plots and animations).

    Parameters
    ----------
    points : dict of name -> (x, y) sympy expressions in q and parameters [m]
    links : list of tuple of point names
        Each link is drawn as a bar (two points) or polygon (more) through these points.
    ground : list of point names
        Points fixed to the ground, drawn hatched.
    guides : list of ((x0, y0), (x1, y1)) of sympy expressions
        Fixed straight guides (slider tracks), drawn as lines.
    """

    points: dict[str, tuple[sp.Expr, sp.Expr]]
    links: list[tuple[str, ...]]
    ground: list[str] = field(default_factory=list)
    guides: list[tuple[tuple[sp.Expr, sp.Expr], tuple[sp.Expr, sp.Expr]]] = field(default_factory=list)


@dataclass(frozen=True)
class Observable:
    """A scalar quantity of the mechanism worth recording and plotting, s(q).

    Its rate ds/dt = (ds/dq) qd is recorded beside it.
    """

    name: str
    expression: sp.Expr
    unit: str
    rate_unit: str
    description: str


@dataclass
class MechanismDefinition:
    """A holonomic, scleronomic mechanism in redundant coordinates.

    Parameters
    ----------
    name : str
        Registry name (``mechanism.name`` in a case file).
    description : str
    coordinates : list of sympy Symbol, length m
        Generalized coordinates q.
    velocities : list of sympy Symbol, length m
        Symbols for qd, same order.
    coordinate_units : list of str
    parameters : list of Parameter
    kinetic_energy : sympy expression
        T(q, qd), quadratic in qd [J].
    potential_energy : sympy expression
        V(q) [J].
    constraints : list of sympy expressions, length r
        Phi(q) = 0.
    loads : list of Load
    observables : list of Observable
    drawing : Drawing or None
    default_independent : dict name -> float
        Default values of the independent coordinates (their velocities in
        ``default_independent_velocities``) for ``initial`` in a case file.
    default_guess : dict name -> float
        Newton start values for the dependent coordinates (select the assembly branch).
    """

    name: str
    description: str
    coordinates: list[sp.Symbol]
    velocities: list[sp.Symbol]
    coordinate_units: list[str]
    parameters: list[Parameter]
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    constraints: list[sp.Expr]
    loads: list[Load] = field(default_factory=list)
    observables: list[Observable] = field(default_factory=list)
    drawing: Drawing | None = None
    default_independent: dict[str, float] = field(default_factory=dict)
    default_independent_velocities: dict[str, float] = field(default_factory=dict)
    default_guess: dict[str, float] = field(default_factory=dict)

    @property
    def coordinate_names(self) -> list[str]:
        return [str(s) for s in self.coordinates]

    @property
    def parameter_names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def parameter_symbols(self) -> list[sp.Symbol]:
        return [p.symbol for p in self.parameters]

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)
