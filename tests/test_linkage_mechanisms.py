"""Slider-crank, four-bar, spatial RSUR and Bricard's linkage, each against independent
geometry: closed-form positions or a separately coded loop equation."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from csim.case import load_case
from csim.describe import load_linkage
from csim.pipeline import run_case

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def params(name):
    return yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())["mechanism"]["parameters"]


def run(name, *overrides):
    case = load_case(CONFIGS / f"{name}.yaml", list(overrides))
    result = run_case(case)
    assert result.ok, result.message
    return case, result


def col(result, name):
    return result.q[:, result.coordinate_names.index(name)]


def test_slider_crank_against_closed_form():
    lk = load_linkage(CONFIGS / "slider_crank.yaml")
    assert [c.name for c in lk.topology.cut_joints] == ["C"] and lk.dof == 1 and lk.grubler == 1
    assert lk.variable_names == ["q_crank", "q_B", "s_slide"] and lk.planar
    _, res = run("slider_crank")
    p = params("slider_crank")
    th = col(res, "q_crank")
    x = p["r"] * np.cos(th) + np.sqrt(p["l"] ** 2 - (p["r"] * np.sin(th) - p["e"]) ** 2)
    assert np.abs(col(res, "s_slide") - x).max() < 1e-11  # Newton stops at max |Phi| <= 1e-12
    # slider velocity: d/dt of the closed form, by the chain rule
    dx = -p["r"] * np.sin(th) - (p["r"] * np.sin(th) - p["e"]) * p["r"] * np.cos(th) / (x - p["r"] * np.cos(th))
    assert np.abs(res.qd[:, 2] - dx * res.qd[:, 0]).max() < 1e-11


def test_four_bar_against_circle_intersection():
    _, res = run("fourbar")
    p = params("fourbar")
    th = col(res, "q_crank")
    B = np.stack([p["a"] * np.cos(th), p["a"] * np.sin(th)], axis=1)
    D = np.array([p["d"], 0.0])
    # C on both circles |C - B| = b, |C - D| = c, the branch above B->D
    v = D - B
    L = np.linalg.norm(v, axis=1)
    along = (p["b"] ** 2 - p["c"] ** 2 + L ** 2) / (2 * L)
    h = np.sqrt(p["b"] ** 2 - along ** 2)
    u = v / L[:, None]
    C = B + along[:, None] * u + h[:, None] * np.stack([-u[:, 1], u[:, 0]], axis=1)
    rocker = np.arctan2(C[:, 1], C[:, 0] - p["d"])
    err = np.angle(np.exp(1j * (col(res, "q_rocker") - rocker)))
    assert np.abs(err).max() < 1e-12
    assert res.observable_names == ["B_x", "B_y", "C_x", "C_y"]
    assert np.abs(res.observables[:, 2:] - C).max() < 1e-12


def test_rsur_against_closed_form_rocker_angle():
    lk = load_linkage(CONFIGS / "rsur_spatial.yaml")
    assert [c.type for c in lk.topology.cut_joints] == ["S"]  # S preferred for cutting
    assert lk.variable_names == ["q_A", "q_D", "q_C_1", "q_C_2"]
    assert (lk.dof, lk.grubler, lk.planar, len(lk.reduction.kept)) == (1, 1, False, 3)
    _, res = run("rsur_spatial")
    p = params("rsur_spatial")
    th, phi = col(res, "q_A"), col(res, "q_D")
    # |C(phi) - B(theta)| = b  ->  K1 cos phi + K2 sin phi = K3
    K1 = 2 * p["c"] * (p["dy"] - p["a"] * np.sin(th))
    K2 = 2 * p["c"] * p["dz"] * np.ones_like(th)
    K3 = p["b"] ** 2 - (p["dx"] - p["a"] * np.cos(th)) ** 2 - (p["dy"] - p["a"] * np.sin(th)) ** 2 - p["dz"] ** 2 \
        - p["c"] ** 2
    base, spread = np.arctan2(K2, K1), np.arccos(np.clip(K3 / np.hypot(K1, K2), -1, 1))
    roots = np.stack([base + spread, base - spread], axis=1)
    err = np.abs(np.angle(np.exp(1j * (phi[:, None] - roots))))
    branch = np.argmin(err[0])
    assert np.all(np.argmin(err, axis=1) == branch)
    assert err[:, branch].max() < 1e-9


def dh(a, alpha, d):
    c, s = np.cos(alpha), np.sin(alpha)
    return np.array([[1, 0, 0, a], [0, c, -s, 0], [0, s, c, d], [0, 0, 0, 1.0]])


def rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


@pytest.mark.slow
def test_bricard_is_overconstrained_and_moves_on_its_loop():
    """Grubler count 0, actual 1 DOF; one dependent equation removed; the driven motion
    closes a separately coded Denavit-Hartenberg loop."""
    lk = load_linkage(CONFIGS / "bricard.yaml")
    assert (lk.grubler, lk.dof, lk.reduction.generic_rank) == (0, 1, 4)
    assert [e.status for e in lk.reduction.equations].count("dependent") == 1
    _, res = run("bricard", "simulation.t_end=0.5", "output.dt=0.05")
    p = params("bricard")
    a = [p["a1"], p["a2"], p["a3"]] * 2
    d = [p["d1"], p["d2"], p["d3"]] * 2
    alpha = [0.6, 1.1, 1.4] * 2
    assert np.ptp(res.q[:, 0]) > 0.25  # it really moves (0.3 rad of q1)
    for q in res.q:
        M = dh(a[0], alpha[0], d[0])
        for k in range(5):
            M = M @ rz(q[k]) @ dh(a[k + 1], alpha[k + 1], d[k + 1])
        # closing the loop needs only a rotation about joint 6's axis: M = Rz(-theta6)
        assert np.abs(M[:3, 3]).max() < 1e-10 and abs(M[2, 2] - 1) < 1e-10


def test_spatial_mechanisms_are_drawn_in_3d_planar_ones_in_2d():
    """Drawing points: (x, y, z) for the spatial RSUR, (x, y) for the planar four-bar; the
    generated model.points give the joint positions of the analysis (the observables)."""
    from csim.pipeline import numeric_model

    rsur = load_case(CONFIGS / "rsur_spatial.yaml", ["simulation.t_end=0.3"])
    assert {len(p) for p in rsur.mechanism.drawing.points.values()} == {3}
    four = load_case(CONFIGS / "fourbar.yaml")
    assert {len(p) for p in four.mechanism.drawing.points.values()} == {2}
    res = run_case(rsur)
    model = numeric_model(rsur)
    par = model.parameter_vector(rsur.parameters)
    names = list(rsur.mechanism.drawing.points)
    for k in (0, len(res.t) // 2, -1):
        pts = model.points(res.q[k], par)
        assert pts.shape == (len(names), 3)
        # the moving coordinates of B and C are recorded as observables (B_x, B_y, C_y, C_z)
        for name in res.observable_names:
            point, axis = name.split("_")
            j = res.observable_names.index(name)
            assert pts[names.index(point), "xyz".index(axis)] == pytest.approx(res.observables[k, j], abs=1e-12)


def _six_bar_with_a_ternary_pin(shared: bool) -> dict:
    """The four-bar of fourbar_gravity.yaml with a bar hanging from the coupler-rocker pin C:
    one joint shared by three links, declared once (``shared``) or as two binary couplings
    with a second, coincident frame on the coupler."""
    import copy

    data = copy.deepcopy(yaml.safe_load((CONFIGS / "fourbar_gravity.yaml").read_text()))
    mech = data["mechanism"]
    mech["links"].append({"link": 4, "name": "bar", "joints": [["R", 0, "C"], ["R", [0.2, 0, 0], "E"]],
                          "mass": 0.4, "com": [0.1, 0, 0], "inertia": 0.4 * 0.04 / 12})
    if shared:
        mech["couplings"][3] = {"name": "C", "couple": [["coupler", "C"], ["rocker", "C"], ["bar", "C"]]}
    else:
        mech["links"][2]["joints"].append(["R", ["b", 0, 0], "C2"])
        mech["couplings"].append({"name": "C_2", "couple": ["coupler", "C2", "bar", "C"]})
    data["initial"]["q"]["q_C_2"], data["initial"]["qd"]["q_C_2"] = -1.0, 0.0
    data["simulation"]["t_end"] = 1.0
    return data


def test_a_joint_shared_by_three_links_is_declared_once():
    from csim.case import validate_case

    once = run_case(validate_case(_six_bar_with_a_ternary_pin(True)))
    twice = run_case(validate_case(_six_bar_with_a_ternary_pin(False)))
    assert once.ok and twice.ok and once.coordinate_names == twice.coordinate_names
    np.testing.assert_allclose(once.q, twice.q, rtol=0, atol=1e-12)
    # the bar stays pinned at C with its length, and gravity alone does no net work: T + V conserved
    obs = {name: once.observables[:, i] for i, name in enumerate(once.observable_names)}
    length = np.hypot(obs["E_x"] - obs["C_x"], obs["E_y"] - obs["C_y"])
    np.testing.assert_allclose(length, 0.2, rtol=0, atol=1e-9)
    assert once.backend == "compiled" and once.energy_error_relative < 1e-8 and np.ptp(obs["E_x"]) > 0.01


@pytest.mark.parametrize("couple, words", [
    ([["coupler", "C"], ["rocker", "C"], ["coupler", "B"]], "couples link 2 with itself"),
    ([["coupler", "C"], ["rocker", "C"], ["bar", "X"]], "has no joint 'X'"),
    ([["coupler", "C"], ["rocker", "C"], ["crank", "A"]], "already coupled"),
])
def test_bad_shared_joints_name_the_row(couple, words):
    from csim.case import validate_case
    from csim.errors import CaseError

    data = _six_bar_with_a_ternary_pin(True)
    data["mechanism"]["couplings"][3]["couple"] = couple
    with pytest.raises(CaseError) as info:
        validate_case(data)
    assert "mechanism.couplings[3]" in str(info.value) and words in str(info.value)
