"""Kinematic analysis (csim.linkage.kinematics) against the slider-crank's closed form.

The slider's position on either assembly branch, s = r cos(theta) +- sqrt(l^2 - (e - r sin(theta))^2),
its rate and its acceleration (finite differences of the closed form) are independent of
csim's model; the samples are 45 degrees of crank apart, so each one is far from the last
and the analysis must follow the branch it started on.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from csim.case import load_case
from csim.pipeline import run_case

CONFIG = Path(__file__).resolve().parent.parent / "configs" / "slider_crank.yaml"
R, L, E = 0.1, 0.3, 0.02


def load(**values) -> object:
    """The slider-crank case with --set style overrides (keys with '.' spelled '__')."""
    return load_case(CONFIG, overrides=[f"{k.replace('__', '.')}={v}" for k, v in values.items()])


def slider(theta: np.ndarray, branch: float) -> np.ndarray:
    """s(theta) [m] on the branch with the slider right (+1) or left (-1) of the crank pivot."""
    return R * np.cos(theta) + branch * np.sqrt(L**2 - (E - R * np.sin(theta)) ** 2)


@pytest.mark.parametrize("branch", [1.0, -1.0])
def test_kinematic_analysis_follows_its_branch_through_coarse_samples(branch):
    case = load(simulation__t_end=2.0, output__dt=0.125, initial__guess__s_slide=0.38 * branch,
                initial__guess__q_B=-0.2 if branch > 0 else np.pi + 0.2)
    result = run_case(case)
    assert result.status == "success", result.message
    names = case.mechanism.coordinate_names
    theta = result.q[:, names.index("q_crank")]
    s = result.q[:, names.index("s_slide")]
    np.testing.assert_allclose(theta, 2 * np.pi * result.t, atol=1e-12)
    np.testing.assert_allclose(s, slider(theta, branch), atol=1e-11)
    # rates and accelerations: d/dt and d2/dt2 of the closed form by central differences (h = 1e-4 s)
    h, w = 1e-4, 2 * np.pi
    plus, minus = slider(w * (result.t + h), branch), slider(w * (result.t - h), branch)
    np.testing.assert_allclose(result.qd[:, names.index("s_slide")], (plus - minus) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(result.qdd[:, names.index("s_slide")], (plus - 2 * slider(theta, branch) + minus) / h**2,
                               atol=2e-3)
    assert np.max(np.abs(result.phi)) < 1e-10


def test_a_drive_past_the_dead_centre_fails_with_the_reason():
    """A rod shorter than the crank (l < r) stops it at r sin(theta) = l, t = 0.148 s: the analysis stops there
    and says why."""
    case = load(mechanism__parameters__l=0.08, mechanism__parameters__e=0.0, initial__guess__q_B=-0.1,
                initial__guess__s_slide=0.18)
    result = run_case(case)
    assert result.status == "failed"
    assert result.message.startswith("kinematic analysis: ")
    assert "cannot be assembled" in result.message or "singular" in result.message
    assert 0.13 <= result.t[-1] < 0.148  # the last sample before the limit (output.dt = 0.01 s)
