"""The joint-type registry is the single source of what a joint type is: a type registered
here, and nowhere else, is parsed, named, transformed, cut, counted and described."""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from csim.linkage import joints
from csim.linkage.describe import report
from csim.linkage.joints import (
    JOINT_TYPES,
    PARALLEL_AXES,
    CutEquation,
    CutGeometry,
    JointType,
    UnknownJointType,
    VariableSpec,
    register_joint_type,
)
from csim.linkage.model import build_linkage
from csim.linkage.transforms import euler_zxz, joint_transform, rot_z, translation

RNG = np.random.default_rng(11)

#: A planar pair (German "Ebene"): two translations in the plane, then a rotation about its
#: normal. Not one of the brief's types: it exists only in this record.
PLANAR_PAIR = JointType(
    "E", "planar pair",
    (VariableSpec("x_{J}", "m", "translation along x_ik"), VariableSpec("y_{J}", "m", "translation along y_ik"),
     VariableSpec("q_{J}", "rad", "rotation about z_ik")),
    lambda q: translation(q[0], q[1], 0) * rot_z(q[2]),
    lambda q, qd: qd[2] * sp.Matrix([0, 0, 1]),
    (CutEquation("z_ik . (r_jm - r_ik)", "force f_z along z_ik", "f_z",
                 lambda g: g.axis_ik(2).dot(g.d)),) + PARALLEL_AXES,
    cut_preference=4, planar_axis="normal", placement="origin anywhere in the plane, z normal to the plane")


@pytest.fixture
def planar_pair(monkeypatch):
    """E registered for one test only."""
    monkeypatch.setitem(JOINT_TYPES, "E", PLANAR_PAIR)
    return PLANAR_PAIR


def numeric(M, subs=None):
    return np.array(sp.Matrix(M).evalf(subs=subs or {}), dtype=float)


def test_a_registered_type_is_parsed_named_transformed_and_has_energy(planar_pair):
    """A free body on a planar pair: 3 joint variables named from the record's templates,
    the link transform from its transform, T from its angular velocity, planar DOF count."""
    mech = {"parameters": {"l": 0.1, "m": 2.0, "J": 0.01},
            "links": [{"link": 0, "joints": [["E", 0, "O"]]},
                      {"link": 1, "joints": [["E", ["l", 0, 0], "O"]], "mass": "m", "com": ["l", 0, 0],
                       "inertia": [0, 0, "J"]}],
            "couplings": [{"name": "J1", "couple": [0, 1, 1, 1]}],
            "gravity": [0, -9.81, 0]}
    lk = build_linkage(mech, {})
    assert lk.variable_names == ["x_J1", "y_J1", "q_J1"]
    assert [v.unit for v in lk.topology.variables] == ["m", "m", "rad"]
    assert lk.planar and lk.grubler == 3 and lk.dof == 3
    x, y, q = (v.symbol for v in lk.topology.variables)
    values = {x: 0.3, y: -0.2, q: 0.7}
    expected = np.array(translation(0.3, -0.2, 0) * rot_z(0.7), dtype=float) @ np.linalg.inv(
        np.array(translation(0.1, 0, 0), dtype=float))
    assert np.allclose(numeric(lk.frames.links[1], {**values, **lk.tables.values}), expected, atol=1e-14)
    # the centre of mass is the joint point: T = m/2 (xd^2 + yd^2) + J/2 qd^2
    xd, yd, qd = (v.velocity for v in lk.topology.variables)
    T = lk.definition.kinetic_energy.subs(lk.tables.values)
    assert sp.simplify(T - (xd ** 2 + yd ** 2) - sp.Rational(1, 200) * qd ** 2) == 0


def test_a_registered_type_is_cut_by_its_preference_with_its_equations(planar_pair):
    """A pendulum also joined to the ground by a planar pair: E (preference 4) is cut, its
    3 equations (the record's) vanish identically in the plane, its reactions are listed."""
    mech = {"parameters": {"l": 0.5},
            "links": [{"link": 0, "joints": [["R", 0, "A"], ["E", 0, "O"]]},
                      {"link": 1, "joints": [["R", 0, "A"], ["E", ["l", 0, 0], "O"]]}],
            "couplings": [[0, 1, 1, 1], {"name": "K", "couple": [0, 2, 1, 2]}],
            "drive": {1: "t"}}
    lk = build_linkage(mech, {})
    assert [c.type for c in lk.topology.cut_joints] == ["E"] and lk.variable_names == ["q1"]
    eqs = lk.reduction.equations
    assert [e.component for e in eqs] == ["z_ik . (r_jm - r_ik)", "y_ik . z_jm", "x_ik . z_jm"]
    assert all(e.status == "identically zero" for e in eqs)
    assert (lk.dof, lk.grubler, lk.planar) == (1, 1, True)
    data = report(lk)
    assert data["cut_joints"][0]["reactions"] == ["f_z", "m_x", "m_y"]
    assert [v["meaning"] for v in data["joint_variables"]] == ["rotation about z_ik"]
    # the preference is read from the record: below R's, the (undriven) revolute joint is cut instead
    JOINT_TYPES["E"] = dataclasses.replace(PLANAR_PAIR, cut_preference=-1)
    del mech["drive"]
    lk = build_linkage(mech, {})
    assert [c.type for c in lk.topology.cut_joints] == ["R"]
    assert lk.variable_names == ["x_K", "y_K", "q_K"] and len(lk.reduction.kept) == 2


def test_an_unregistered_type_is_rejected_listing_the_registered_ones(planar_pair):
    from csim.errors import CaseError

    mech = {"links": [{"link": 0, "joints": ["H"]}, {"link": 1, "joints": ["H"]}], "couplings": [[0, 1, 1, 1]]}
    with pytest.raises(CaseError) as excinfo:
        build_linkage(mech, {})
    assert excinfo.value.problems == ["mechanism.links[0].joints[0]: joint type got 'H' (string); expected one of "
                                      "R, P, C, U, S, E",
                                      "mechanism.links[1].joints[0]: joint type got 'H' (string); expected one of "
                                      "R, P, C, U, S, E"]


def test_registry_lookup_and_registration_errors():
    with pytest.raises(UnknownJointType, match=r"unknown joint type 'H'; expected one of R, P, C, U, S$"):
        JOINT_TYPES["H"]
    with pytest.raises(ValueError, match="expected one of R, P, C, U, S"):
        joint_transform("H", [sp.Symbol("q")])
    with pytest.raises(ValueError, match="'R' is already registered"):
        register_joint_type(JOINT_TYPES["R"])
    with pytest.raises(ValueError, match="expected distinct names"):
        dataclasses.replace(PLANAR_PAIR, variables=(VariableSpec("x", "m", "no {J} in the name"),))
    with pytest.raises(ValueError, match="planar_axis 'tilted'"):
        dataclasses.replace(PLANAR_PAIR, planar_axis="tilted")


def _skew_rate(kind: JointType, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """Angular velocity from the transform alone: omega~ = dA/dt A^T (frame ik axes)."""
    syms = sp.symbols(f"a0:{kind.freedoms}", real=True)
    A = kind.transform(list(syms))[:3, :3]
    subs = dict(zip(syms, q))
    Adot = sum((numeric(A.diff(s), subs) * rate for s, rate in zip(syms, qd)), np.zeros((3, 3)))
    W = Adot @ numeric(A, subs).T
    return np.array([W[2, 1], W[0, 2], W[1, 0]])


@pytest.mark.parametrize("name", sorted(JOINT_TYPES) + ["E"])
def test_every_record_is_consistent(name, planar_pair):
    """Within each record: the angular velocity is that of the transform, and the cut
    equations hold when frame jm is frame ik moved by the joint's own transform."""
    kind = JOINT_TYPES[name]
    q, qd = RNG.uniform(-1, 1, kind.freedoms), RNG.uniform(-2, 2, kind.freedoms)
    w = numeric(kind.angular_velocity([sp.Float(x) for x in q], [sp.Float(x) for x in qd]))[:, 0]
    assert np.allclose(w, _skew_rate(kind, q, qd), atol=1e-12)
    a = RNG.uniform(-np.pi, np.pi, 3)
    T_ik = numeric(euler_zxz(*(sp.Float(x) for x in a)))
    T_ik[:3, 3] = RNG.uniform(-1, 1, 3)
    T_jm = T_ik @ numeric(kind.transform([sp.Float(x) for x in q]))
    g = CutGeometry.from_transforms(sp.Matrix(T_ik), sp.Matrix(T_jm))
    assert max(abs(float(e.expression(g))) for e in kind.cut_equations) < 1e-13
    assert len(kind.reactions) == len(kind.cut_equations)


def test_no_other_linkage_module_keeps_a_table_of_joint_types():
    """Every per-type fact is read from the registry: outside joints.py, no module of
    csim/linkage compares with or keys by a joint-type letter."""
    folder = Path(joints.__file__).parent
    letter = r"""["'][RPCUS]["']"""
    pattern = re.compile(rf"{letter}\s*:|(==|!=|\bin)\s*\(?\s*{letter}|\(\s*{letter}\s*,")
    for path in sorted(folder.glob("*.py")):
        if path.name == "joints.py":
            continue
        hits = [line.strip() for line in path.read_text().splitlines() if pattern.search(line)]
        assert hits == [], f"{path.name} keeps per-type facts: {hits}"


@pytest.mark.parametrize("name", ["R", "P", "C", "U", "S"])
def test_measure_inverts_the_joint_transform_at_any_pose(name):
    """Frame jm placed by the joint's own transform, T_jm = T_ik T(q), at random poses of
    frame ik: the variables measured from the two frames are q (S: its second angle in (0, pi))."""
    kind = JOINT_TYPES[name]
    rng = np.random.default_rng(11)
    for _ in range(6):
        pose = [sp.Float(x) for x in rng.uniform(-np.pi, np.pi, 3)]
        T_ik = translation(*[sp.Float(x) for x in rng.uniform(-1, 1, 3)]) * euler_zxz(*pose)
        q = [rng.uniform(0.1, np.pi - 0.1) if name == "S" and n == 1 else
             rng.uniform(-1, 1) if v.unit == "m" else rng.uniform(-np.pi, np.pi) for n, v in enumerate(kind.variables)]
        T_jm = T_ik * kind.transform([sp.Float(x) for x in q])
        measured = kind.measure(CutGeometry.from_transforms(T_ik, T_jm), lambda e: e)
        np.testing.assert_allclose([float(x) for x in measured], q, rtol=0, atol=1e-12)
