"""The interpreted backend: the compiled kernels' own source, run by Python, takes the compiled loop's steps.

``csim.fast.kernels`` is one source: numba compiles a copy of it (:mod:`csim.fast.module`), and
Python runs it as it is (``simulation.backend: interpreted``, and what ``CSIM_PURE_PYTHON=1``
runs). Both call the same machine code of the model functions (C or cfuncs, through their
addresses). So every step, event and sample agrees to the last bit, for every integrator and
method the kernels run, the partitioned system of ``minimal`` included; a failure fails at the
same step with the same message. A check of the compiled loop's logic that its own numba
typing cannot see.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import CONFIGS, qr_case

from csim.case import load_case
from csim.fast.runner import integrate_compiled
from csim.pipeline import build_system, initial_state, run_case
from csim.result import failure_kind

#: every integrator of the kernels, each with another method (minimal: the partitioned system)
COMBINATIONS = [("DOP853", "none"), ("RK4", "baumgarte"), ("RK45", "sliding_mode"), ("Tsit5", "projection"),
                ("Vern7", "baumgarte"), ("Radau", "none"), ("DOP853", "minimal")]


def _both(case):
    """(compiled, interpreted): the trajectories of ``case`` from one initial state."""
    system = build_system(case)
    y0, settings = initial_state(case, system), case.integration_settings()
    return integrate_compiled(system, y0, settings), integrate_compiled(system, y0, settings, interpreted=True)


def _assert_same_steps(fast, slow):
    assert (fast.status, fast.failure, fast.message) == (slow.status, slow.failure, slow.message)
    assert (fast.nfev, fast.nsteps, fast.njev, fast.nlu) == (slow.nfev, slow.nsteps, slow.njev, slow.nlu)
    assert (fast.event_times, fast.event_labels) == (slow.event_times, slow.event_labels)
    np.testing.assert_array_equal(fast.t, slow.t)
    np.testing.assert_array_equal(fast.y, slow.y)
    np.testing.assert_array_equal(fast.mode, slow.mode)


@pytest.mark.parametrize(("integrator", "method"), COMBINATIONS)
def test_the_interpreted_kernels_take_the_compiled_steps(integrator, method):
    """The quick-return with its switching cutting force: steps, events and samples, bit for bit."""
    fast, slow = _both(qr_case(f"simulation.integrator={integrator}", f"stabilization.method={method}",
                               "simulation.t_end=0.4", "simulation.step=0.002"))
    assert fast.status == "success", fast.message
    assert fast.event_times, "no event: the event location would go unchecked"
    _assert_same_steps(fast, slow)


def test_a_failure_fails_at_the_same_step_with_the_same_message():
    """No stabilization, a bound on |Phi| the drift crosses: both stop at the same step."""
    fast, slow = _both(qr_case("simulation.max_phi=1e-9", "simulation.rtol=1e-4", "simulation.atol=1e-6"))
    assert (fast.status, fast.failure) == ("failed", "drift"), fast.message
    _assert_same_steps(fast, slow)


@pytest.mark.parametrize(("sets", "kind"), [
    (["simulation.max_steps=40"], "max steps"),
    (["simulation.max_events=2"], "chatter"),
    (["simulation.integrator=Radau", "simulation.min_step=1e-3"], "step collapse"),
    (["simulation.integrator=RK4", "simulation.step=0.2"], "drift"),
])
def test_each_way_to_fail_fails_alike(sets, kind):
    """The loop's other exits: too many steps, chattering events, Radau's step collapse, RK4's drift."""
    fast, slow = _both(qr_case("simulation.t_end=0.5", *sets))
    assert (fast.status, fast.failure) == ("failed", kind), fast.message
    _assert_same_steps(fast, slow)


def test_minimal_on_an_overconstrained_spatial_linkage():
    """Bricard's mechanism (IFToMM A04) for 10 s with minimal: the partitioned system on the branch of a
    linkage whose closure equations are dependent, 206 steps."""
    fast, slow = _both(load_case(CONFIGS / "iftomm" / "a04_bricard.yaml"))
    assert fast.status == "success" and fast.nsteps > 100, fast.message
    _assert_same_steps(fast, slow)


def test_drives_run_interpreted():
    """A driven mechanism (its drives are constraint rows of the model, their work a state)."""
    case = load_case(CONFIGS / "slider_crank_dynamic.yaml", ["simulation.t_end=0.3"])
    assert case.driven
    fast, slow = _both(case)
    assert fast.status == "success", fast.message
    _assert_same_steps(fast, slow)


def test_a_run_records_the_same_quantities():
    """run_case end to end: the samples' evaluation (the kernels' evaluate_samples) interpreted too."""
    sets = ["simulation.t_end=0.2", "stabilization.method=baumgarte"]
    fast = run_case(qr_case(*sets, "simulation.backend=compiled"))
    slow = run_case(qr_case(*sets, "simulation.backend=interpreted"))
    assert (fast.backend, slow.backend) == ("compiled", "interpreted") and slow.ok, slow.message
    for name in ("q", "qd", "qdd", "lam", "phi", "phi_dot", "loads", "generalized_forces", "kinetic", "potential",
                 "observables"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name), err_msg=name)
    assert slow.backend_reason == "" and "not compiled because" not in slow.summary()  # it was asked for


def test_a_blow_up_fails_as_the_compiled_run_does():
    """A torque of 1e170 N m: the first step's norms overflow. Python raises where machine code goes on
    with inf (a float divided by zero); the loop's norms are numpy's, so both fail alike."""
    fast, slow = _both(qr_case("loads.torque=1e170", "simulation.t_end=0.1"))
    assert fast.status == "failed", fast.message
    _assert_same_steps(fast, slow)


def test_an_exception_in_the_interpreted_loop_is_a_failed_run(monkeypatch):
    """What Python still raises on the way to a blow-up comes back as a failed run of kind backend, saying so."""
    import csim.fast.kernels.driver as driver

    def raises(*args):
        raise ZeroDivisionError("float division by zero")

    case = qr_case("simulation.t_end=0.1")
    system = build_system(case)
    monkeypatch.setattr(driver, "_start", raises)
    run = integrate_compiled(system, initial_state(case, system), case.integration_settings(), interpreted=True)
    assert (run.status, run.failure, run.t.size) == ("failed", "backend", 0)
    assert "ZeroDivisionError" in run.message and "run it compiled" in run.message
    assert "tests/test_interpreted.py" in run.message and "(raises)" in run.message  # where it raised
    assert failure_kind(run.message) == "backend"


@pytest.mark.parametrize("error", [ValueError("operands could not be broadcast together"),
                                   IndexError("index 7 is out of bounds"), TypeError("a bug")])
def test_any_other_exception_of_the_interpreted_loop_is_raised(monkeypatch, error):
    """A bug, a deliberate check of the loop or a plug-in's own error is raised as it is (the backend is
    for debugging), not reported as a blow-up."""
    import csim.fast.kernels.driver as driver

    def raises(*args):
        raise error

    case = qr_case("simulation.t_end=0.1")
    system = build_system(case)
    monkeypatch.setattr(driver, "_start", raises)
    with pytest.raises(type(error), match=str(error)):
        integrate_compiled(system, initial_state(case, system), case.integration_settings(), interpreted=True)


def test_python_model_functions_give_the_same_motion(monkeypatch):
    """Without C and numba the model functions are the cfunc source run as Python: the same steps and,
    to round-off, the same motion as the C functions."""
    from csim.fast.module import load_model

    case = qr_case("simulation.t_end=0.2")
    system = build_system(case)
    y0, settings = initial_state(case, system), case.integration_settings()
    reference = integrate_compiled(system, y0, settings, interpreted=True)
    monkeypatch.setenv("CSIM_MODEL_BACKEND", "python")
    assert load_model(system.model.definition, interpreted=True).backend == "python"
    run = integrate_compiled(system, y0, settings, interpreted=True)
    assert run.status == "success" and (run.nsteps, run.event_times) == (reference.nsteps, reference.event_times)
    np.testing.assert_allclose(run.y, reference.y, rtol=1e-11, atol=1e-11)
    with pytest.raises(ValueError, match="CSIM_MODEL_BACKEND=python"):
        integrate_compiled(system, y0, settings)


PURE_STEPS = """
import sys
import numpy as np
from csim.case import load_case
from csim.fast.runner import integrate_compiled
from csim.pipeline import build_system, initial_state
out = {}
for i, (config, sets) in enumerate(eval(sys.argv[1])):
    case = load_case(config, sets)
    system = build_system(case)
    run = integrate_compiled(system, initial_state(case, system), case.integration_settings(), interpreted=True)
    out.update({f"t{i}": run.t, f"y{i}": run.y, f"counts{i}": [run.nfev, run.nsteps, run.njev, run.nlu],
                f"events{i}": np.asarray(run.event_times), f"status{i}": run.status})
np.savez(sys.argv[2], numba="numba" in sys.modules, **out)
"""

#: (config, settings): every integrator and method of COMBINATIONS, minimal on Bricard's mechanism (its Newton
#: solves on the branch), drives
PURE_COMBINATIONS = [
    *((CONFIGS / "quick_return.yaml", [f"simulation.integrator={integrator}", f"stabilization.method={method}",
                                       "simulation.t_end=0.4", "simulation.step=0.002"])
      for integrator, method in COMBINATIONS),
    (CONFIGS / "iftomm" / "a04_bricard.yaml", []),
    (CONFIGS / "slider_crank_dynamic.yaml", ["simulation.t_end=0.3"]),
]


def test_pure_python_takes_the_compiled_steps(tmp_path):
    """CSIM_PURE_PYTHON=1: the loop and every core function run as Python (numba is never imported), and
    still take the compiled run's steps to the last bit (numpy's complex division, which Radau's complex LU
    used, rounded otherwise). In this process the core is compiled, so only here does the test see it as Python."""
    runs = [(str(config), extra) for config, extra in PURE_COMBINATIONS]
    out = tmp_path / "pure.npz"
    env = dict(os.environ, CSIM_PURE_PYTHON="1")
    done = subprocess.run([sys.executable, "-c", PURE_STEPS, repr(runs), str(out)],
                          env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    pure = np.load(out)
    assert not pure["numba"]
    for i, (config, extra) in enumerate(runs):
        case = load_case(config, extra)
        system = build_system(case)
        fast = integrate_compiled(system, initial_state(case, system), case.integration_settings())
        assert fast.status == str(pure[f"status{i}"]) == "success", (extra, fast.message)
        assert [fast.nfev, fast.nsteps, fast.njev, fast.nlu] == pure[f"counts{i}"].tolist(), extra
        np.testing.assert_array_equal(fast.event_times, pure[f"events{i}"], err_msg=str(extra))
        np.testing.assert_array_equal(fast.t, pure[f"t{i}"], err_msg=str(extra))
        np.testing.assert_array_equal(fast.y, pure[f"y{i}"], err_msg=str(extra))


PURE_RUN = """
import json, sys
from csim.case import load_case
from csim.pipeline import run_case
result = run_case(load_case(sys.argv[1], ["simulation.t_end=0.3"]))
print(json.dumps(dict(backend=result.backend, reason=result.backend_reason, ok=result.ok, message=result.message,
                      numba="numba" in sys.modules)))
"""


def test_pure_python_runs_the_kernels_without_numba():
    """CSIM_PURE_PYTHON=1: ``auto`` runs the kernels interpreted, says why, and never imports numba."""
    env = dict(os.environ, CSIM_PURE_PYTHON="1")
    done = subprocess.run([sys.executable, "-c", PURE_RUN, str(CONFIGS / "pendulum.yaml")], env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    got = json.loads(done.stdout.strip().splitlines()[-1])
    assert got == dict(backend="interpreted", reason="CSIM_PURE_PYTHON=1 rules numba out", ok=True,
                       message=got["message"], numba=False), got
