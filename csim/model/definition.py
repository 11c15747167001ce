"""What a mechanic writes down about a mechanism, as sympy expressions.

A :class:`MechanismDefinition` holds the generalized coordinates, the kinetic and potential
energies, the constraint functions Phi(q), the loads (each with the coordinate along which
it does work), named parameters with defaults and units, and the points used to draw the
mechanism. Nothing here is an equation of motion: :mod:`csim.model.derive` derives M, C qd,
h, Phi_q, gamma and the load matrix B from it.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from csim.model.deferred import DeferredFields

if TYPE_CHECKING:  # sympy is imported where expressions are built, not by reading this module
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
        import sympy as sp

        return sp.Symbol(self.name, real=True)


@dataclass(frozen=True)
class Load:
    """An applied load u_k: a force element that does work as the mechanism moves.

    Its generalized force is Q_k = b_k(q) u_k and its power u_k b_k . qd (virtual power),
    where the direction b_k is ds_k/dq (the load does work along its coordinate s_k), or
    given (a force fixed in a moving link's frame has no coordinate it works along). The
    value is

        u_k = magnitude_k * active_k * f_k(q, qd, t)

    with the magnitude and the switching law (``active_k``: conditions on s_k and ds_k/dt)
    from the case (:mod:`csim.load_laws`), and the law f_k of the mechanism (1 when ``law`` is
    None: a switched constant).

    Parameters
    ----------
    name : str
        Key under ``loads`` in a case file.
    coordinate : sympy expression
        s_k(q): the crank angle for a torque on the crank, the x coordinate of the point
        of application for a horizontal force, ... The switching conditions watch it.
    unit : str
        Unit of u_k (``"N m"`` or ``"N"``).
    coordinate_unit : str
        Unit of s_k (``"rad"`` or ``"m"``).
    description : str
        One line for a person, saying the positive sense.
    direction : list of sympy expressions (m,) or None
        b_k(q), generalized force per unit of u_k [N or N m per unit of u_k, per unit of
        q]; None: ds_k/dq.
    law : sympy expression or None
        f_k(q, qd, t) in the coordinates, velocities, the time ``t`` [s] and the
        parameters; None: 1.
    magnitude : float
        Default magnitude when the case's ``loads`` section does not name the load.
    window : (float, float)
        Default window of s_k (see :class:`csim.load_laws.LoadLaw`).
    velocity : {"any", "positive", "negative"}
        Default sign condition on ds_k/dt.
    """

    name: str
    coordinate: sp.Expr
    unit: str
    coordinate_unit: str
    description: str
    direction: list | None = None
    law: sp.Expr | None = None
    magnitude: float = 0.0
    window: tuple[float, float] = (float("-inf"), float("inf"))
    velocity: str = "any"

    @property
    def has_law(self) -> bool:
        """Whether the mechanism gives it a law (a force element's); else it is a switched constant."""
        return self.law is not None


#: the symbol of time in load laws [s]
TIME = "t"


def time_symbol() -> sp.Symbol:
    """The time t [s] as it appears in load laws (real)."""
    import sympy as sp

    return sp.Symbol(TIME, real=True)


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
        import sympy as sp

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


@dataclass(frozen=True)
class SiteBody:
    """A body of a registered mechanism that force elements may be placed on (planar).

    Its frame has its origin at ``origin`` and its x axis turned by ``angle`` from the
    global x axis (about global z); a point ``[BODY, [x, y, z]]`` of a force element is
    ``origin + R(angle) (x, y) + z e_z``.

    Parameters
    ----------
    name : str
        What ``mechanism.forces`` calls it (``[crank, A]``); ``"ground"`` for the fixed body.
    origin : tuple of two sympy expressions
        Global (x, y) of the frame's origin, functions of q and the parameters [m].
    angle : sympy expression
        Orientation of the frame [rad] (0 for a body that only translates).
    points : dict of name -> (x, y) sympy expressions [m]
        The named material points of the body, global positions as functions of q.
    """

    name: str
    origin: tuple[sp.Expr, sp.Expr]
    angle: sp.Expr
    points: dict[str, tuple[sp.Expr, sp.Expr]]


@dataclass(frozen=True)
class SiteJoint:
    """A joint of a registered mechanism: one relative coordinate an element may act on.

    Parameters
    ----------
    name : str
        What ``mechanism.forces`` calls it (``joint: O``).
    value : sympy expression
        The joint's variable as a function of q [rad or m] (the crank angle, the relative
        angle of two bodies, a slider's travel).
    unit : {"rad", "m"}
    description : str
        One line: the joint and the positive sense of its variable.
    """

    name: str
    value: sp.Expr
    unit: str
    description: str


@dataclass(frozen=True)
class Sites:
    """Where the force elements of ``mechanism.forces`` may act on a registered mechanism
    (:mod:`csim.mechanisms.sites`): its bodies with their named points, and its joints."""

    bodies: list[SiteBody]
    joints: list[SiteJoint] = field(default_factory=list)


@dataclass(frozen=True)
class Panel:
    """One axes of a declared figure: curves that share a y axis.

    Parameters
    ----------
    series : tuple of str
        What to plot against time, each a series name ``KIND:NAME`` of
        :mod:`csim.plot.series`: ``q:NAME``, ``qd:NAME``, ``qdd:NAME`` (a coordinate, its
        velocity or acceleration), ``observable:NAME``, ``observable_rate:NAME``,
        ``phi:I`` / ``phi_dot:I`` / ``lambda:I`` (constraint I, counted from 1; ``phi:max``
        and ``phi_dot:max`` are the largest magnitude over the constraints), ``load:NAME``,
        ``work:NAME``, ``energy:kinetic|potential|balance_error``. The prefix ``change:``
        plots the change since t = 0 (``change:observable:ram_x``).
    labels : tuple of str
        Legend labels, one per series (empty: automatic; no legend for a single series).
    ylabel : str
        Name of the plotted quantity for the y-axis label; its unit is appended from the
        series (e.g. ``"crank angular velocity"`` becomes ``crank angular velocity [rad/s]``).
    log : bool
        Logarithmic y axis (magnitudes are plotted, e.g. of constraint errors).
    """

    series: tuple[str, ...]
    labels: tuple[str, ...] = ()
    ylabel: str = ""
    log: bool = False


@dataclass(frozen=True)
class DeclaredFigure:
    """A figure a mechanism asks for (e.g. a figure of its paper), built by ``csim plot``.

    Either time histories (``panels``, stacked, sharing the time axis) or the mechanism
    drawn at several instants (``snapshots`` > 0).

    Parameters
    ----------
    name : str
        File name stem and ``--only`` name, e.g. ``"crank_velocity"``.
    title : str
        Figure title, e.g. ``"Crank angular velocity"``.
    panels : tuple of Panel
    snapshots : int
        Draw the mechanism at this many instants (0: a time-history figure).
    cycle : str
        For snapshots: a coordinate whose first full turn (2 pi) is the cycle the instants
        are spread over (the crank of a linkage); empty, or no full turn in the run: the
        whole run.
    reference : str
        Where the figure comes from, shown in the title (e.g. ``"paper fig. H.2"``).
    """

    name: str
    title: str
    panels: tuple[Panel, ...] = ()
    snapshots: int = 0
    cycle: str = ""
    reference: str = ""


@dataclass
class MechanismDefinition(DeferredFields):
    """A holonomic, scleronomic mechanism in redundant coordinates.

    Its energies, constraints, drawing and force-element sites pickle as one blob, unpickled
    where first read (:class:`csim.model.deferred.DeferredFields`): a cached linkage's warm
    run reads none of them.

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
    figures : list of DeclaredFigure
        Mechanism-specific figures of ``csim plot`` (e.g. the paper's), besides the ones
        every mechanism gets (coordinates, velocities, constraints, energy, multipliers).
    sites : Sites or None
        Bodies, points and joints that force elements (``mechanism.forces``) may act on;
        None: the mechanism takes no force elements.
    recursive : callable () -> csim.model.recursive.RecursiveTerms, or None
        The same mechanism's kinematics link by link in named intermediates (a linkage
        built from tables, :mod:`csim.linkage.recursive`): when given,
        :func:`csim.model.derive.derive` assembles M, C qd, T, Phi, Phi_q and gamma from it
        instead of differentiating the whole-mechanism T and Phi (same values, to round-off;
        linear instead of steep growth with the number of links).
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
    figures: list[DeclaredFigure] = field(default_factory=list)
    sites: Sites | None = None
    recursive: Callable | None = field(default=None, repr=False, compare=False)

    DEFERRED = ("kinetic_energy", "potential_energy", "constraints", "drawing", "sites")

    @property
    def coordinate_names(self) -> list[str]:
        return [str(s) for s in self.coordinates]

    @property
    def parameter_names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def n_constraints(self) -> int:
        # counted at construction where the constraints are still pickled (a cached linkage's)
        return self._n_constraints if "_deferred" in self.__dict__ else len(self.constraints)

    def __post_init__(self):
        self._n_constraints = len(self.constraints)

    @property
    def parameter_symbols(self) -> list[sp.Symbol]:
        return [p.symbol for p in self.parameters]

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)
