"""The compiled backend (csim.fast) against the reference Python path and the reference solution.

The first test to run compiles the kernels (tens of seconds, once per cache directory);
every later one reuses them.
"""
from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIGS, qr_case

from csim.case import load_case
from csim.errors import CaseError
from csim.fast.module import load_module
from csim.fast.runner import pack_problem
from csim.pipeline import build_system, initial_state, run_case
from csim.solver.simulate import integrate

pytest.importorskip("numba")


def _system(*overrides):
    case = qr_case(*overrides)
    system = build_system(case)
    return case, system, initial_state(case, system)


@pytest.fixture(scope="module")
def kernels():
    _, system, _ = _system()
    return load_module(system.model.definition)


@pytest.mark.parametrize("method", ["none", "baumgarte", "sliding_mode", "projection"])
def test_compiled_rhs_equals_python_rhs(kernels, method):
    """dy/dt and the multipliers at random states (off the manifold, every mode) agree to round-off."""
    # gains per constraint, each different, so that a swapped or shared gain shows
    gains = {"baumgarte": ["stabilization.w=[20, 30]", "stabilization.d=[0.7, 1.0]"],
             "sliding_mode": ["stabilization.Lambda=[20, 35]", "stabilization.K=[15, 40]",
                              "stabilization.k=[0.5, 2.0]", "stabilization.switching=sqrt", "stabilization.eps=1e-3"]}
    _, system, y0 = _system(f"stabilization.method={method}", *gains.get(method, []))
    par, pf, pi = pack_problem(system)
    rng = np.random.default_rng(1)
    for _ in range(20):
        y = y0 + rng.normal(scale=[0.3, 0.05, 0.05, 2, 2, 2, 10, 10])
        mode = rng.random(system.loads.n_switches) < 0.5
        code, f, x = kernels.rhs_entry(0.0, y, mode, par, pf, pi)
        assert code == 0
        expected = system.rhs(0.0, y, mode)
        scale = np.maximum(1.0, np.abs(expected))
        assert np.max(np.abs(f - expected) / scale) < 1e-12
        ev = system.evaluate(0.0, y, mode)
        assert np.allclose(x, np.concatenate((ev.qdd, ev.lam)), rtol=1e-11, atol=1e-9)


def test_compiled_projection_equals_python(kernels):
    _, system, y0 = _system("stabilization.method=projection")
    par, pf, pi = pack_problem(system)
    y = y0 + np.array([1e-3, -2e-3, 1e-3, 0.01, -0.02, 0.03, 0, 0])
    code, _, out = kernels.project_entry(y, par, pf, pi)
    assert code == 0
    assert np.allclose(out, system.project(0.0, y), rtol=0, atol=1e-13)


def test_compiled_dop853_run_equals_python_run():
    """Same events (to 1e-12 s), same steps, same final state (to 1e-9) on the case with events."""
    case, system, y0 = _system("simulation.t_end=3", "simulation.rtol=1e-9", "simulation.atol=1e-9")
    settings = case.integration_settings()
    from csim.fast import integrate_compiled

    fast = integrate_compiled(system, y0, settings)
    ref = integrate(system, y0, settings)
    assert fast.status == ref.status == "success"
    assert len(fast.event_times) == len(ref.event_times) > 30
    assert np.max(np.abs(np.subtract(fast.event_times, ref.event_times))) < 1e-12
    assert fast.event_labels == ref.event_labels
    assert fast.nsteps == ref.nsteps
    assert np.array_equal(fast.t, ref.t) and np.array_equal(fast.mode, ref.mode)
    m = system.m
    assert np.max(np.abs(fast.y[:, :2 * m] - ref.y[:, :2 * m])) < 1e-9
    # the work states are in J (up to 1e6): relative round-off
    assert np.max(np.abs(fast.y[:, 2 * m:] - ref.y[:, 2 * m:])) < 1e-12 * np.max(np.abs(ref.y[:, 2 * m:])) * 1e3


def test_backend_key_selects_the_path():
    fast = run_case(qr_case("simulation.t_end=0.5", "simulation.backend=compiled"))
    slow = run_case(qr_case("simulation.t_end=0.5", "simulation.backend=python"))
    auto = run_case(qr_case("simulation.t_end=0.5"))
    assert fast.ok and slow.ok
    assert (fast.backend, slow.backend, auto.backend) == ("compiled", "python", "compiled")
    assert run_case(qr_case("simulation.t_end=0.5", "simulation.integrator=BDF")).backend == "python"
    # the same work on both paths: the Python driver reuses the dense output it built to look for events
    assert fast.nfev == slow.nfev and fast.nsteps == slow.nsteps
    assert np.allclose(fast.q, slow.q, rtol=0, atol=1e-10)
    assert np.allclose(fast.lam, slow.lam, rtol=1e-9, atol=1e-6)


def test_compiled_dop853_agrees_with_tight_reference(reference):
    res = run_case(qr_case("simulation.backend=compiled", "stabilization.method=projection"))
    assert res.ok and res.backend == "compiled"
    assert abs(res.q[-1, 0] - reference["q1"]) < 1e-6
    assert res.max_phi < 1e-12
    assert np.allclose(res.event_times, reference["events"], atol=1e-6)


def test_compiled_rk4_converges_at_order_4():
    """Cutting force off (a smooth problem): the error at t = 1 s falls 16-fold per halving of h."""
    errs = []
    base = ["simulation.backend=compiled", "simulation.integrator=RK4", "simulation.t_end=1",
            "loads.cutting_force=0"]
    ref = run_case(qr_case(*base, "simulation.step=1e-4"))
    for h in (4e-3, 2e-3, 1e-3):
        res = run_case(qr_case(*base, f"simulation.step={h}"))
        assert res.backend == "compiled"
        errs.append(abs(res.q[-1, 0] - ref.q[-1, 0]))
    orders = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(np.abs(orders - 4) < 0.3), orders


def test_rk4_compiled_equals_python():
    case, system, y0 = _system("simulation.integrator=RK4", "simulation.step=1e-3", "simulation.t_end=1")
    from csim.fast import integrate_compiled

    fast = integrate_compiled(system, y0, case.integration_settings())
    ref = integrate(system, y0, case.integration_settings())
    assert fast.nfev == ref.nfev and fast.event_times == pytest.approx(ref.event_times, abs=1e-12)
    assert np.max(np.abs(fast.y[:, :6] - ref.y[:, :6])) < 1e-10


def test_divergence_checks_fire():
    res = run_case(qr_case("simulation.backend=compiled", "simulation.max_phi=1e-9", "simulation.rtol=1e-4",
                           "simulation.atol=1e-4"))
    assert res.status == "failed" and "constraint violation" in res.message and "max_phi" in res.message
    assert res.backend == "compiled"
    res = run_case(qr_case("simulation.backend=compiled", "simulation.max_steps=10"))
    assert res.status == "failed" and "simulation.max_steps = 10" in res.message
    res = run_case(qr_case("simulation.backend=compiled", "simulation.min_step=1.0"))
    assert res.status == "failed" and "step-size collapse" in res.message
    res = run_case(qr_case("simulation.backend=compiled", "simulation.max_events=3"))
    assert res.status == "failed" and "simulation.max_events = 3" in res.message
    # the same failures as the Python path, at the same instant
    slow = run_case(qr_case("simulation.backend=python", "simulation.max_events=3"))
    assert res.message == slow.message and res.t.size == slow.t.size


@pytest.mark.parametrize("overrides", [
    (),
    ("simulation.integrator=RK4", "simulation.step=0.005"),
    ("stabilization.method=projection", "simulation.integrator=RK4", "simulation.step=0.005"),
    ("simulation.chatter_events=5",),
])
def test_chatter_fails_fast_and_alike_on_both_backends(overrides):
    """A stalling drive (issue 13): both stop at the same event with the same message and evaluations."""
    fast = run_case(qr_case("loads.torque=160000", "simulation.backend=compiled", *overrides))
    slow = run_case(qr_case("loads.torque=160000", "simulation.backend=python", *overrides))
    assert fast.backend == "compiled" and fast.status == "failed"
    assert fast.message.startswith("chattering load law: cutting_force: ds/dt = 0 (velocity sign) switched")
    assert fast.message == slow.message and fast.nfev == slow.nfev
    assert fast.event_labels == slow.event_labels
    assert fast.event_times == pytest.approx(slow.event_times, abs=1e-12)
    n = 5 if overrides == ("simulation.chatter_events=5",) else 20
    assert len(fast.event_times) == 23 + n  # before: 100,001 events, 1.7 million evaluations (DOP853)
    assert fast.nfev < 5_000


@pytest.mark.parametrize("override, key", [
    ("stabilization.method=augmented_lagrangian", "stabilization.method 'augmented_lagrangian'"),
    ("simulation.integrator=BDF", "simulation.integrator 'BDF'"),
])
def test_unsupported_combinations_are_rejected(override, key):
    with pytest.raises(CaseError) as info:
        qr_case("simulation.backend=compiled", override)
    text = str(info.value)
    assert "simulation.backend: got 'compiled'" in text and key in text


def test_auto_falls_back_to_python_for_unsupported_combinations():
    from csim.fast import resolve_backend

    assert resolve_backend(qr_case("simulation.integrator=BDF")) == "python"
    assert resolve_backend(qr_case("formulation.method=elimination")) == "compiled"
    assert resolve_backend(qr_case()) == "compiled"
    assert resolve_backend(qr_case("simulation.backend=python")) == "python"


def test_unloadable_kernels_fall_back_under_auto_and_fail_under_compiled(monkeypatch):
    import csim.pipeline as pipeline

    def broken(*args):
        raise OSError("no space left on device")
    monkeypatch.setattr(pipeline, "prepare_compiled", broken)
    auto = run_case(qr_case("simulation.t_end=0.2"))
    assert auto.ok and auto.backend == "python" and "compiled kernels could not be loaded" in auto.message
    forced = run_case(qr_case("simulation.t_end=0.2", "simulation.backend=compiled"))
    assert forced.status == "failed" and "OSError: no space left on device" in forced.message
    assert forced.failure == "backend"


def test_an_unwritable_cache_folder_is_no_error(monkeypatch, tmp_path):
    from csim.fast import module

    blocked = tmp_path / "a_file"
    blocked.write_text("")
    monkeypatch.setattr(module, "_FALLBACK_DIR", None)
    path = module._writable(blocked / "fast" / "m_key.py")
    assert path.name == "m_key.py" and path.parent != blocked / "fast" and path.parent.is_dir()


@pytest.mark.parametrize("config, overrides", [
    ("quick_return.yaml", ["stabilization.method=projection"]),
    ("quick_return.yaml", ["stabilization.method=sliding_mode", "stabilization.Lambda=[20, 35]"]),
    ("quick_return.yaml", ["stabilization.method=baumgarte", "simulation.integrator=RK4", "simulation.step=2e-3"]),
    ("pendulum.yaml", ["stabilization.method=baumgarte"]),  # no loads, no switches, a perturbed start
    ("pendulum.yaml", ["stabilization.method=projection"]),
], ids=["qr-projection", "qr-sliding", "qr-baumgarte-rk4", "pendulum-baumgarte", "pendulum-projection"])
def test_whole_runs_agree_with_the_python_path(config, overrides):
    from csim.case import load_case

    CONFIGS = Path(__file__).resolve().parents[1] / "configs"
    base = [*overrides, "simulation.t_end=1.5"]
    fast = run_case(load_case(CONFIGS / config, [*base, "simulation.backend=compiled"]))
    slow = run_case(load_case(CONFIGS / config, [*base, "simulation.backend=python"]))
    assert (fast.backend, slow.backend) == ("compiled", "python")
    assert fast.ok and slow.ok, (fast.message, slow.message)
    assert (fast.nfev, fast.nsteps) == (slow.nfev, slow.nsteps)
    np.testing.assert_allclose(fast.event_times, slow.event_times, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(fast.phi, slow.phi, rtol=0, atol=1e-12)


def test_a_run_records_the_kernel_load_and_a_cold_one_says_it_compiled():
    res = run_case(qr_case("simulation.t_end=0.1", "simulation.backend=compiled"))
    assert res.kernel_load_time > 0.0
    res.kernel_load_time = 0.5  # as on a warm cache: no notice
    assert "compilation:" not in res.summary()
    res.kernel_load_time = 30.0  # as on a cold cache
    assert "compilation:       30.0 s before the run (the first run of this mechanism" in res.summary()


@pytest.mark.parametrize("overrides", [
    ["stabilization.method=baumgarte"],
    ["stabilization.method=sliding_mode", "stabilization.Lambda=[20, 35]"],
], ids=["baumgarte", "sliding"])
def test_compiled_sample_evaluation_equals_python_evaluation(overrides):
    """The result's samples evaluated in one compiled call equal ConstrainedSystem.evaluate, sample by sample,
    on one trajectory with both load modes (observables and their rates included)."""
    from csim.fast import integrate_compiled
    from csim.pipeline import assemble_result

    case, system, y0 = _system(*overrides, "simulation.t_end=0.6")
    traj = integrate_compiled(system, y0, case.integration_settings())
    assert traj.mode.any() and not traj.mode.all()
    fast = assemble_result(case, system, traj, 0.0, backend="compiled")
    slow = assemble_result(case, system, traj, 0.0, backend="python")
    assert len(case.mechanism.observables) > 0
    for name in ("qdd", "lam", "phi", "phi_dot", "loads", "generalized_forces", "kinetic", "potential",
                 "observables", "observable_rates"):
        a, b = getattr(fast, name), getattr(slow, name)
        assert a.shape == b.shape and np.isfinite(a).all(), name
        np.testing.assert_allclose(a, b, rtol=1e-11, atol=1e-9 * max(1.0, np.max(np.abs(b))), err_msg=name)


# --- minimal coordinates (coordinate partitioning): the same core functions on both backends -------


def _both(case):
    """(compiled, python) trajectories of a case, each from a fresh system (the partition is state)."""
    from csim.fast import integrate_compiled

    settings = case.integration_settings()
    system = build_system(case)
    fast = integrate_compiled(system, initial_state(case, system), settings)
    system = build_system(case)
    return fast, integrate(system, initial_state(case, system), settings), system


def _assert_same_run(fast, ref, m, atol):
    assert fast.status == ref.status and fast.message == ref.message
    assert fast.nfev == ref.nfev and fast.nsteps == ref.nsteps
    assert np.array_equal(fast.t, ref.t) and np.array_equal(fast.mode, ref.mode)
    assert fast.event_labels == ref.event_labels
    assert fast.event_times == pytest.approx(ref.event_times, abs=1e-12)
    scale = np.maximum(1.0, np.max(np.abs(ref.y[:, :2 * m]), axis=0))
    assert np.max(np.abs(fast.y[:, :2 * m] - ref.y[:, :2 * m]) / scale) < atol


@pytest.mark.parametrize("overrides", [
    ("simulation.t_end=3", "simulation.rtol=1e-9", "simulation.atol=1e-9"),
    ("simulation.integrator=RK4", "simulation.step=1e-3", "simulation.t_end=1"),
])
def test_compiled_minimal_run_equals_python_run(overrides):
    """The quick-return with its events: same steps, evaluations, events and samples; q, qd to 1e-10."""
    fast, ref, system = _both(qr_case("stabilization.method=minimal", *overrides))
    assert fast.status == "success" and len(fast.event_times) > 10
    _assert_same_run(fast, ref, system.m, 1e-10)  # measured 1.3e-11 (DOP853, 1 s), 1.2e-12 (RK4, 2 s)


def test_compiled_minimal_keeps_the_assembly_of_andrews_mechanism():
    """Andrews' mechanism at rtol = 1e-8, where trial stages far ahead need the branch check (issue 15)."""
    from test_andrews import Q_END

    case = load_case(CONFIGS / "andrews.yaml", ["stabilization.method=minimal", "simulation.rtol=1e-8",
                                                 "simulation.atol=1e-8"])
    fast, ref, system = _both(case)
    assert fast.status == "success"
    # velocities up to 1.4e3 rad/s: relative to each coordinate's scale; measured 2.1e-10
    _assert_same_run(fast, ref, system.m, 1e-9)
    np.testing.assert_allclose(fast.y[-1, :system.m], Q_END, rtol=0, atol=5e-6)
    assert np.max(np.abs(np.diff(fast.y[:, 2:system.m], axis=0))) < 0.3  # no change of closure


def test_compiled_minimal_repartitions_as_python_does():
    """A pendulum over the top: x and y each stop determining the other twice a turn."""
    case = load_case(CONFIGS / "pendulum.yaml", ["stabilization.method=minimal", "initial.q={x: 0.0}",
                                                  "initial.qd={x: 7.0}", "initial.q_offset={}", "simulation.t_end=3",
                                                  "simulation.rtol=1e-10", "simulation.atol=1e-10"])
    fast, ref, system = _both(case)
    assert fast.status == "success" and system.repartitions >= 6
    _assert_same_run(fast, ref, system.m, 1e-10)


def test_minimal_failures_read_the_same_on_both_backends():
    fast = run_case(load_case(CONFIGS / "pendulum.yaml", ["stabilization.method=minimal", "simulation.backend=compiled",
                                                          "stabilization.minimal_tol=1e-300",
                                                          "stabilization.minimal_max_iter=1"]))
    slow = run_case(load_case(CONFIGS / "pendulum.yaml", ["stabilization.method=minimal", "simulation.backend=python",
                                                          "stabilization.minimal_tol=1e-300",
                                                          "stabilization.minimal_max_iter=1"]))
    assert fast.backend == "compiled" and fast.status == slow.status == "failed"
    assert "Newton-Raphson for the dependent coordinates" in fast.message and "x = 0.5" in fast.message
    assert fast.message == slow.message and fast.failure == slow.failure == "newton"


def test_auto_runs_minimal_compiled():
    from csim.fast import resolve_backend

    assert resolve_backend(qr_case("stabilization.method=minimal")) == "compiled"
    assert resolve_backend(qr_case("stabilization.method=ggl", "simulation.integrator=Radau")) == "compiled"


def test_one_copy_of_the_kernels_is_the_source_unchanged_and_runs_every_method():
    """One copy in the cache (csim.fast.module), file for file the source: imported under its own name it
    is the compiled one, and the package's own source the interpreted backend. Every method runs it."""
    from csim.fast import module
    from csim.fast.runner import _kernels_for

    source = {path.name: path.read_text() for path in module._sources(module.KERNELS)}
    assert module.kernels_source() == source
    copy = module.load_kernels()
    assert copy.COMPILED is True and importlib.import_module("csim.fast.kernels").COMPILED is False
    assert {path.name: path.read_text() for path in module._sources(module.kernels_path())} == source
    # every file of the copy is the copy's own (a file that imported csim.fast.kernels would run the
    # interpreted source inside the compiled copy): relative imports only
    files = {name: mod for name, mod in sys.modules.items() if name.startswith(copy.__name__ + ".")}
    assert len(files) == len(source) - 2 and copy.__name__ + ".interpreted" not in files, sorted(files)
    assert all(mod.__file__.startswith(str(module.kernels_path())) for mod in files.values())
    absolute = re.compile(r"^\s*(from|import) csim\.fast\.kernels", re.M)
    assert not [name for name, text in source.items() if absolute.search(text)]
    systems = [_system(f"stabilization.method={method}", "simulation.t_end=0.1")[1] for method in ("none", "minimal")]
    assert all(_kernels_for(system) is copy for system in systems)


def test_the_loop_refuses_to_run_without_the_address_of_its_right_hand_side():
    """The loop calls feval through pi[PI_FEVAL] (csim.fast.kernels.calls.call_feval): arguments packed
    without it are refused with a message, not a jump to address 0."""
    from csim.fast import module
    from csim.fast.layout import PI_FEVAL
    from csim.fast.runner import _arguments

    case, system, y0 = _system("simulation.t_end=0.1")
    args = list(_arguments(system, y0, case.integration_settings(), 10, module.load_kernels()))
    pi = args[5]
    assert pi[PI_FEVAL] == module.addressed_function(module.load_kernels(), "feval") != 0
    pi[PI_FEVAL] = 0
    with pytest.raises(ValueError, match="PI_FEVAL"):
        module.load_kernels().integrate(*args)


def test_a_call_by_address_returns_the_result_and_passes_an_exception_on():
    """csim.fast.kernels.calls.call_feval on a small function of feval's argument types: the result and
    the outputs come back, and an exception raised behind the address reaches Python (numba's own call
    passes it on; read as a result, it would have been status 0, OK)."""
    import types as pytypes

    from numba import njit

    from csim.fast import module
    from csim.fast.kernels.addresses import FEVAL_TYPES, call_feval

    @njit  # compiled by addressed_function, for FEVAL_TYPES
    def target(t, y, mode, located, par, pf, pi, w, piv, f, info):
        if t < 0:
            raise ValueError("negative time")
        f[0] = 2 * t + y[0]
        return np.int64(7)

    @njit
    def caller(addr, t, y, mode, located, par, pf, pi, w, piv, f, info):
        return call_feval(addr, t, y, mode, located, par, pf, pi, w, piv, f, info)

    fake = pytypes.ModuleType("fake_kernels")
    fake.feval, fake.FEVAL_TYPES, fake.COMPILED = target, FEVAL_TYPES, True
    address = module.addressed_function(fake, "feval")
    f = np.zeros(1)
    rest = (np.zeros(1, np.bool_), True, np.zeros(1), np.zeros(1), np.zeros(1, np.int64), np.zeros(1),
            np.zeros(1, np.int64), f, np.zeros(2))
    assert caller(address, 1.5, np.array([1.0]), *rest) == 7 and f[0] == 4.0
    with pytest.raises(ValueError, match="negative time"):
        caller(address, -1.0, np.array([1.0]), *rest)
