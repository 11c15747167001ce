"""``csim describe`` of force elements and the drive mode (csim/linkage/describe.py)."""
from __future__ import annotations

import json

import sympy as sp
import yaml
from conftest import CONFIGS

from csim.describe import describe_main

SLIDE = [0, 0, 0, "90*deg", "90*deg", 0]


def slider_case(tmp_path, forces, **mechanism) -> str:
    """A block on a prismatic joint along x, with ``forces``; the file's path."""
    data = {"mechanism": {
        "label": "slider", "parameters": {"m": 2.0, "k": 50.0, "L0": 0.3, "c": 1.5},
        "links": [{"link": 0, "name": "ground", "joints": [["P", SLIDE, "G"], ["R", [-1, 0, 0], "E"]]},
                  {"link": 1, "name": "block", "joints": [["P", SLIDE, "G"]], "mass": "m"}],
        "couplings": [{"name": "slide", "couple": ["ground", "G", "block", "G"]}],
        "forces": forces, **mechanism}, "initial": {"q": {"s_slide": 0.5}}}
    path = tmp_path / "slider.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def test_json_lists_each_element_with_its_derived_potential_and_loads(tmp_path):
    path = slider_case(tmp_path, [
        {"name": "spring", "type": "joint_spring", "joint": "slide", "stiffness": "k", "free_length": "L0",
         "damping": "c"},
        {"name": "push", "type": "actuator", "joint": "slide", "force": "2*sin(t)", "window": [0, 1]}])
    data = json.loads(describe_main(path, json=True))
    assert data["drive_mode"] is None and data["run"].startswith("forward dynamics")
    spring, push = data["forces"]
    assert (spring["name"], spring["type"], push["type"]) == ("spring", "joint_spring", "actuator")
    s, k, L0, c, t = sp.symbols("s_slide k L0 c t", real=True)
    names = {"s_slide": s, "k": k, "L0": L0, "c": c, "t": t, "s_slide_dot": sp.Symbol("s_slide_dot", real=True)}
    # V = k (s - L0)^2 / 2, written here by hand
    assert sp.simplify(sp.sympify(spring["potential"], locals=names) - k * (s - L0) ** 2 / 2) == 0
    (damper,) = spring["loads"]
    assert sp.simplify(sp.sympify(damper["law"], locals=names) - c * names["s_slide_dot"]) == 0
    (load,) = push["loads"]
    assert (load["unit"], load["coordinate"], load["window"], load["velocity"]) == ("N", "s_slide", [0.0, 1.0], "any")
    assert sp.simplify(sp.sympify(load["law"], locals=names) - 2 * sp.sin(t)) == 0


def test_text_and_latex_name_the_run_and_the_elements(tmp_path):
    path = slider_case(tmp_path, [{"name": "spring_1", "type": "joint_spring", "joint": "slide", "stiffness": "k"}])
    text = describe_main(path)
    assert "Run: forward dynamics" in text
    assert "Force elements (1):\n  spring_1 (joint_spring): joint: slide, stiffness: k\n    potential V = " in text
    latex = describe_main(path, latex=True)
    assert r"\paragraph{Force elements}" in latex and r"V_{\mathrm{spring\_1}} &= \frac{k s_{slide}^{2}}{2}" in latex


def test_drive_modes_are_reported():
    driven = describe_main(CONFIGS / "slider_crank_dynamic.yaml")
    assert "Run: driven dynamics (mechanism.drive, drive_mode dynamic)" in driven
    assert "load resist [N] = -F0" in driven
    kinematic = json.loads(describe_main(CONFIGS / "slider_crank.yaml", json=True))
    assert kinematic["drive_mode"] == "kinematic" and kinematic["forces"] == []
    assert "Force elements (0): none" in describe_main(CONFIGS / "slider_crank.yaml")
