"""A link-coupling model through the dynamics: the four-bar under gravity conserves energy,
with every formulation and a stabilizer, like a hand-written mechanism."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from csim.case import load_case
from csim.pipeline import run_case

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "fourbar_gravity.yaml"


@pytest.mark.parametrize("overrides", [
    [],
    ["formulation.method=elimination"],
    ["stabilization.method=projection"],
])
def test_four_bar_under_gravity_conserves_energy(overrides):
    case = load_case(CONFIG, ["simulation.t_end=0.6", *overrides])
    assert case.mechanism.coordinate_names == ["q_crank", "q_B", "q_rocker"]
    assert len(case.mechanism.constraints) == 2
    result = run_case(case)
    assert result.ok, result.message
    assert np.ptp(result.q[:, 0]) > 1.0                       # it really swings
    assert result.energy_error_relative < 1e-7                # T + V constant (no loads)
    assert result.max_phi < 1e-8 and result.max_phi_dot < 1e-7
    assert np.isfinite(result.lam).all()


def test_kinetic_energy_of_the_links_against_hand_formula():
    """T from the link masses, centres and inertias, against planar rigid-body formulas."""
    from csim.model import build_numeric_model

    case = load_case(CONFIG)
    model = build_numeric_model(case.mechanism)
    par = model.parameter_vector(case.parameters)
    p = case.parameters
    rng = np.random.default_rng(3)
    q, qd = rng.uniform(-np.pi, np.pi, 3), rng.uniform(-2, 2, 3)
    t1, t2, t3 = q[0], q[0] + q[1], q[2]            # absolute link angles
    w1, w2, w3 = qd[0], qd[0] + qd[1], qd[2]
    v1 = p["a"] / 2 * w1
    vB = p["a"] * w1 * np.array([-np.sin(t1), np.cos(t1)])
    v2 = vB + p["b"] / 2 * w2 * np.array([-np.sin(t2), np.cos(t2)])
    v3 = p["c"] / 2 * w3
    T = 0.5 * p["m1"] * v1 ** 2 + 0.5 * p["m1"] * p["a"] ** 2 / 12 * w1 ** 2 \
        + 0.5 * p["m2"] * v2 @ v2 + 0.5 * p["m2"] * p["b"] ** 2 / 12 * w2 ** 2 \
        + 0.5 * p["m3"] * v3 ** 2 + 0.5 * p["m3"] * p["c"] ** 2 / 12 * w3 ** 2
    V = 9.81 * (p["m1"] * p["a"] / 2 * np.sin(t1) + p["m2"] * (p["a"] * np.sin(t1) + p["b"] / 2 * np.sin(t2))
                + p["m3"] * p["c"] / 2 * np.sin(t3))
    assert np.isclose(model.kinetic_energy(q, qd, par), T, rtol=1e-12)
    assert np.isclose(model.potential_energy(q, par), V, rtol=1e-12)


@pytest.mark.slow  # about 35 s, nearly all of it the symbolic derivation of the spatial model
def test_spatial_rsur_linkage_under_gravity_conserves_energy():
    """A spatial loop (R, S, U, R) with link masses, released with the crank turning: the
    dynamics of a link-coupling model in 3-D, checked by the energy balance T + V = const."""
    import yaml

    from csim.case import validate_case

    data = yaml.safe_load((CONFIG.parent / "rsur_spatial.yaml").read_text())
    mech = data["mechanism"]
    del mech["drive"]
    mech["gravity"] = [0, 0, -9.81]
    mech["parameters"].update(m1=0.5, m2=1.0, m3=0.8)
    for row, (mass, length) in zip(mech["links"][1:], (("m1", "a"), ("m2", "b"), ("m3", "c"))):
        row.update(mass=mass, com=[f"{length}/2", 0, 0], inertia=f"{mass}*{length}^2/12")
    data["initial"].update(q={"q_A": 0.3}, qd={"q_A": 2.0})
    data["stabilization"] = {"method": "projection"}
    # the Python path: a first compiled run of a new mechanism would spend a minute compiling
    data["simulation"] = {"t_end": 0.5, "rtol": 1e-10, "atol": 1e-10, "backend": "python"}
    result = run_case(validate_case(data))
    assert result.ok, result.message
    assert np.ptp(result.q[:, 0]) > 0.5                       # the crank turns
    assert result.energy_error_relative < 1e-8                # measured 9e-11
    assert result.max_phi < 1e-12
