"""The brief's planar 3-RRR robot: structure, transforms, equations, DOF, describe, run."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import yaml

from csim.describe import describe_main, load_linkage
from csim.linkage.describe import describe_case

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "rrr3_planar.yaml"


@pytest.fixture(scope="module")
def rrr3():
    return load_linkage(CONFIG)


def brief_equations(q, p):
    """The four equations of the brief, typed in from it."""
    q1, q2, q3, q4, q5, q6, q7 = q
    c, s = np.cos, np.sin
    return np.array([
        p["l1"] * c(q1) + p["l2"] * c(q1 + q2) + p["xN"] * c(q1 + q2 + q3) - p["xB"] - p["l3"] * c(q4)
        - p["l4"] * c(q4 + q5),
        p["l1"] * s(q1) + p["l2"] * s(q1 + q2) + p["xN"] * s(q1 + q2 + q3) - p["yB"] - p["l3"] * s(q4)
        - p["l4"] * s(q4 + q5),
        p["l1"] * c(q1) + p["l2"] * c(q1 + q2) + p["xP"] * c(q1 + q2 + q3) - p["yP"] * s(q1 + q2 + q3) - p["xC"]
        - p["l5"] * c(q6) - p["l6"] * c(q6 + q7),
        p["l1"] * s(q1) + p["l2"] * s(q1 + q2) + p["xP"] * s(q1 + q2 + q3) + p["yP"] * c(q1 + q2 + q3) - p["yC"]
        - p["l5"] * s(q6) - p["l6"] * s(q6 + q7),
    ])


def test_structure_as_in_the_brief(rrr3):
    topo = rrr3.topology
    assert topo.chains == [[0, 1, 2, 7], [0, 3, 4], [0, 5, 6]]
    assert [c.number for c in topo.cut_joints] == [8, 9]
    assert rrr3.variable_names == [f"q{i}" for i in range(1, 8)]
    by_chain = [[v.name for c in (topo.edges[x].coupling for x in chain[1:]) for v in topo.variables_of(c)]
                for chain in topo.chains]
    assert by_chain == [["q1", "q2", "q3"], ["q4", "q5"], ["q6", "q7"]]


def test_platform_transform_as_in_the_brief(rrr3):
    q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
    l1, l2 = sp.symbols("l1 l2", real=True)
    s = q1 + q2 + q3
    expected = sp.Matrix([[sp.cos(s), -sp.sin(s), 0, l1 * sp.cos(q1) + l2 * sp.cos(q1 + q2)],
                          [sp.sin(s), sp.cos(s), 0, l1 * sp.sin(q1) + l2 * sp.sin(q1 + q2)],
                          [0, 0, 1, 0], [0, 0, 0, 1]])
    assert sp.simplify(rrr3.frames.links[7] - expected) == sp.zeros(4, 4)


def test_four_independent_equations_equivalent_to_the_brief(rrr3):
    red = rrr3.reduction
    assert len(red.equations) == 10
    assert sum(e.status == "identically zero" for e in red.equations) == 6
    assert len(red.kept) == 4
    p = rrr3.tables.parameters
    syms = [v.symbol for v in rrr3.topology.variables]
    f = sp.lambdify([syms, list(rrr3.tables.symbols.values())], [e.expression for e in red.kept])
    rng = np.random.default_rng(0)
    for _ in range(50):  # the same functions at random configurations, not only on the manifold
        q = rng.uniform(-np.pi, np.pi, 7)
        assert np.allclose(f(q, list(p.values())), brief_equations(q, p), atol=1e-12)
    assert rrr3.dof == 3 and rrr3.grubler == 3 and rrr3.planar


def test_describe_text_json_and_latex(rrr3):
    text = describe_case(rrr3, links=[7])
    for piece in ("Substructures", "0 (base) - 1 - 2 - 7 (platform)", "Cut joints: 8", "q7 [rad]",
                  "cos(q1 + q2 + q3)", "6 hold identically", "4 independent", "Grubler-Kutzbach count (planar) 3",
                  "actual 3", "Reaction unknowns"):
        assert piece in text, piece
    data = json.loads(describe_main(str(CONFIG), json=True))
    assert {"joint_variables", "constraints", "dof", "cut_joints", "substructures", "transforms"} <= set(data)
    assert [v["name"] for v in data["joint_variables"]] == [f"q{i}" for i in range(1, 8)]
    assert len(data["constraints"]) == 4 and data["dof"]["actual"] == 3
    assert [c["number"] for c in data["cut_joints"]] == [8, 9]
    assert data["cut_joints"][0]["reactions"] == ["f_x", "f_y", "f_z", "m_x", "m_y"]
    latex = describe_main(str(CONFIG), latex=True, links=[7])
    assert r"\begin{align}" in latex and r"\cos{\left(q_{1} + q_{2} + q_{3} \right)}" in latex


def test_kinematic_run_closes_the_brief_loops(tmp_path):
    """csim run: every output sample satisfies the brief's equations; velocities match
    finite differences of the positions; the file says it is a kinematic analysis."""
    from csim.case import load_case
    from csim.io.hdf5 import read_result, write_result
    from csim.pipeline import run_case

    case = load_case(CONFIG, ["simulation.t_end=0.5"])
    result = run_case(case)
    assert result.ok, result.message
    out = tmp_path / "rrr3.h5"
    write_result(out, result, case.mechanism.coordinate_units)
    back = read_result(out)
    assert back.message.startswith("kinematic analysis") and back.run_kind == "kinematic"
    assert np.isnan(back.lam).all() and back.lam.shape == (51, 4)
    p = yaml.safe_load(CONFIG.read_text())["mechanism"]["parameters"]
    assert max(np.abs(brief_equations(q, p)).max() for q in back.q) < 1e-11
    t = back.t
    assert np.allclose(back.q[:, 0], 0.5773 + 0.05 * np.sin(2 * np.pi * t))
    fd = np.gradient(back.q, t, axis=0, edge_order=2)
    assert np.abs(fd - back.qd)[2:-2].max() < 2e-3 * np.abs(back.qd).max()
    fdd = np.gradient(back.qd, t, axis=0, edge_order=2)
    assert np.abs(fdd - back.qdd)[2:-2].max() < 2e-2 * np.abs(back.qdd).max()
    assert np.abs(back.phi).max() < 1e-11 and np.abs(back.phi_dot).max() < 1e-12


def test_cli_describe_runs_and_plots_a_link_coupling_case(tmp_path):
    """The commands end to end: describe (text and JSON), run, and plot from the stored case."""
    from typer.testing import CliRunner

    from csim.cli import app

    runner = CliRunner()
    res = runner.invoke(app, ["describe", str(CONFIG), "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.stdout)
    assert {"joint_variables", "constraints", "dof", "cut_joints"} <= set(data)
    assert len(data["joint_variables"]) == 7 and len(data["constraints"]) == 4
    # a registered mechanism has no tables to describe: exit 2, no traceback
    qr = Path(__file__).resolve().parents[1] / "configs" / "quick_return.yaml"
    res = runner.invoke(app, ["describe", str(qr)])
    assert res.exit_code == 2 and "mechanism.links" in res.stderr and "Traceback" not in res.output
    out = tmp_path / "rrr3.h5"
    res = runner.invoke(app, ["run", str(CONFIG), "-o", str(out), "--set", "simulation.t_end=0.2"])
    assert res.exit_code == 0, res.output
    assert "kinematic analysis of prescribed motion" in res.stdout
    # the stored case validates again (the drive's initial values may stay), so the mechanism is drawn
    res = runner.invoke(app, ["plot", str(out), "-o", str(tmp_path / "plots"), "--dpi", "40"])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "plots" / "mechanism.png").is_file()
    assert "skipped multipliers: a kinematic analysis" in res.stdout
