"""The quick-return (shaper) mechanism of Haug's textbook, as used by the sliding-mode paper.

Planar, 1 DOF, vertical x-y plane, gravity along -y. Redundant coordinates
q = [q1, q2, q3]: crank, rocker and connecting-rod angles from +x. Rocker pivot B at the
origin, crank pivot O at (0, h1), ram guide on the line y = h2. See
docs/how-it-works.md; only geometry, bodies and loads are written here, the
equations of motion are derived.
"""
from __future__ import annotations

import sympy as sp

from csim.model.definition import (
    DeclaredFigure,
    Drawing,
    Load,
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
    Parameter("l1", 1.5, "m", "crank length OA", strictly_positive=True),
    Parameter("l2", 4.0, "m", "rocker length BC", strictly_positive=True),
    Parameter("l3", 1.9, "m", "connecting-rod length CD", strictly_positive=True),
    Parameter("h1", 2.0, "m", "height of the crank pivot O above the rocker pivot B", strictly_positive=True),
    Parameter("h2", 4.0, "m", "height of the ram guide above B", strictly_positive=True),
    Parameter("a1", 0.0, "m", "crank centre of mass from O", minimum=0.0),
    Parameter("a2", 2.0, "m", "rocker centre of mass from B", minimum=0.0),
    Parameter("a3", 0.95, "m", "rod centre of mass from C", minimum=0.0),
    Parameter("m1", 4000.0, "kg", "crank mass", strictly_positive=True),
    Parameter("m2", 100.0, "kg", "rocker mass", strictly_positive=True),
    Parameter("m3", 30.0, "kg", "rod mass", strictly_positive=True),
    Parameter("m4", 5.0, "kg", "slider-block mass", strictly_positive=True),
    Parameter("m5", 50.0, "kg", "ram mass", strictly_positive=True),
    Parameter("J1", 4000.0, "kg m^2", "crank inertia about its centre of mass", strictly_positive=True),
    Parameter("J2", 100.0, "kg m^2", "rocker inertia about its centre of mass", strictly_positive=True),
    Parameter("J3", 10.0, "kg m^2", "rod inertia about its centre of mass", strictly_positive=True),
    Parameter("J4", 0.05, "kg m^2", "slider-block inertia about its centre of mass", minimum=0.0),
    Parameter("g", 9.81, "m/s^2", "gravitational acceleration (along -y)", minimum=0.0),
]


#: the paper's figures H.2 to H.7 (docs/plots.md), in terms of the recorded series
FIGURES = (
    DeclaredFigure("crank_velocity", "Crank angular velocity", reference="paper fig. H.2",
                   panels=(Panel(("qd:q1",), ylabel=r"crank angular velocity $\dot{q}_1$"),)),
    DeclaredFigure("ram_displacement", "Ram displacement", reference="paper fig. H.3",
                   panels=(Panel(("change:observable:ram_x",), ylabel=r"ram displacement $x_D - x_D(0)$"),)),
    DeclaredFigure("ram_position_velocity", "Ram position and velocity", reference="paper fig. H.4",
                   panels=(Panel(("observable:ram_x",), ylabel=r"ram position $x_D$"),
                           Panel(("observable_rate:ram_x",), ylabel=r"ram velocity $v_D = \dot{x}_D$"))),
    DeclaredFigure("rocker_rod_angles", "Rocker and connecting-rod angles", reference="paper fig. H.5",
                   panels=(Panel(("q:q2", "q:q3"), labels=(r"rocker $q_2$", r"rod $q_3$"), ylabel="angle"),)),
    DeclaredFigure("constraint_error", "Constraint error", reference="paper fig. H.6",
                   panels=(Panel(("phi:1", "phi:2"), labels=(r"$|\Phi_1|$: A on the rocker line",
                                                             r"$|\Phi_2|$: D on the ram guide"),
                                 ylabel=r"constraint error $|\Phi_i|$", log=True),)),
    DeclaredFigure("configurations", "The mechanism during one crank revolution", reference="paper fig. H.7",
                   snapshots=6, cycle="q1"),
)


def _drawing(O, A, B, C, D, q2, l2, l3, h2) -> Drawing:
    """The drawing: the links through the joints, the slider block, a small rectangle on the
    rocker line at A, and the ram, a block sliding on its guide through D (both drawn only:
    their size is not a parameter)."""
    def unit(angle):
        return sp.cos(angle), sp.sin(angle)

    e2, n2 = unit(q2), (-sp.sin(q2), sp.cos(q2))
    block_a, block_b = sp.Rational(1, 4), sp.Rational(3, 20)
    ram_a, ram_b = sp.Rational(1, 2), sp.Rational(3, 20)

    def block_corner(sa, sb):
        return (A[0] + sa * block_a * e2[0] + sb * block_b * n2[0], A[1] + sa * block_a * e2[1] + sb * block_b * n2[1])

    return Drawing(
        points={
            "O": O,
            "A": A,
            "B": B,
            "C": C,
            "D": D,
            "block_1": block_corner(-1, -1),
            "block_2": block_corner(1, -1),
            "block_3": block_corner(1, 1),
            "block_4": block_corner(-1, 1),
            "ram_1": (D[0] - ram_a, h2 - ram_b),
            "ram_2": (D[0] + ram_a, h2 - ram_b),
            "ram_3": (D[0] + ram_a, h2 + ram_b),
            "ram_4": (D[0] - ram_a, h2 + ram_b),
        },
        links=[("O", "A"), ("B", "C"), ("C", "D"), ("block_1", "block_2", "block_3", "block_4"),
               ("ram_1", "ram_2", "ram_3", "ram_4")],
        ground=["O", "B"],
        guides=[((-l2 - l3, h2), (l2 + l3, h2))],
    )


def definition() -> MechanismDefinition:
    """Build the symbolic quick-return mechanism."""
    q1, q2, q3 = q = sp.symbols("q1 q2 q3", real=True)
    qd = sp.symbols("qd1 qd2 qd3", real=True)
    P = {p.name: p.symbol for p in PARAMETERS}
    l1, l2, l3, h1, h2 = (P[k] for k in ("l1", "l2", "l3", "h1", "h2"))

    def unit(angle):
        return sp.cos(angle), sp.sin(angle)

    O = (sp.Integer(0), h1)
    B = (sp.Integer(0), sp.Integer(0))
    A = (O[0] + l1 * sp.cos(q1), O[1] + l1 * sp.sin(q1))  # crank pin
    C = (l2 * sp.cos(q2), l2 * sp.sin(q2))  # rocker tip
    D = (C[0] + l3 * sp.cos(q3), C[1] + l3 * sp.sin(q3))  # rod end on the ram

    def along(start, angle, distance):
        e = unit(angle)
        return (start[0] + distance * e[0], start[1] + distance * e[1])

    bodies = [
        PlanarBody("crank", P["m1"], P["J1"], along(O, q1, P["a1"]), q1),
        PlanarBody("rocker", P["m2"], P["J2"], along(B, q2, P["a2"]), q2),
        PlanarBody("rod", P["m3"], P["J3"], along(C, q3, P["a3"]), q3),
        # The block is pinned to the crank at A and turns with the rocker.
        PlanarBody("block", P["m4"], P["J4"], A, q2),
        # The ram only translates; D rides on it. Its weight is carried by the guide at
        # height h2, so its potential energy is constant (it enters neither h nor lambda).
        PlanarBody("ram", P["m5"], sp.Integer(0), D, sp.Integer(0), height=h2),
    ]
    T = sum(b.kinetic_energy(list(q), list(qd)) for b in bodies)
    V = sum(b.potential_energy(P["g"]) for b in bodies)

    constraints = [
        # A lies on the rocker line BC: (A - B) x e2 = 0, written as in the sliding-mode paper
        l1 * sp.sin(q1 - q2) + h1 * sp.cos(q2),
        # D stays on the ram guide, y_D = h2
        h2 - D[1],
    ]
    loads = [
        Load("torque", q1, "N m", "rad", "driving torque on the crank, counter-clockwise positive"),
        Load("cutting_force", D[0], "N", "m", "horizontal force on the ram at D, positive along +x"),
    ]
    observables = [
        Observable("ram_x", D[0], "m", "m/s", "ram position x_D"),
    ]
    drawing = _drawing(O, A, B, C, D, q2, l2, l3, h2)
    # where force elements (mechanism.forces) may act: the bodies' points and the joints
    zero = sp.Integer(0)
    sites = Sites(
        bodies=[
            SiteBody("ground", B, zero, {"O": O, "B": B}),
            SiteBody("crank", O, q1, {"O": O, "A": A}),
            SiteBody("rocker", B, q2, {"B": B, "C": C}),
            SiteBody("rod", C, q3, {"C": C, "D": D}),
            SiteBody("block", A, q2, {"A": A}),
            SiteBody("ram", D, zero, {"D": D}),
        ],
        joints=[
            SiteJoint("O", q1, "rad", "crank on the ground at O: the crank angle q1 from +x"),
            SiteJoint("B", q2, "rad", "rocker on the ground at B: the rocker angle q2 from +x"),
            SiteJoint("A", q2 - q1, "rad", "slider block on the crank pin A: block angle minus crank angle"),
            SiteJoint("slide", (A[0] - B[0]) * sp.cos(q2) + (A[1] - B[1]) * sp.sin(q2), "m",
                      "slider block along the rocker: distance |BA| from B"),
            SiteJoint("C", q3 - q2, "rad", "rod on the rocker at C: rod angle minus rocker angle"),
            SiteJoint("D", -q3, "rad", "ram on the rod at D: ram angle (0) minus rod angle"),
            SiteJoint("ram", D[0], "m", "ram on its guide: x_D, positive along +x"),
        ],
    )
    return MechanismDefinition(
        name="quick_return",
        description="quick-return (shaper) mechanism: crank, rocker, rod, slider block, ram",
        coordinates=list(q),
        velocities=list(qd),
        coordinate_units=["rad", "rad", "rad"],
        parameters=list(PARAMETERS),
        kinetic_energy=T,
        potential_energy=V,
        constraints=constraints,
        loads=loads,
        observables=observables,
        drawing=drawing,
        default_independent={"q1": 3.0020},
        default_independent_velocities={"q1": 6.2832},
        # the paper's branch: rocker leaning left of A's side, cos q3 < 0
        default_guess={"q2": 2.0, "q3": 2.8},
        figures=list(FIGURES),
        sites=sites,
    )
