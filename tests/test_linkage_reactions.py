"""Cut-joint reactions (csim.linkage.reactions) against statics and Newton-Euler solved by hand.

The four-bar of configs/fourbar_gravity.yaml: crank AB (link 1), coupler BC (link 2),
rocker DC (link 3), ground pivots A = (0, 0) and D = (d, 0). Absolute link angles t1 =
q_crank, t2 = q_crank + q_B, t3 = q_rocker; each centre of mass halfway along its link.
The reference equations below are written from free-body diagrams, not from csim.
"""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from csim.case import load_case, validate_case
from csim.io.hdf5 import read_result, write_result
from csim.pipeline import run_case

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "fourbar_gravity.yaml"
G = np.array([0.0, -9.81])


def _e(angle):
    return np.array([np.cos(angle), np.sin(angle)])


def _cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def _case(**changes) -> dict:
    data = yaml.safe_load(CONFIG.read_text())
    data = copy.deepcopy(data)
    data["simulation"]["backend"] = "python"  # a first compiled run of each variant would compile for a minute
    for key, value in changes.items():
        section, name = key.split("__")
        data.setdefault(section, {})[name] = value
    return data


def _points(p, t1, t2, t3):
    """A, B, C (from the coupler), D and the centres G1, G2, G3 [m], each (2,)."""
    A, D = np.zeros(2), np.array([p["d"], 0.0])
    B = p["a"] * _e(t1)
    C = B + p["b"] * _e(t2)
    return dict(A=A, B=B, C=C, D=D, G1=B / 2, G2=B + p["b"] / 2 * _e(t2), G3=D + p["c"] / 2 * _e(t3))


def _static_solution(p, t1, t2, t3):
    """F, the force of the coupler on the rocker at C, and the crank torque tau that hold the
    four-bar at rest under gravity.

    Rocker, moments about D: (C - D) x F + (G3 - D) x m3 g = 0.
    Coupler (forces F_B from the crank at B, -F at C, m2 g), moments about B:
    (C - B) x (-F) + (G2 - B) x m2 g = 0. Two linear equations in F = (Fx, Fy).
    Coupler forces: F_B = F - m2 g. Crank, moments about A: tau - (B - A) x F_B + (G1 - A) x m1 g = 0.
    """
    P = _points(p, t1, t2, t3)
    rD, rB = P["C"] - P["D"], P["C"] - P["B"]
    # a x F = a_x F_y - a_y F_x
    K = np.array([[-rD[1], rD[0]], [rB[1], -rB[0]]])
    rhs = np.array([-_cross(P["G3"] - P["D"], p["m3"] * G), -_cross(P["G2"] - P["B"], p["m2"] * G)])
    F = np.linalg.solve(K, rhs)
    F_B = F - p["m2"] * G
    tau = _cross(P["B"] - P["A"], F_B) - _cross(P["G1"] - P["A"], p["m1"] * G)
    return F, tau


def test_cut_pin_reaction_of_a_four_bar_at_rest_against_hand_statics():
    """Held at rest by gravity and the crank torque of the hand statics, the reaction at the
    cut pin C (coupler on rocker) is the statics' force, in global and joint-frame axes."""
    q0 = 0.7
    first = validate_case(_case(initial__q={"q_crank": q0}))
    p = first.parameters
    start = first.linkage.start
    t1, t2, t3 = start["q_crank"], start["q_crank"] + start["q_B"], start["q_rocker"]
    P = _points(p, t1, t2, t3)
    assert np.allclose(P["C"], P["D"] + p["c"] * _e(t3), atol=1e-12)  # the loop closes
    F, tau = _static_solution(p, t1, t2, t3)
    data = _case(initial__q={"q_crank": q0}, simulation__t_end=0.2)
    data["mechanism"]["forces"] = [{"name": "motor", "type": "actuator", "joint": "crank", "torque": float(tau)}]
    result = run_case(validate_case(data))
    assert result.ok, result.message
    assert np.max(np.abs(result.qdd[0])) < 1e-9                # static: the torque holds it
    assert np.max(np.abs(result.q - result.q[0])) < 1e-9       # and it stays at rest
    assert [r.name for r in result.reactions] == ["C", "crank", "B", "rocker"]  # the cut joint, then the tree's
    reaction = result.reactions[0]
    scale = np.linalg.norm(F)
    assert np.allclose(reaction.force_global[:, :2], F, atol=1e-8 * scale, rtol=0)
    assert np.allclose(reaction.force_global[:, 2], 0.0) and np.allclose(reaction.torque_global, 0.0)
    # frame ik is the coupler's frame at C: turned by t2 about z
    c, s = np.cos(t2), np.sin(t2)
    local = np.array([c * F[0] + s * F[1], -s * F[0] + c * F[1]])
    assert np.allclose(reaction.force_joint[0, :2], local, atol=1e-8 * scale, rtol=0)
    # the planar model carries no f_z, m_x, m_y: named, not silently zero
    assert len(reaction.undetermined) == 3
    assert all("planar" in u for u in reaction.undetermined)
    # the tree joints, by Newton-Euler of the links beyond each: the hand statics' free bodies
    # crank: F_A - F_B + m1 g = 0 (F_B: crank on coupler = F - m2 g); rocker: F_D + F + m3 g = 0
    F_B = F - p["m2"] * G
    expected = {"crank": F_B - p["m1"] * G, "B": F_B, "rocker": -F - p["m3"] * G}
    for tree in result.reactions[1:]:
        assert "tree joint" in tree.label and tree.undetermined
        assert np.allclose(tree.force_global[:, :2], expected[tree.name], atol=1e-8 * scale, rtol=0), tree.name
        # the moment about the pin's axis is the joint's equation of motion (the motor's torque
        # at the crank is a force element, not a reaction): zero
        assert np.max(np.abs(tree.torque_global)) < 1e-9 * scale * p["b"], tree.name


def _accelerations(p, q, qd, qdd):
    """Coupler: acceleration of G2 (N, 2) [m/s^2] and angular acceleration (N,) [rad/s^2], from
    a four-bar run (coordinates q_crank, q_B, q_rocker) differentiated by hand."""
    t1, t2 = q[:, 0], q[:, 0] + q[:, 1]
    w1, w2 = qd[:, 0], qd[:, 0] + qd[:, 1]
    a1, a2 = qdd[:, 0], qdd[:, 0] + qdd[:, 1]

    def acc(length, t, w, a):  # d2/dt2 of length * e(t)
        return length * (a[:, None] * np.column_stack((-np.sin(t), np.cos(t)))
                         - (w ** 2)[:, None] * np.column_stack((np.cos(t), np.sin(t))))

    return acc(p["a"], t1, w1, a1) + acc(p["b"] / 2, t2, w2, a2), a2


def test_newton_euler_on_the_coupler_with_reactions_at_both_ends():
    """The coupler swinging under gravity: m2 a_G2 = F_B + (-F_C) + m2 g and
    I2 alpha2 = (B - G2) x F_B + (C - G2) x (-F_C), with F_C from a run that cuts C and F_B
    from a run of the same four-bar whose table order cuts B instead."""
    settings = {"t_end": 0.6, "rtol": 1e-11, "atol": 1e-11}
    cut_c = run_case(validate_case(_case(**{f"simulation__{k}": v for k, v in settings.items()})))
    assert cut_c.ok and [r.name for r in cut_c.reactions][0] == "C"
    data = _case(**{f"simulation__{k}": v for k, v in settings.items()})
    rows = data["mechanism"]["couplings"]
    data["mechanism"]["couplings"] = [rows[0], rows[2], rows[3], rows[1]]  # crank, rocker, C, then B: B is cut
    q = dict(zip(cut_c.coordinate_names, cut_c.q[0]))
    data["initial"]["guess"] = {"q_rocker": q["q_rocker"], "q_C": q["q_rocker"] - q["q_crank"] - q["q_B"]}
    cut_b = run_case(validate_case(data))
    assert cut_b.ok and [r.name for r in cut_b.reactions][0] == "B"
    assert np.array_equal(cut_b.t, cut_c.t)
    assert np.max(np.abs(cut_b.q[:, 0] - cut_c.q[:, 0])) < 1e-8   # the same motion
    p = validate_case(_case()).parameters
    F_C = cut_c.reactions[0].force_global[:, :2]                 # coupler on rocker
    F_B = cut_b.reactions[0].force_global[:, :2]                 # crank on coupler
    a_G2, alpha2 = _accelerations(p, cut_c.q, cut_c.qd, cut_c.qdd)
    m2, I2 = p["m2"], p["m2"] * p["b"] ** 2 / 12
    scale = np.max(np.abs(F_C))
    assert scale > 1.0 and np.ptp(alpha2) > 10.0                   # real forces, a real motion
    assert np.max(np.abs(F_B - F_C + m2 * G - m2 * a_G2)) < 1e-8 * scale   # measured 1.5e-10
    t1, t2 = cut_c.q[:, 0], cut_c.q[:, 0] + cut_c.q[:, 1]
    B = p["a"] * np.column_stack((np.cos(t1), np.sin(t1)))
    u2 = np.column_stack((np.cos(t2), np.sin(t2)))
    G2, C = B + p["b"] / 2 * u2, B + p["b"] * u2
    moments = _cross((B - G2).T, F_B.T) + _cross((C - G2).T, -F_C.T)
    assert np.max(np.abs(moments - I2 * alpha2)) < 1e-8 * scale * p["b"]   # measured 3.5e-11
    # each run's tree-joint reactions (Newton-Euler) against the other run's cut-joint ones (multipliers)
    tree_b = next(r for r in cut_c.reactions if r.name == "B")
    tree_c = next(r for r in cut_b.reactions if r.name == "C")
    assert np.max(np.abs(tree_b.force_global - cut_b.reactions[0].force_global)) < 1e-9 * scale  # measured 2.4e-9 N
    assert np.max(np.abs(tree_c.force_global - cut_c.reactions[0].force_global)) < 1e-9 * scale  # of 73 N


def test_reactions_round_trip_through_hdf5(tmp_path):
    result = run_case(validate_case(_case(simulation__t_end=0.05)))
    path = tmp_path / "fourbar.h5"
    write_result(path, result)
    back = read_result(path)
    assert [r.name for r in back.reactions] == [r.name for r in result.reactions] == ["C", "crank", "B", "rocker"]
    a, b = result.reactions[0], back.reactions[0]
    assert (b.name, b.label, b.undetermined) == (a.name, a.label, a.undetermined)
    for name in ("force_global", "force_joint", "torque_global", "torque_joint"):
        assert np.array_equal(getattr(a, name), getattr(b, name))
    import h5py

    with h5py.File(path) as fh:
        assert fh["reactions/C/force_global"].attrs["units"] == "N"
        assert fh["reactions/C/force_global"].attrs["description"].startswith("N, in the fixed frame")
        assert fh["reactions/C/torque_joint"].attrs["units"] == "N m"
        assert [fh["reactions/C/force_global"].dims[i][0].name for i in (0, 1)] == ["/t", "/axis"]
        assert fh["reactions/C/force_global"].shape == (result.t.size, 3)


@pytest.mark.parametrize("joint_type", ["R", "P", "C", "U", "S"])
def test_wrench_jacobian_is_the_derivative_of_the_cut_equations(joint_type):
    """dPhi/d(r_jm, theta_j) from sympy against central differences of the same equations at
    random frame poses (a check of the virtual-motion derivation, not of the equations)."""
    import sympy as sp

    from csim.linkage.joints import JOINT_TYPES, CutGeometry
    from csim.linkage.reactions import wrench_jacobian

    rng = np.random.default_rng(5)
    r_ik, r_jm = rng.normal(size=3), rng.normal(size=3)
    A_ik, A_jm = _rodrigues(rng.normal(size=3)), _rodrigues(rng.normal(size=3))
    J = wrench_jacobian(joint_type)(r_ik, A_ik, r_jm, A_jm)
    eqs = JOINT_TYPES[joint_type].cut_equations

    def phi(rj, Aj):
        g = CutGeometry(sp.Matrix(r_ik), sp.Matrix(rj), sp.Matrix(A_ik), sp.Matrix(Aj))
        return np.array([float(eq.expression(g)) for eq in eqs])

    h = 1e-6
    for axis in range(3):
        step = np.eye(3)[axis] * h
        d_r = (phi(r_jm + step, A_jm) - phi(r_jm - step, A_jm)) / (2 * h)
        d_t = (phi(r_jm, _rodrigues(step) @ A_jm) - phi(r_jm, _rodrigues(-step) @ A_jm)) / (2 * h)
        assert np.allclose(J[axis], d_r, atol=1e-8)
        assert np.allclose(J[3 + axis], d_t, atol=1e-8)


def _rodrigues(v):
    """The rotation matrix of the rotation vector v [rad], (3, 3)."""
    angle = np.linalg.norm(v)
    if angle == 0:
        return np.eye(3)
    k = v / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def test_tree_pin_of_a_pendulum_with_springs_and_damper_against_hand_newton():
    """A bar pinned at O (no cut joint), with a torsional spring-damper at O and a spring from
    its tip P to a fixed point: ground on bar F = m (a_G - g) - F_spring, a_G by hand from
    the recorded angle, rate and acceleration; the moment about the pin's axis (its equation
    of motion, the torsional spring's torque included) vanishes."""
    m, a, L, k, l0, anchor = 1.5, 0.4, 0.8, 20.0, 0.2, np.array([0.5, 0.3])
    mech = {"label": "pendulum", "parameters": {"m": m, "a": a, "L": L}, "gravity": [0, -9.81, 0],
            "links": [{"link": 0, "name": "ground", "joints": [["R", 0, "O"]]},
                      {"link": 1, "name": "bar", "joints": [["R", 0, "O"], ["R", ["L", 0, 0], "P"]], "mass": "m",
                       "com": ["a", 0, 0], "inertia": 0.02}],
            "couplings": [{"name": "O", "couple": ["ground", "O", "bar", "O"]}],
            "forces": [{"name": "tors", "type": "joint_spring", "joint": "O", "stiffness": 3.0, "free_angle": 0.2,
                        "damping": 0.1},
                       {"name": "pull", "type": "spring", "between": [["bar", "P"], ["ground", [0.5, 0.3, 0]]],
                        "stiffness": k, "free_length": l0}]}
    res = run_case(validate_case({"mechanism": mech, "initial": {"q": {"q_O": -1.0}, "qd": {"q_O": 0.0}},
                                  "simulation": {"t_end": 1.0, "rtol": 1e-11, "atol": 1e-11, "backend": "python"}}))
    assert res.ok, res.message
    (pin,) = res.reactions
    th, w, al = res.q[:, 0], res.qd[:, 0], res.qdd[:, 0]
    a_G = a * (al[:, None] * np.column_stack((-np.sin(th), np.cos(th)))
               - (w ** 2)[:, None] * np.column_stack((np.cos(th), np.sin(th))))
    d = anchor - L * np.column_stack((np.cos(th), np.sin(th)))
    length = np.linalg.norm(d, axis=1)
    F_spring = k * (length - l0)[:, None] * d / length[:, None]  # pulls P towards the anchor
    F = m * (a_G - G) - F_spring
    assert np.ptp(al) > 10.0
    assert np.max(np.abs(pin.force_global[:, :2] - F)) < 1e-10 * np.max(np.abs(F))  # measured 9e-15 N of 16 N
    assert np.max(np.abs(pin.torque_global)) < 1e-12 and np.all(pin.force_global[:, 2] == 0)


@pytest.mark.slow  # about 20 s: a spatial body with a full inertia tensor, derived and run on the Python path
def test_spherical_joint_of_a_spatial_body_against_newton_from_its_recorded_motion():
    """A body on a spherical joint (spatial, no cut joint): the joint's force is m (a_G - g),
    with a_G differentiated numerically from the recorded velocity of a point named at the
    centre of mass; a spherical joint carries no moment."""
    m = 2.0
    com = [0.1, 0.05, -0.3]
    mech = {"label": "top", "parameters": {"m": m}, "gravity": [0, 0, -9.81],
            "links": [{"link": 0, "name": "ground", "joints": [["S", 0, "O"]]},
                      {"link": 1, "name": "body", "joints": [["S", 0, "O"], ["R", com, "G"]], "mass": "m", "com": com,
                       "inertia": [[0.05, 0.001, 0], [0.001, 0.04, 0.002], [0, 0.002, 0.02]]}],
            "couplings": [{"name": "O", "couple": ["ground", "O", "body", "O"]}]}
    res = run_case(validate_case({
        "mechanism": mech, "output": {"dt": 1e-3},
        "initial": {"q": {"q_O_1": 0.3, "q_O_2": 0.8, "q_O_3": -0.2},
                    "qd": {"q_O_1": 1.0, "q_O_2": -0.5, "q_O_3": 2.0}},
        "simulation": {"t_end": 0.5, "rtol": 1e-12, "atol": 1e-12, "backend": "python"}}))
    assert res.ok, res.message
    (joint,) = res.reactions
    assert joint.undetermined == []  # spatial: every component
    v = np.column_stack([res.observable_rates[:, res.observable_names.index(f"G_{a}")] for a in "xyz"])
    a_G = np.gradient(v, res.t, axis=0, edge_order=2)
    F = m * (a_G - np.array([0, 0, -9.81]))
    assert np.max(np.abs(joint.force_global - F)[2:-2]) < 1e-4 * np.max(np.abs(F))  # finite differences: 8e-6
    assert np.max(np.abs(joint.torque_global)) < 1e-10
    assert np.allclose(joint.force_joint, joint.force_global)  # frame ik is the ground's


@pytest.mark.slow  # about 6 s: the tabled quick-return's model derived, 0.5 s on the Python path
def test_tree_joints_of_the_tabled_quick_return_carry_nothing_along_their_free_directions():
    """The tabled quick-return (an actuator on the crank pivot O, the switched cutting force on
    the ram, two cut slides): at every tree pin the moment about the pin's axis, which is the
    pin's equation of motion with the motor torque and the loads applied, vanishes to round-off."""
    case = load_case(CONFIG.parent / "quick_return_tables.yaml", ["simulation.backend=python", "simulation.t_end=0.5"])
    result = run_case(case)
    assert result.ok, result.message
    tree = {str(c.name or c.number) for c in case.linkage.topology.tree_joints}
    reactions = [r for r in result.reactions if r.name in tree]
    assert sorted(r.name for r in reactions) == ["A", "B", "C", "D", "O"]
    scale = max(np.max(np.abs(r.force_global)) for r in reactions)
    assert scale > 1e5  # the cutting force and the crank torque's reactions, N
    for r in reactions:
        assert np.max(np.abs(r.torque_joint[:, 2])) < 1e-11 * scale, r.name  # measured 1.5e-9 N m at O


def test_a_subtree_sum_leaves_out_the_links_outside_the_subtree():
    # a non-finite wrench outside a subtree (a cut joint's reaction not evaluated at a sample)
    # must not blank the joints whose subtrees do not hold it, as 0 * NaN in a matrix product would
    from csim.linkage.reactions import _subtree_sums

    wrenches = np.arange(18.0).reshape(3, 6)
    wrenches[2] = np.nan
    weights = np.array([[1.0, 1.0, 0.0], [0.0, -1.0, 0.0], [1.0, 0.0, 1.0]])
    sums = _subtree_sums(weights, wrenches)
    assert np.array_equal(sums[:2], [wrenches[0] + wrenches[1], -wrenches[1]])
    assert np.isnan(sums[2]).all()


def test_a_linkage_that_has_run_still_pickles():
    # the reactions keep their lambdified functions on the linkage (closures); a sweep's
    # process pool or the linkage cache pickles it after a run, and gets it back without them
    import pickle

    case = load_case(CONFIG.parent / "fourbar_gravity.yaml", ["simulation.t_end=0.05"])
    assert run_case(case).ok
    assert any(k.startswith("_reaction_") for k in vars(case.linkage))
    again = pickle.loads(pickle.dumps(case.linkage))
    assert not any(k.startswith("_reaction_") for k in vars(again))
    assert again.cache_key == case.linkage.cache_key and again.dof == case.linkage.dof


def test_reactions_in_blocks_of_samples_equal_those_at_once(monkeypatch):
    # the samples go through the lambdified functions a block at a time (memory: each
    # subexpression is an array of a block's samples); the block edges change no value
    import csim.linkage.reactions as reactions

    case = load_case(CONFIG.parent / "quick_return_tables.yaml", ["simulation.backend=python", "simulation.t_end=0.05"])
    whole = run_case(case)
    monkeypatch.setattr(reactions, "BLOCK", 3)
    blocks = run_case(load_case(CONFIG.parent / "quick_return_tables.yaml",
                                ["simulation.backend=python", "simulation.t_end=0.05"]))
    assert whole.t.size > 3 * 3 and [r.name for r in whole.reactions] == [r.name for r in blocks.reactions]
    for a, b in zip(whole.reactions, blocks.reactions):
        for name in ("force_global", "torque_global", "force_joint", "torque_joint"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"{a.name} {name}")


def test_the_plane_of_a_planar_mechanism_is_read_at_its_first_finite_sample():
    """A first sample of NaN (a failed start) blanked every tree joint's reaction of a planar mechanism: the
    plane's normal was read at sample 0 only. The plane does not move; any finite sample gives it."""
    import csim.linkage.reactions as reactions
    from csim.pipeline import build_system

    case = load_case(CONFIG.parent / "quick_return_tables.yaml", ["simulation.backend=python", "simulation.t_end=0.05"])
    q = run_case(case).q
    par = build_system(case).par
    normal = reactions._plane_normal(case.linkage, case.mechanism, par, q)
    first_nan = q.copy()
    first_nan[0] = np.nan
    assert normal is not None and np.isclose(np.linalg.norm(normal), 1.0)
    np.testing.assert_array_equal(reactions._plane_normal(case.linkage, case.mechanism, par, first_nan), normal)
    assert reactions._plane_normal(case.linkage, case.mechanism, par, np.full_like(q, np.nan)) is None
