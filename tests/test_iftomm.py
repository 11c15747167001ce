"""The IFToMM benchmark problems (configs/iftomm/) against motions computed independently of
csim (tests/iftomm_reference.py), with the benchmark's own error measures and tolerances."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS
from iftomm_reference import a01_point, a02_b0, a05_motion
from test_andrews import Q_END

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


@pytest.mark.slow
def test_a02_forty_four_bars_with_the_shipped_minimal_coordinates():
    # 80 dependent coordinates: the partition is chosen again after every step (cond(Phi_v) stays
    # above minimal_max_condition), by pivoted QR (81 blocks of 80 x 80 are too many to invert)
    result = run_case(load_case(IFTOMM / "a02_n_four_bar_40.yaml", ["simulation.t_end=1.5"]))
    assert result.status == "success", result.message
    assert result.singular_times.size >= 2  # t = 0.72 s and 1.24 s
    p, _ = a02_b0(result.t, 40)
    theta = result.q[:, 0]
    assert np.max(np.hypot(np.cos(theta) - p[:, 0], np.sin(theta) - p[:, 1])) < 1e-4


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


def _a05_errors(result):
    """Largest |s - s_ref| [m], |theta - theta_ref| [rad] (both rods) and |tau - tau_ref| [N m]."""
    names = result.coordinate_names
    y, tau = a05_motion(result.t)
    s_err = np.max(np.abs(result.q[:, names.index("s_slide")] - y[:, 0]))
    th_err = max(np.max(np.abs(result.q[:, names.index(n)] - y[:, i])) for i, n in ((1, "q_A"), (2, "q_B")))
    return s_err, th_err, np.max(np.abs(result.drive_forces[:, 0] - tau))


def test_a05_governor_against_its_rotating_frame_equations():
    """The shaft driven at 2 pi rad/s (one drive for four degrees of freedom): the slider, the
    rods and the drive torque against Lagrange's equations in the rotating frame, over 1 s
    at the shipped tolerance and at a tight one (the error must shrink: not a match by
    construction)."""
    errors, energy = [], []
    for tol in ("1e-5", "1e-9"):
        result = run_case(load_case(IFTOMM / "a05_flyball_governor.yaml",
                                    ["simulation.t_end=1", f"simulation.rtol={tol}", f"simulation.atol={tol}"]))
        assert result.status == "success", result.message
        assert not result.warnings
        assert np.max(np.abs(result.qd[:, 0] - 2 * np.pi)) < 1e-9  # the shaft keeps its speed
        energy.append(result.energy_error_relative)
        errors.append(_a05_errors(result))
    shipped, tight = errors
    assert energy[0] < 1e-4 and energy[1] < 1e-8  # the drive's and dampers' work included: 3.7e-6, 3.3e-10
    assert shipped[0] < 1e-4 and tight[0] < 1e-8  # measured 1.6e-6 and 1.3e-10 m
    assert tight[1] < 1e-8 and tight[2] < 1e-6  # torque up to 49 N m; measured 2.2e-8 N m
    assert tight[0] < shipped[0] / 100


@pytest.mark.slow
def test_a05_governor_meets_the_benchmark_tolerance():
    """The slider coordinate over 10 s within 1e-3 m, with the shipped settings."""
    result = run_case(load_case(IFTOMM / "a05_flyball_governor.yaml"))
    assert result.status == "success", result.message
    assert result.t.size == 1001
    assert _a05_errors(result)[0] < 1e-3  # measured 2.7e-6 m


def test_a03_andrews_as_link_and_coupling_tables_meets_the_test_set():
    """The tables (a quaternary pin E, three cut joints, the spring and the torque as force
    elements) against the IVP test set's solution at 0.03 s, in its coordinates (each link's
    frame placed so that the joint variables are beta, Theta, gamma, Phi, delta, Omega,
    epsilon): 1e-6 relative."""
    case = load_case(IFTOMM / "a03_andrews.yaml")
    assert case.linkage is not None and case.linkage.dof == 1 and len(case.linkage.topology.cut_joints) == 3
    result = run_case(case)
    assert result.status == "success", result.message
    order = ["q_O", "q_F", "q_B", "q_G", "q_AG", "q_H", "q_AH"]
    q = result.q[-1, [result.coordinate_names.index(n) for n in order]]
    assert np.max(np.abs(q - Q_END) / np.abs(Q_END)) < 1e-6  # measured 2.8e-10
