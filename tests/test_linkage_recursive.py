"""The equations of motion of a linkage derived link by link (csim.linkage.recursive) against
the whole-mechanism derivation of the same definition (Hessian of T, Lagrange, Jacobians of
Phi: csim.model.derive without the recursive terms), at random states, to round-off."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from csim.case import load_case, validate_case
from csim.model import derive as derive_module
from csim.model.codegen import generate_source
from csim.model.light import full_definition

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
TERMS = [("mass", "q"), ("velocity_terms", "qv"), ("gravity", "q"), ("phi", "q"), ("phi_q", "q"),
         ("gamma", "qv"), ("kinetic_energy", "qv"), ("potential_energy", "q"), ("observables", "q"),
         ("observable_jacobian", "q"), ("points", "q")]


def functions(definition) -> dict:
    """The generated Python functions of ``definition``'s derivation (no cache)."""
    namespace: dict = {}
    exec(generate_source(derive_module._derive(definition)), namespace)
    return namespace


def compare(definition, seed: int = 0, samples: int = 3) -> None:
    """Recursive and whole-expression models agree at random states (relative 1e-12)."""
    definition = full_definition(definition)  # (a case's is light: csim.linkage.plan)
    assert definition.recursive is not None
    recursive = functions(definition)
    whole = functions(dataclasses.replace(definition, recursive=None))
    rng = np.random.default_rng(seed)
    m = len(definition.coordinates)
    par = np.array([p.default for p in definition.parameters])
    for _ in range(samples):
        q, qd = rng.uniform(-np.pi, np.pi, m), rng.uniform(-2, 2, m)
        for name, args in TERMS:
            call = (q, qd, par) if args == "qv" else (q, par)
            a, b = np.asarray(recursive[name](*call)), np.asarray(whole[name](*call))
            scale = max(1.0, float(np.max(np.abs(b)))) if b.size else 1.0
            assert a.shape == b.shape, name
            assert np.allclose(a, b, rtol=0, atol=1e-12 * scale), f"{name}: {np.max(np.abs(a - b))}"


@pytest.mark.parametrize("config", ["fourbar_gravity.yaml", "slider_crank_dynamic.yaml", "rrr3_planar.yaml"])
def test_planar_linkages_agree_with_the_whole_mechanism_derivation(config):
    compare(load_case(CONFIGS / config).mechanism)


def test_recursive_terms_use_named_intermediates():
    """The derivation of a linkage is built from intermediates; M is symmetric and T = qd.M.qd/2."""
    definition = load_case(CONFIGS / "fourbar_gravity.yaml").mechanism
    derived = derive_module._derive(definition)
    assert len(derived.intermediates) > 20
    assert derived.mass == derived.mass.T
    names = {str(s) for s, _ in derived.intermediates}
    assert all(n.startswith("_v") for n in names)
    f = functions(definition)
    rng = np.random.default_rng(1)
    q, qd = rng.uniform(-3, 3, 3), rng.uniform(-2, 2, 3)
    par = np.array([p.default for p in definition.parameters])
    assert np.isclose(f["kinetic_energy"](q, qd, par), 0.5 * qd @ f["mass"](q, par) @ qd, rtol=1e-13)


@pytest.mark.slow  # about 40 s: the whole-mechanism derivation of a spatial loop (trigsimp)
def test_spatial_linkage_with_full_inertia_agrees_with_the_whole_mechanism_derivation():
    """R-S-U-R with off-axis centres of mass, full inertia tensors and a skew gravity: the
    rotational terms (G^T I G, G^T (I wd + w x I w)) against the Hessian of T."""
    data = yaml.safe_load((CONFIGS / "rsur_spatial.yaml").read_text())
    mech = data["mechanism"]
    del mech["drive"]
    mech["gravity"] = [0.5, -2, -9.81]
    mech["parameters"].update(m1=0.5, m2=1.0, m3=0.8)
    inertia = [[0.02, 0.003, -0.001], [0.003, 0.015, 0.002], [-0.001, 0.002, 0.01]]
    for row, mass in zip(mech["links"][1:], ("m1", "m2", "m3")):
        row.update(mass=mass, com=[0.05, 0.01, -0.02], inertia=inertia)
    data["initial"].update(q={"q_A": 0.3}, qd={"q_A": 2.0})
    compare(validate_case(data).mechanism, samples=2)


@pytest.mark.slow  # about 20 s: the whole-mechanism derivation
def test_quick_return_tables_agree_with_the_whole_mechanism_derivation():
    compare(load_case(CONFIGS / "quick_return_tables.yaml").mechanism)
