"""The elimination formulation (csim.physics.elimination) on both backends: the compiled kernels, the
interpreted kernels and the Python path call the same solve, so they take the same steps; and the
compiled elimination's motion against an independent reference (an angle ODE solved by scipy)."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS, qr_case

from csim.case import load_case
from csim.pipeline import build_system, initial_state, run_case
from csim.solver.simulate import integrate

ELIMINATION = "formulation.method=elimination"
#: a pendulum in Cartesian coordinates over the top: x and y each fail as the dependent coordinate twice
#: a turn, so the elimination must choose its partition again (csim.physics.elimination._partition) where
#: ||Phi_q||_1 ||Phi_v^-1||_1 = max(|x|, |y|) / |v| passes 20 (1e8, the default, is met only within 1e-8 m of it)
ROTATING = [ELIMINATION, "formulation.max_condition=20", "stabilization.method=baumgarte", "initial.q={x: 0.0}",
            "initial.qd={x: 7.0}", "initial.q_offset={}", "simulation.t_end=3", "simulation.rtol=1e-10",
            "simulation.atol=1e-10"]


def _both(case_of, *overrides):
    """{backend: result} of the compiled kernels and the Python path."""
    return {b: run_case(case_of(*overrides, f"simulation.backend={b}")) for b in ("compiled", "python")}


def _same_run(fast, slow, q_tol=1e-10):
    assert (fast.backend, slow.backend) == ("compiled", "python"), (fast.message, slow.message)
    assert fast.status == slow.status and fast.message == slow.message
    assert (fast.nsteps, fast.nfev) == (slow.nsteps, slow.nfev)
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=q_tol)
    scale = np.max(np.abs(slow.lam))
    np.testing.assert_allclose(fast.lam, slow.lam, rtol=0, atol=1e-9 * scale)


@pytest.mark.parametrize("overrides", [
    ("simulation.t_end=2",),  # none, DOP853, with the cutting force's switching events
    ("simulation.t_end=2", "stabilization.method=baumgarte", "simulation.integrator=RK4", "simulation.step=1e-3"),
    ("simulation.t_end=2", "stabilization.method=sliding_mode", "simulation.integrator=Tsit5"),
    ("simulation.t_end=2", "stabilization.method=projection"),
])
def test_the_compiled_elimination_takes_the_python_paths_steps(overrides):
    runs = _both(qr_case, ELIMINATION, *overrides)
    assert runs["compiled"].ok and len(runs["compiled"].event_times), runs["compiled"].message
    _same_run(runs["compiled"], runs["python"])


def test_the_interpreted_kernels_run_the_compiled_elimination_bit_for_bit():
    fast = run_case(qr_case(ELIMINATION, "simulation.t_end=0.5", "simulation.backend=compiled"))
    slow = run_case(qr_case(ELIMINATION, "simulation.t_end=0.5", "simulation.backend=interpreted"))
    assert (fast.backend, slow.backend) == ("compiled", "interpreted")
    assert fast.nfev == slow.nfev and np.array_equal(fast.q, slow.q) and np.array_equal(fast.lam, slow.lam)


def test_a_fixed_partition_fails_alike_on_both_backends_at_the_rocker_dead_point():
    """formulation.independent = [q2] (the rocker): Phi_v is singular where the rocker reverses; both backends
    stop there with the same message, kind and samples (tests/test_failure_modes.py has the figures)."""
    runs = _both(qr_case, ELIMINATION, "formulation.independent=[q2]", "simulation.t_end=1")
    fast, slow = runs["compiled"], runs["python"]
    assert fast.status == "failed" and fast.failure == slow.failure == "singular"
    assert "formulation.independent" in fast.message and "formulation.max_condition" in fast.message
    _same_run(fast, slow)
    assert 0.05 < fast.t[-1] < 0.2


def test_the_compiled_elimination_chooses_its_partition_again_over_the_top():
    """The Cartesian pendulum over the top: the Python path's partition changes at least twice a turn, the
    compiled run takes the same steps through those changes, and both follow the angle ODE."""
    case = load_case(CONFIGS / "pendulum.yaml", ROTATING)
    system = build_system(case)
    traj = integrate(system, initial_state(case, system), case.integration_settings())
    assert traj.status == "success", traj.message
    assert system.formulation.repartitions >= 2 * int(3.0 * 7.0 / (2 * np.pi))
    runs = _both(lambda *o: load_case(CONFIGS / "pendulum.yaml", [*ROTATING, *o]))
    _same_run(runs["compiled"], runs["python"], q_tol=1e-9)
    from test_partitioned import angle_reference

    fast = runs["compiled"]
    theta = angle_reference(7.0, fast.t)
    assert np.max(np.abs(fast.q[:, 0] - np.sin(theta))) < 1e-6
    assert np.max(np.abs(fast.q[:, 1] + np.cos(theta))) < 1e-6


def test_minimal_with_the_elimination_stays_on_the_python_path():
    from csim.fast.support import resolve_backend, unsupported

    case = qr_case(ELIMINATION, "stabilization.method=minimal", "simulation.t_end=0.05")
    why = unsupported(case)
    assert len(why) == 1 and "minimal" in why[0] and "elimination" in why[0]
    assert resolve_backend(case) == "python" and run_case(case).backend == "python"
    assert unsupported(qr_case(ELIMINATION)) == [] and resolve_backend(qr_case(ELIMINATION)) == "compiled"
