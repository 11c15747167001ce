"""A simple pendulum in Cartesian coordinates: the smallest closed-form test bed.

A point mass m on a massless rod of length L, pivot at the origin, gravity along -y.
Redundant coordinates q = [x, y] with one constraint

    Phi(q) = (x^2 + y^2 - L^2) / (2 L) = 0        [m]

(1 DOF). Scaled so that Phi is, to first order, the radial distance from the circle. Its
exact motion is the planar pendulum's, theta'' = -(g / L) sin theta with
theta = atan2(x, -y); the stabilizers' decay of Phi(t) is checked against analytic curves
on it.
"""
from __future__ import annotations

import sympy as sp

from csim.model.definition import (
    DeclaredFigure,
    Drawing,
    MechanismDefinition,
    Observable,
    Panel,
    Parameter,
    PlanarBody,
    SiteBody,
    SiteJoint,
    Sites,
)

PARAMETERS = [
    Parameter("m", 1.0, "kg", "bob mass", strictly_positive=True),
    Parameter("L", 1.0, "m", "rod length", strictly_positive=True),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration (along -y)", minimum=0.0),
]


def definition() -> MechanismDefinition:
    """Build the symbolic Cartesian pendulum."""
    x, y = q = sp.symbols("x y", real=True)
    qd = sp.symbols("xd yd", real=True)
    m, L, g = (p.symbol for p in PARAMETERS)
    bob = PlanarBody("bob", m, sp.Integer(0), (x, y), sp.Integer(0))
    pivot = (sp.Integer(0), sp.Integer(0))
    angle = sp.atan2(x, -y)  # from the downward vertical, counter-clockwise
    # where force elements (mechanism.forces) may act; the rod's frame has x along pivot -> bob
    sites = Sites(bodies=[SiteBody("ground", pivot, sp.Integer(0), {"pivot": pivot}),
                          SiteBody("rod", pivot, angle - sp.pi / 2, {"pivot": pivot, "bob": (x, y)})],
                  joints=[SiteJoint("pivot", angle, "rad", "rod on the ground: angle from the downward vertical, "
                                    "counter-clockwise")])
    return MechanismDefinition(
        name="pendulum",
        description="point-mass pendulum in Cartesian coordinates",
        coordinates=list(q),
        velocities=list(qd),
        coordinate_units=["m", "m"],
        parameters=list(PARAMETERS),
        kinetic_energy=bob.kinetic_energy(list(q), list(qd)),
        potential_energy=bob.potential_energy(g),
        constraints=[(x**2 + y**2 - L**2) / (2 * L)],
        observables=[Observable("angle", angle, "rad", "rad/s", "angle from the downward vertical")],
        drawing=Drawing(points={"pivot": (sp.Integer(0), sp.Integer(0)), "bob": (x, y)},
                        links=[("pivot", "bob")], ground=["pivot"]),
        default_independent={"x": 0.5},
        default_independent_velocities={"x": 0.0},
        default_guess={"y": -1.0},
        figures=[
            DeclaredFigure("angle", "Pendulum angle and angular velocity",
                           panels=(Panel(("observable:angle",), ylabel="angle from the downward vertical"),
                                   Panel(("observable_rate:angle",), ylabel="angular velocity"))),
            DeclaredFigure("configurations", "The pendulum at six instants", snapshots=6),
        ],
        sites=sites,
    )
