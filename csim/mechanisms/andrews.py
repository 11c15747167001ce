"""Andrews' squeezing mechanism: the seven-body planar benchmark of multibody codes.

Hairer and Wanner, *Solving Ordinary Differential Equations II*, Sec. VII.7 (after
Giles and Manning, and Schiehlen's benchmark collection); the "andrews" problem of the
IVP test set of Mazzia and Magherini, whose data and reference solution at t = 0.03 s
are used here. Planar, 1 DOF, gravity neglected.

Seven bodies, seven angle coordinates q = [beta, Theta, gamma, Phi, delta, Omega,
epsilon] [rad] and six holonomic constraints (two closed loops through the common joint
E, written as x and y closure of each):

* body 1, the crank: pivot O at the origin, absolute angle beta, crank pin F at distance
  rr, driven by the constant torque ``mom``;
* body 2, the rod F-E: relative angle Theta at F, absolute angle beta + Theta, E at
  distance d from F, centre of mass at da;
* body 3, the triangle B-E-D: pivot B, angle gamma; in its frame E = (0, -ss), the
  spring point D = (sd, -sc), the centre of mass (sb, -sa);
* body 5, the link A-G: pivot A, angle delta, G = (zt, 0), centre of mass (ta, tb);
* body 4, the link G-E: relative angle Phi at G, absolute angle Phi + delta,
  E = G + e (sin, -cos)(Phi + delta), centre of mass at distance e - ea from G;
* body 7, the link A-H: pivot A, angle epsilon, H = u (sin, -cos)(epsilon), centre of
  mass (-ua, -ub);
* body 6, the link H-E: relative angle Omega at H, absolute angle Omega + epsilon,
  E = H + zf (cos, sin)(Omega + epsilon), centre of mass at distance zf - fa from H.

The spring (stiffness c0, natural length l0) acts between D on body 3 and the fixed
point C. Only T, V, Phi(q) and the torque's coordinate are written here; csim derives
M, C qd, Phi_q, gamma and the generalized forces (the test set's hand-written M, its
force vector and its constraint Jacobian follow from these by differentiation, which
``tests/test_andrews.py`` checks). The directions of the centre-of-mass offsets of bodies
3, 5 and 7 in their frames (after Schiehlen's figure) do not enter T, which depends on
the distances only, nor V, since gravity is neglected.
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

# The test set's data (IVP test set, problem "andrews"; Hairer and Wanner, Table VII.7.1).
PARAMETERS = [
    Parameter("m1", 0.04325, "kg", "crank mass", strictly_positive=True),
    Parameter("m2", 0.00365, "kg", "rod F-E mass", strictly_positive=True),
    Parameter("m3", 0.02373, "kg", "triangle B-E-D mass", strictly_positive=True),
    Parameter("m4", 0.00706, "kg", "link G-E mass", strictly_positive=True),
    Parameter("m5", 0.07050, "kg", "link A-G mass", strictly_positive=True),
    Parameter("m6", 0.00706, "kg", "link H-E mass", strictly_positive=True),
    Parameter("m7", 0.05498, "kg", "link A-H mass", strictly_positive=True),
    Parameter("I1", 2.194e-6, "kg m^2", "crank inertia about its centre of mass", strictly_positive=True),
    Parameter("I2", 4.410e-7, "kg m^2", "rod F-E inertia about its centre of mass", strictly_positive=True),
    Parameter("I3", 5.255e-6, "kg m^2", "triangle B-E-D inertia about its centre of mass", strictly_positive=True),
    Parameter("I4", 5.667e-7, "kg m^2", "link G-E inertia about its centre of mass", strictly_positive=True),
    Parameter("I5", 1.169e-5, "kg m^2", "link A-G inertia about its centre of mass", strictly_positive=True),
    Parameter("I6", 5.667e-7, "kg m^2", "link H-E inertia about its centre of mass", strictly_positive=True),
    Parameter("I7", 1.912e-5, "kg m^2", "link A-H inertia about its centre of mass", strictly_positive=True),
    Parameter("xa", -0.06934, "m", "fixed pivot A, x"),
    Parameter("ya", -0.00227, "m", "fixed pivot A, y"),
    Parameter("xb", -0.03635, "m", "fixed pivot B, x"),
    Parameter("yb", 0.03273, "m", "fixed pivot B, y"),
    Parameter("xc", 0.014, "m", "fixed spring anchor C, x"),
    Parameter("yc", 0.072, "m", "fixed spring anchor C, y"),
    Parameter("rr", 0.007, "m", "crank length O-F", strictly_positive=True),
    Parameter("ra", 0.00092, "m", "crank centre of mass from O", minimum=0.0),
    Parameter("d", 0.028, "m", "rod length F-E", strictly_positive=True),
    Parameter("da", 0.0115, "m", "rod centre of mass from F", minimum=0.0),
    Parameter("ss", 0.035, "m", "triangle side B-E", strictly_positive=True),
    Parameter("sa", 0.01874, "m", "triangle centre of mass, offset along B-E", minimum=0.0),
    Parameter("sb", 0.01043, "m", "triangle centre of mass, offset across B-E", minimum=0.0),
    Parameter("sc", 0.018, "m", "spring point D of the triangle, offset along B-E", minimum=0.0),
    Parameter("sd", 0.02, "m", "spring point D of the triangle, offset across B-E", minimum=0.0),
    Parameter("e", 0.02, "m", "link length G-E", strictly_positive=True),
    Parameter("ea", 0.01421, "m", "link G-E centre of mass from E", minimum=0.0),
    Parameter("zt", 0.04, "m", "link length A-G", strictly_positive=True),
    Parameter("ta", 0.02308, "m", "link A-G centre of mass, along A-G", minimum=0.0),
    Parameter("tb", 0.00916, "m", "link A-G centre of mass, across A-G", minimum=0.0),
    Parameter("zf", 0.02, "m", "link length H-E", strictly_positive=True),
    Parameter("fa", 0.01421, "m", "link H-E centre of mass from E", minimum=0.0),
    Parameter("u", 0.04, "m", "link length A-H", strictly_positive=True),
    Parameter("ua", 0.01228, "m", "link A-H centre of mass, across A-H", minimum=0.0),
    Parameter("ub", 0.00449, "m", "link A-H centre of mass, along A-H", minimum=0.0),
    Parameter("c0", 4530.0, "N/m", "spring stiffness", minimum=0.0),
    Parameter("l0", 0.07785, "m", "spring natural length", minimum=0.0),
]

#: the test set's consistent initial positions [rad] (at rest); beta is the independent one
Q0 = {
    "beta": -0.0617138900142764496358948458001,
    "Theta": 0.0,
    "gamma": 0.455279819163070380255912382449,
    "Phi": 0.222668390165885884674473185609,
    "delta": 0.487364979543842550225598953530,
    "Omega": -0.222668390165885884674473185609,
    "epsilon": 1.23054744454982119249735015568,
}

#: driving torque of the benchmark [N m] (a case's ``loads.torque``; csim's load default is 0)
TORQUE = 0.033


def _rotate(angle, x, y):
    """The body-frame vector (x, y) turned by ``angle``: R(angle) (x, y)."""
    c, s = sp.cos(angle), sp.sin(angle)
    return (c * x - s * y, s * x + c * y)


def _add(p, v):
    return (p[0] + v[0], p[1] + v[1])


#: the mechanism's own figures (csim plot)
FIGURES = (
    DeclaredFigure("crank", "Crank angle and speed", reference="Hairer and Wanner, Fig. VII.7.2",
                   panels=(Panel(("q:beta",), ylabel=r"crank angle $\beta$"),
                           Panel(("qd:beta",), ylabel=r"crank speed $\dot\beta$"))),
    DeclaredFigure("configurations", "The mechanism during the run", snapshots=6, cycle="beta"),
)


def definition() -> MechanismDefinition:
    """Build the symbolic Andrews squeezing mechanism."""
    names = list(Q0)
    q = sp.symbols(" ".join(names), real=True)
    qd = sp.symbols(" ".join(f"{n}_dot" for n in names), real=True)
    beta, Theta, gamma, Phi, delta, Omega, epsilon = q
    P = {p.name: p.symbol for p in PARAMETERS}

    O = (sp.Integer(0), sp.Integer(0))
    A, B, C = (P["xa"], P["ya"]), (P["xb"], P["yb"]), (P["xc"], P["yc"])
    F = _rotate(beta, P["rr"], 0)  # crank pin
    E2 = _add(F, _rotate(beta + Theta, -P["d"], 0))  # E reached through the crank and rod
    E3 = _add(B, _rotate(gamma, 0, -P["ss"]))  # E on the triangle
    D = _add(B, _rotate(gamma, P["sd"], -P["sc"]))  # spring point of the triangle
    G = _add(A, _rotate(delta, P["zt"], 0))
    E4 = _add(G, _rotate(Phi + delta, 0, -P["e"]))  # E reached through A-G-E
    H = _add(A, _rotate(epsilon, 0, -P["u"]))
    E6 = _add(H, _rotate(Omega + epsilon, P["zf"], 0))  # E reached through A-H-E

    bodies = [
        PlanarBody("crank", P["m1"], P["I1"], _rotate(beta, P["ra"], 0), beta),
        PlanarBody("rod", P["m2"], P["I2"], _add(F, _rotate(beta + Theta, -P["da"], 0)), beta + Theta),
        PlanarBody("triangle", P["m3"], P["I3"], _add(B, _rotate(gamma, P["sb"], -P["sa"])), gamma),
        PlanarBody("link_GE", P["m4"], P["I4"], _add(G, _rotate(Phi + delta, 0, P["ea"] - P["e"])), Phi + delta),
        PlanarBody("link_AG", P["m5"], P["I5"], _add(A, _rotate(delta, P["ta"], P["tb"])), delta),
        PlanarBody("link_HE", P["m6"], P["I6"], _add(H, _rotate(Omega + epsilon, P["zf"] - P["fa"], 0)),
                   Omega + epsilon),
        PlanarBody("link_AH", P["m7"], P["I7"], _add(A, _rotate(epsilon, -P["ua"], -P["ub"])), epsilon),
    ]
    T = sum(b.kinetic_energy(list(q), list(qd)) for b in bodies)
    # spring between D and C: V = 1/2 c0 (l - l0)^2 with l = |D - C|; gravity neglected. l by the
    # law of cosines in the triangle B-C-D, whose sides |BC| and |BD| are fixed and whose angle
    # at B is gamma + (direction of (sd, -sc) in body 3) - (direction of C - B):
    #   l^2 = |BC|^2 + |BD|^2 - 2 |BC| |BD| cos(gamma - psi)
    # (the same function as |D - C|^2; its derivative simplifies in a quarter of the time)
    bc = sp.sqrt((C[0] - B[0]) ** 2 + (C[1] - B[1]) ** 2)
    bd = sp.sqrt(P["sd"] ** 2 + P["sc"] ** 2)
    psi = sp.atan2(C[1] - B[1], C[0] - B[0]) - sp.atan2(-P["sc"], P["sd"])
    spring_length = sp.sqrt(bc**2 + bd**2 - 2 * bc * bd * sp.cos(gamma - psi))
    V = sp.Rational(1, 2) * P["c0"] * (spring_length - P["l0"]) ** 2

    # E is one point: reached through the rod it coincides with E on the triangle (loop
    # O-F-E-B), on the link G-E (loop O-F-E-G-A) and on the link H-E (loop O-F-E-H-A)
    constraints = [
        E2[0] - E3[0], E2[1] - E3[1],
        E2[0] - E4[0], E2[1] - E4[1],
        E2[0] - E6[0], E2[1] - E6[1],
    ]
    loads = [Load("torque", beta, "N m", "rad", "driving torque on the crank, counter-clockwise positive")]
    observables = [Observable("spring_length", spring_length, "m", "m/s", "spring length |D - C|")]
    drawing = Drawing(
        points={"O": O, "F": F, "E": E2, "B": B, "D": D, "A": A, "G": G, "H": H, "C": C},
        links=[("O", "F"), ("F", "E"), ("B", "E", "D"), ("A", "G"), ("G", "E"), ("A", "H"), ("H", "E"),
               ("D", "C")],
        ground=["O", "A", "B", "C"],
    )
    # where force elements (mechanism.forces) may act: each body's frame as in its PlanarBody
    sites = Sites(
        bodies=[
            SiteBody("ground", O, sp.Integer(0), {"O": O, "A": A, "B": B, "C": C}),
            SiteBody("crank", O, beta, {"O": O, "F": F}),
            SiteBody("rod", F, beta + Theta, {"F": F, "E": E2}),
            SiteBody("triangle", B, gamma, {"B": B, "E": E3, "D": D}),
            SiteBody("link_GE", G, Phi + delta, {"G": G, "E": E4}),
            SiteBody("link_AG", A, delta, {"A": A, "G": G}),
            SiteBody("link_HE", H, Omega + epsilon, {"H": H, "E": E6}),
            SiteBody("link_AH", A, epsilon, {"A": A, "H": H}),
        ],
        joints=[
            SiteJoint("O", beta, "rad", "crank on the ground: beta"),
            SiteJoint("F", Theta, "rad", "rod on the crank: Theta"),
            SiteJoint("B", gamma, "rad", "triangle on the ground: gamma"),
            SiteJoint("A_G", delta, "rad", "link A-G on the ground: delta"),
            SiteJoint("G", Phi, "rad", "link G-E on the link A-G: Phi"),
            SiteJoint("A_H", epsilon, "rad", "link A-H on the ground: epsilon"),
            SiteJoint("H", Omega, "rad", "link H-E on the link A-H: Omega"),
        ],
    )
    return MechanismDefinition(
        name="andrews",
        description="Andrews' squeezing mechanism: seven bodies, two closed loops, spring, driving torque",
        coordinates=list(q),
        velocities=list(qd),
        coordinate_units=["rad"] * 7,
        parameters=list(PARAMETERS),
        kinetic_energy=T,
        potential_energy=V,
        constraints=constraints,
        loads=loads,
        observables=observables,
        drawing=drawing,
        default_independent={"beta": Q0["beta"]},
        default_independent_velocities={"beta": 0.0},
        # the test set's assembly (its branch of each loop)
        default_guess={name: value for name, value in Q0.items() if name != "beta"},
        figures=list(FIGURES),
        sites=sites,
    )
