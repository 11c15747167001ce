"""Link-coupling case documents of any size, for the scaling table (bench/scaling.py) and its test.

Two families, both planar with R joints only, every moving link a uniform bar (mass, centre
of mass at mid-length, inertia m L^2 / 12) under gravity, released at rest:

* :func:`fourbar_chain` (N): a chain of N four-bar loops. Loop 1 is the four-bar of
  configs/fourbar.yaml (crank a = 0.1, coupler b = 0.35, rocker c = 0.3, ground d = 0.4).
  Loop i + 1 shares the rocker of loop i: that rocker carries, at a from its pivot, the
  crank point of the next coupler, whose rocker pivots on the ground d further on. Every
  added loop is a dyad (2 links, 3 R joints), so the chain has 1 DOF for any N, 2N + 1
  links besides the ground, 2N + 1 joint variables and 2N independent constraints.
* :func:`nbar_loop` (N): one closed planar loop of N links, the ground included (N R joints),
  the vertices of an irregular convex polygon: N - 1 joint variables, 2 independent
  constraints, N - 3 DOF.

The couplings are listed so that the spanning tree (Kruskal in table order,
csim.linkage.topology) cuts the last coupling of each loop; the joint variables are then the
relative angles q_J = (angle of the child link) - (angle of its parent), and the initial
guesses below are computed from the geometry, on the branch drawn.
"""
from __future__ import annotations

import math


def _bar(name: str, length: float, mass: float, joints: list, link: int) -> dict:
    return {"link": link, "name": name, "joints": joints, "mass": mass, "com": [length / 2, 0, 0],
            "inertia": mass * length ** 2 / 12}


def _case(label: str, links: list, couplings: list, q: dict, guess: dict) -> dict:
    return {
        "mechanism": {"label": label, "gravity": [0, -9.81, 0], "links": links, "couplings": couplings},
        "initial": {"q": q, "qd": {name: 0.0 for name in q}, "guess": guess},
        "simulation": {"t_end": 0.1, "rtol": 1e-8, "atol": 1e-8},
        "output": {"dt": 0.01},
    }


def _circles(p, r1, c, r2):
    """The upper intersection (left of p -> c) of the circles (p, r1) and (c, r2)."""
    dx, dy = c[0] - p[0], c[1] - p[1]
    dist = math.hypot(dx, dy)
    along = (r1 ** 2 - r2 ** 2 + dist ** 2) / (2 * dist)
    h = math.sqrt(r1 ** 2 - along ** 2)
    ux, uy = dx / dist, dy / dist
    return p[0] + along * ux - h * uy, p[1] + along * uy + h * ux


def fourbar_chain(n: int, a: float = 0.1, b: float = 0.35, c: float = 0.3, d: float = 0.4,
                  mass: float = 0.5) -> dict:
    """A chain of ``n`` four-bar loops (1 DOF, 2n + 1 joint variables): see the module docstring."""
    links = [{"link": 0, "name": "ground", "joints": [["R", [i * d, 0, 0], f"P{i}"] for i in range(n + 1)]}]
    links.append(_bar("crank", a, mass, [["R", 0, "P0"], ["R", [a, 0, 0], "E1"]], 1))
    couplings = [{"name": "crank", "couple": ["ground", "P0", "crank", "P0"]}]
    guess = {}
    driver, angle, pivot = "crank", 0.0, (0.0, 0.0)  # the input link of the next loop, its angle and pivot
    for i in range(1, n + 1):
        rocker_joints = [["R", 0, f"P{i}"], ["R", [c, 0, 0], f"C{i}"]]
        if i < n:
            rocker_joints.append(["R", [a, 0, 0], f"E{i + 1}"])
        links.append(_bar(f"coupler{i}", b, mass, [["R", 0, f"E{i}"], ["R", [b, 0, 0], f"C{i}"]], len(links)))
        links.append(_bar(f"rocker{i}", c, mass, rocker_joints, len(links)))
        couplings += [{"name": f"E{i}", "couple": [driver, f"E{i}", f"coupler{i}", f"E{i}"]},
                      {"name": f"P{i}", "couple": ["ground", f"P{i}", f"rocker{i}", f"P{i}"]},
                      {"name": f"C{i}", "couple": [f"coupler{i}", f"C{i}", f"rocker{i}", f"C{i}"]}]
        e = (pivot[0] + a * math.cos(angle), pivot[1] + a * math.sin(angle))
        p = (i * d, 0.0)
        point = _circles(e, b, p, c)  # the branch of configs/fourbar.yaml (C above the ground line)
        coupler = math.atan2(point[1] - e[1], point[0] - e[0])
        rocker = math.atan2(point[1] - p[1], point[0] - p[0])
        guess[f"q_E{i}"] = coupler - angle
        guess[f"q_P{i}"] = rocker
        driver, angle, pivot = f"rocker{i}", rocker, p
    return _case(f"fourbar_chain_{n}", links, couplings, {"q_crank": 0.0}, guess)


def nbar_loop(n: int, radius: float = 0.2, mass: float = 0.5) -> dict:
    """One closed loop of ``n`` links, the ground included (n - 3 DOF): see the module docstring."""
    if n < 4:
        raise ValueError(f"an n-bar loop that moves needs n >= 4, got {n}")
    # an irregular convex polygon, the ground edge V[n-1] -> V[0] at the bottom, traversed clockwise
    theta0 = -math.pi / 2 - math.pi / n
    pts = [(radius * (1 + 0.1 * math.cos(2.3 * k)) * math.cos(theta0 - 2 * math.pi * k / n),
            radius * (1 + 0.1 * math.cos(2.3 * k)) * math.sin(theta0 - 2 * math.pi * k / n)) for k in range(n)]
    pts = [(x - pts[0][0], y - pts[0][1]) for x, y in pts]
    ground = [["R", 0, "J0"], ["R", [pts[n - 1][0], pts[n - 1][1], 0], f"J{n - 1}"]]
    links = [{"link": 0, "name": "ground", "joints": ground}]
    angles = []
    for i in range(1, n):
        (x0, y0), (x1, y1) = pts[i - 1], pts[i]
        length = math.hypot(x1 - x0, y1 - y0)
        angles.append(math.atan2(y1 - y0, x1 - x0))
        links.append(_bar(f"bar{i}", length, mass, [["R", 0, f"J{i - 1}"], ["R", [length, 0, 0], f"J{i}"]], i))
    couplings = [{"name": "J0", "couple": ["ground", "J0", "bar1", "J0"]}]
    couplings += [{"name": f"J{i}", "couple": [f"bar{i}", f"J{i}", f"bar{i + 1}", f"J{i}"]} for i in range(1, n - 1)]
    couplings.append({"name": f"J{n - 1}", "couple": ["ground", f"J{n - 1}", f"bar{n - 1}", f"J{n - 1}"]})  # cut
    relative = {"q_J0": angles[0], **{f"q_J{i}": angles[i] - angles[i - 1] for i in range(1, n - 1)}}
    names = list(relative)
    q = {name: relative[name] for name in names[:n - 3]}
    guess = {name: relative[name] for name in names[n - 3:]}
    return _case(f"nbar_loop_{n}", links, couplings, q, guess)
