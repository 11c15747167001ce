"""The IFToMM benchmark problems (configs/iftomm/) against motions computed independently of
csim (tests/iftomm_reference.py), with the benchmark's own error measures and tolerances."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS
from iftomm_reference import a01_point, a02_b0

from csim.case import load_case
from csim.pipeline import run_case

IFTOMM = CONFIGS / "iftomm"


def test_reference_pendulum_is_the_pendulum():
    """The elliptic solution starts horizontal at rest and keeps the energy (L = 1, g = 9.81)."""
    t = np.linspace(0.0, 3.0, 3001)
    p = a01_point(t)
    assert p[0] == pytest.approx([1.0, 0.0], abs=1e-15)
    v = np.gradient(p, t, axis=0)
    energy = 0.5 * np.sum(v[1:-1] ** 2, axis=1) + 9.81 * p[1:-1, 1]
    assert np.max(np.abs(energy)) < 1e-4  # zero at the start (at rest, y = 0)


def test_a01_pendulum_meets_the_benchmark_tolerance():
    """Largest distance of P1 from the exact motion over the 4000 output steps of 2000 s: 1e-3 m."""
    result = run_case(load_case(IFTOMM / "a01_pendulum.yaml"))
    assert result.status == "success", result.message
    assert result.t.size == 4001
    error = np.max(np.hypot(*(result.q - a01_point(result.t)).T))
    assert error < 1e-3


@pytest.mark.parametrize("method", [(), ("stabilization.method=augmented_lagrangian",
                                           "simulation.integrator=trapezoidal")], ids=["minimal", "al"])
def test_a02_two_four_bars_keep_the_parallelogram(method):
    """B0's position and velocity against the one-degree-of-freedom motion (1e-3), through the
    singular crossings, which the result records."""
    result = run_case(load_case(IFTOMM / "a02_n_four_bar_2.yaml", ["simulation.t_end=5", *method]))
    assert result.status == "success", result.message
    p, v = a02_b0(result.t, 2)
    theta, rate = result.q[:, 0], result.qd[:, 0]
    b0 = np.column_stack((np.cos(theta), np.sin(theta)))
    b0_rate = np.column_stack((-np.sin(theta) * rate, np.cos(theta) * rate))
    assert np.max(np.hypot(*(b0 - p).T)) < 1e-3
    assert np.max(np.hypot(*(b0_rate - v).T)) < 1e-3
    assert result.singular_times.size >= 4


@pytest.mark.slow
def test_a02_forty_four_bars_with_the_augmented_lagrangian_method():
    result = run_case(load_case(IFTOMM / "a02_n_four_bar_40.yaml", ["stabilization.method=augmented_lagrangian",
                                                                     "simulation.integrator=trapezoidal"]))
    assert result.status == "success", result.message
    p, _ = a02_b0(result.t, 40)
    theta = result.q[:, 0]
    assert np.max(np.hypot(np.cos(theta) - p[:, 0], np.sin(theta) - p[:, 1])) < 1e-3


def test_a04_bricard_energy_and_a_second_formulation():
    """No closed form: projection on every equation (rows chosen as it moves) and the augmented
    Lagrangian method conserve energy and agree with the shipped minimal coordinates (a
    different formulation: one independent coordinate, Newton for the others on the kept
    equations)."""
    short = ["simulation.t_end=2", "output.dt=0.01"]
    ref = run_case(load_case(IFTOMM / "a04_bricard.yaml", [*short, "simulation.rtol=1e-11",
                                                            "simulation.atol=1e-11"]))  # minimal, shipped
    projection = run_case(load_case(IFTOMM / "a04_bricard.yaml", [*short, "stabilization.method=projection"]))
    al = run_case(load_case(IFTOMM / "a04_bricard.yaml", [*short, "stabilization.method=augmented_lagrangian",
                                                           "simulation.integrator=trapezoidal"]))
    assert ref.status == "success" and ref.energy_error_relative < 1e-8
    # trapezoidal, h = 1 ms: motion and energy O(h^2)
    for run, bound, energy in ((projection, 1e-6, 1e-8), (al, 1e-4, 5e-5)):
        assert run.status == "success", run.message
        assert run.energy_error_relative < energy
        assert np.max(np.abs(run.q - ref.q)) < bound
