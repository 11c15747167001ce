"""Link-coupling input that used to run to "success" or to a misleading message: each is an
exit-2 error through the CLI naming the table row and key, never a traceback."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from csim.cli import app
from csim.errors import CaseError
from csim.linkage.model import build_linkage

CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def config(name: str) -> dict:
    return yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())


def cli(tmp_path, data: dict, command: str = "describe"):
    """Run ``csim COMMAND case.yaml``; (exit code, stderr, all output)."""
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(data))
    args = [command, str(path)] + (["-o", str(tmp_path / "out.h5")] if command == "run" else [])
    res = CliRunner().invoke(app, args)
    assert "Traceback" not in res.output
    return res.exit_code, res.stderr, res.output


def failed(tmp_path, data, command="describe") -> list[str]:
    """The problems of an invalid case: exit 2, one line each after 'csim: error'."""
    code, err, _ = cli(tmp_path, data, command)
    assert code == 2, err
    assert not (tmp_path / "out.h5").exists()  # nothing ran
    return [line.strip() for line in err.splitlines()[1:]]


def crank(data: dict, **changes) -> dict:
    """``data`` with the crank row (links[1]) changed."""
    data = copy.deepcopy(data)
    data["mechanism"]["links"][1].update(changes)
    return data


@pytest.mark.parametrize("mass,shown", [(-0.5, "got -0.5 (number), -0.5 kg"), ("-m1", "got '-m1' (string), -0.5 kg")])
def test_negative_mass_is_rejected_naming_the_row(tmp_path, mass, shown):
    (msg,) = failed(tmp_path, crank(config("fourbar_gravity"), mass=mass), "run")
    assert msg == (f"mechanism.links[1].mass: {shown} at the parameter values; expected a mass >= 0 [kg] (0 or "
                   f"left out, with no inertia: a massless link)")


def test_inertia_without_mass_is_rejected_a_massless_link_is_not(tmp_path):
    (msg,) = failed(tmp_path, crank(config("fourbar_gravity"), mass=0))
    assert msg.startswith("mechanism.links[1].mass: got 0 (integer) with the inertia 'm1*a^2/12' (string); "
                          "expected mass > 0 [kg] for a link with inertia")
    no_mass = crank(config("fourbar_gravity"))
    del no_mass["mechanism"]["links"][1]["mass"]
    (msg,) = failed(tmp_path, no_mass)
    assert msg.startswith("mechanism.links[1].mass: left out with the inertia 'm1*a^2/12' (string)")
    massless = crank(config("fourbar_gravity"), mass=0)
    del massless["mechanism"]["links"][1]["inertia"]
    code, err, _ = cli(tmp_path, massless)
    assert code == 0, err


@pytest.mark.parametrize("inertia,moments", [
    (-1.0, "-1, -1, -1"),                                     # negative scalar
    ([0.1, -0.2, 0.3], "-0.2, 0.1, 0.3"),                     # a negative principal moment
    ([[1, 2, 0], [2, 1, 0], [0, 0, 1]], "-1, 1, 3"),          # symmetric but indefinite
])
def test_inertia_with_a_negative_principal_moment_is_rejected(tmp_path, inertia, moments):
    (msg,) = failed(tmp_path, crank(config("fourbar_gravity"), inertia=inertia))
    assert msg.startswith(f"mechanism.links[1].inertia: got {yaml.safe_load(yaml.safe_dump(inertia))!r}")
    assert f"principal moments {moments} kg m^2 at the parameter values; expected no negative principal moment" \
        in msg


def test_non_symmetric_inertia_is_rejected(tmp_path):
    (msg,) = failed(tmp_path, crank(config("fourbar_gravity"), inertia=[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]))
    assert msg.startswith("mechanism.links[1].inertia: got [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]] (list); expected a "
                          "symmetric 3x3 inertia tensor")


def test_planar_mechanism_needs_only_a_moment_about_the_plane_normal(tmp_path):
    """[0, 0, Izz] (a lamina model, no triangle inequality) runs; Izz = 0 does not."""
    code, err, _ = cli(tmp_path, crank(config("fourbar_gravity"), inertia=[0, 0, "m1*a^2/12"]))
    assert code == 0, err
    (msg,) = failed(tmp_path, crank(config("fourbar_gravity"), inertia=[1e-3, 1e-3, 0]))
    assert msg.startswith("mechanism.links[1].inertia (link 1 'crank'): principal moments 0, 0.001, 0.001 kg m^2 "
                          "at the parameter values, 0 about the normal of the plane of motion; expected a moment > 0")


def rsur_with_crank_inertia(inertia) -> dict:
    data = config("rsur_spatial")
    data["mechanism"]["links"][1].update(mass=1.0, com=["a/2", 0, 0], inertia=inertia)
    return data


@pytest.mark.parametrize("inertia,expected", [
    ([0.1, 0.1, 0.3], "principal moments 0.1, 0.1, 0.3 kg m^2 at the parameter values; 0.1 + 0.1 < 0.3: expected "
                      "the triangle inequality I1 + I2 >= I3 of a rigid body's principal moments in a spatial "
                      "mechanism"),
    ([0, 1e-3, 1e-3], "principal moments 0, 0.001, 0.001 kg m^2 at the parameter values; expected every principal "
                      "moment > 0 (a positive definite tensor) in a spatial mechanism"),
])
def test_spatial_inertia_must_be_a_rigid_bodys(tmp_path, inertia, expected):
    assert failed(tmp_path, rsur_with_crank_inertia(inertia)) == [
        f"mechanism.links[1].inertia (link 1 'crank'): {expected}"]


def test_spatial_inertia_on_the_triangle_boundary_is_accepted(tmp_path):
    """A thin plate: I1 + I2 = I3 exactly holds the inequality."""
    code, err, _ = cli(tmp_path, rsur_with_crank_inertia([1e-3, 2e-3, 3e-3]))
    assert code == 0, err


def test_one_bad_row_is_reported_once(tmp_path):
    """The couplings naming the bad row's link (by name and by number) add nothing."""
    data = crank(config("fourbar"), joints=[["X", 0, "A"], ["R", ["a", 0, 0], "B"]])
    assert failed(tmp_path, data) == ["mechanism.links[1].joints[0]: joint type got 'X' (string); expected one of "
                                      "R, P, C, U, S"]
    data["mechanism"]["couplings"] = [[0, 1, 1, 1], [1, 2, 2, 1], [0, 2, 3, 1], [2, 2, 3, 2]]
    assert len(failed(tmp_path, data)) == 1
    # a link that really is not there is still named
    data["mechanism"]["couplings"][2] = [0, 2, 9, 1]
    assert failed(tmp_path, data)[1].startswith("mechanism.couplings[2] (coupling 3): link 9 (integer) is not "
                                                "defined in mechanism.links")


def test_over_and_under_driven_are_counted_before_any_held_newton_solve(tmp_path, monkeypatch):
    """N drives for M DOF, not "cannot be assembled"; no Newton solve holds the drives."""
    from csim.linkage import constraints

    data = config("fourbar")
    data["mechanism"]["drive"] = {"crank": "2*pi*t", "rocker": 1.5}
    (msg,) = failed(tmp_path, data, "run")
    assert msg == ("mechanism.drive: 2 drives for 1 degree of freedom (q_crank, q_rocker driven); expected exactly 1 "
                   "driven joint variable(s) (over-driven: the drives would contradict the constraints)")
    held = []
    original = constraints.solve_positions

    def spy(phi, phi_q, q_start, free, *args):
        held.append(q_start.size - len(free))
        return original(phi, phi_q, q_start, free, *args)

    monkeypatch.setattr(constraints, "solve_positions", spy)
    with pytest.raises(CaseError, match="2 drives for 1 degree of freedom"):
        build_linkage(data["mechanism"], data["initial"])
    assert held and set(held) == {0}
    data = config("rrr3_planar")
    del data["mechanism"]["drive"][3], data["mechanism"]["drive"][5]
    (msg,) = failed(tmp_path, data)
    assert msg.startswith("mechanism.drive: 1 drive for 3 degrees of freedom (q1 driven); expected exactly 3")
    assert "under-driven" in msg


def test_initial_q_with_more_coordinates_than_dof(tmp_path):
    data = config("fourbar_gravity")
    data["initial"]["q"] = {"q_crank": 0.0, "q_rocker": 1.8}
    (msg,) = failed(tmp_path, data, "run")
    assert msg == ("initial.q: 2 coordinates for 1 degree of freedom (q_crank, q_rocker); expected exactly 1 "
                   "independent coordinate(s)")


def test_describe_prints_drives_as_written(tmp_path):
    code, err, out = cli(tmp_path, config("rrr3_planar"))
    assert code == 0, err
    assert "driven: 0.5773 + 0.05*sin(2*pi*t)" in out and "driven: -0.2047 + 0.05*sin(2*pi*t)" in out
    assert "/10000" not in out
    data = config("fourbar")
    data["mechanism"]["drive"] = {"crank": 0.25}
    code, err, out = cli(tmp_path, data)
    assert code == 0 and "driven: 0.25\n" in out


@pytest.mark.parametrize("where,value,what", [
    (("links", 0, "joints", 1, 1, 0), "acos(d/a/2)", "complex (0+1.31696j)"),     # acos(2)
    (("links", 2, "joints", 1, 1, 0), "b/(a - d + 0.3)", "not finite"),          # a pole at the values
    (("links", 2, "joints", 1, 1, 0), "sqrt(a - d)", "complex (0+0.547723j)"),
    (("gravity", 1), "-9.81*acos(2)", "complex (0-12.9194j)"),
])
def test_expressions_that_are_not_real_at_the_parameter_values(tmp_path, where, value, what):
    data = config("fourbar_gravity")
    node = data["mechanism"]
    for key in where[:-1]:
        node = node[key]
    node[where[-1]] = value
    path = "mechanism." + ".".join(str(k) for k in where[:1]) + "".join(f"[{k}]" for k in where[1:2])
    path += "".join(f".{k}" if isinstance(k, str) else f"[{k}]" for k in where[2:])
    (msg,) = failed(tmp_path, data)
    assert msg == (f"{path}: got {value!r} (string); at the parameter values it is {what}; expected a finite real "
                   f"value of magnitude at most 1e+100")


def test_a_gap_in_the_link_numbers_names_the_missing_link(tmp_path):
    data = config("fourbar")
    data["mechanism"]["links"][3]["link"] = 4
    assert failed(tmp_path, data) == ["mechanism.links: link 3 is missing (links given: 0, 1, 2, 4); expected the "
                                      "links numbered 0 to 4 without gaps"]
    data["mechanism"]["links"][2]["link"] = 5
    assert failed(tmp_path, data) == ["mechanism.links: links 2, 3 are missing (links given: 0, 1, 4, 5); expected "
                                      "the links numbered 0 to 5 without gaps"]


def test_valid_examples_still_derive_with_their_masses():
    """Every example config is valid under the new checks (the slow Bricard aside)."""
    for name in ("fourbar", "fourbar_gravity", "slider_crank", "rrr3_planar", "rsur_spatial"):
        data = config(name)
        lk = build_linkage(data["mechanism"], data.get("initial"))
        assert lk.dof >= 1 and np.isfinite(list(lk.start.values())).all()


# --------------------------------------------------------------------------- found by fuzzing (tests/test_fuzz.py)


def test_a_huge_link_number_is_a_gap_not_a_memory_error(tmp_path):
    data = config("fourbar")
    data["mechanism"]["links"][3]["link"] = 10**12
    problems = failed(tmp_path, data)
    gap = next(p for p in problems if p.startswith("mechanism.links: "))
    assert "links 3" in gap and f"3, 4, 5, 6, 7, 8, 9, 10, 11, 12 and {10**12 - 13} more are missing" in gap


def test_a_parameter_beyond_the_float_range_is_rejected(tmp_path):
    data = config("fourbar")
    data["mechanism"]["parameters"]["a"] = 10**400
    problems = failed(tmp_path, data)
    assert problems[0].startswith("mechanism.parameters.a: got ") and "expected a finite number" in problems[0]
    data = config("fourbar")
    data["mechanism"]["links"][1]["joints"][1][1][0] = 10**400
    problems = failed(tmp_path, data)
    assert problems[0].startswith("mechanism.links[1].joints[1][1][0]: got ")


@pytest.mark.parametrize("value", [1e308, "l * 1e200", 2e100])
def test_a_finite_value_whose_products_overflow_is_rejected(tmp_path, value):
    # 1e308 is a finite float, but the closure equations' Jacobian multiplies positions: the
    # rocker's U joint placed there raised OverflowError in the lambdified code (long fuzz profile)
    data = config("rsur_spatial")
    data["mechanism"]["parameters"]["l"] = 1.0
    data["mechanism"]["links"][3]["joints"][1][1][0] = value
    problems = failed(tmp_path, data)
    assert problems[0].startswith("mechanism.links[3].joints[1][1][0]: got "), problems
    assert "magnitude" in problems[0] and "1e+100" in problems[0]


def test_a_coupling_name_that_is_a_list_is_rejected(tmp_path):
    data = config("fourbar")
    data["mechanism"]["couplings"][2]["name"] = [1, 2]
    (problem,) = failed(tmp_path, data)
    assert problem.startswith("mechanism.couplings[2] (coupling 3).name: got [1, 2] (list); not a usable name")


def test_a_point_name_on_links_no_coupling_joins_is_an_error(tmp_path):
    """``B`` on every crank of the N-four-bar used to give one observable B_x, from the first crank."""
    data = yaml.safe_load((CONFIGS / "iftomm" / "a02_n_four_bar_2.yaml").read_text())
    for row in data["mechanism"]["links"]:
        for joint in row["joints"]:
            if isinstance(joint, list) and len(joint) == 3 and str(joint[2]).startswith("B"):
                joint[2] = "B"
    def by_number(end):  # the cranks' tops by joint number (2), now that their names clash
        return 2 if isinstance(end, str) and end.startswith("B") else end

    for row in data["mechanism"]["couplings"]:
        couple = row["couple"]
        row["couple"] = ([[link, by_number(joint)] for link, joint in couple] if isinstance(couple[0], list)
                         else [by_number(x) for x in couple])
    problems = failed(tmp_path, data)
    assert any("point name 'B' is also on link 1 'crank0'" in p and "no coupling joins" in p for p in problems)
    # the same name on two frames that a coupling joins is one point (B on a crank and its coupler)
    assert not any("point name" in p for p in failed_or_none(tmp_path, config("fourbar_gravity")))


def failed_or_none(tmp_path, data) -> list[str]:
    code, err, _ = cli(tmp_path, data)
    return [] if code == 0 else err.splitlines()
