"""Expectation kinds of ``csim batch``, checked on synthetic results whose figures are known
in closed form (no simulation runs here)."""
from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CONFIGS

from csim.batch.expectations import (
    EXPECTATIONS,
    BackendExpectation,
    EnergyError,
    Evaluations,
    Events,
    FinalTime,
    MaxPhi,
    MaxPhiDot,
    Range,
    StatusExpectation,
    Value,
    WallTime,
    interpolate,
    parse_expectations,
)
from csim.case import load_case
from csim.result import Result


def synthetic(t, q, qd, qdd=None, phi=None, phi_dot=None, kinetic=None, potential=None, work=None, **fields) -> Result:
    """A one-coordinate, one-constraint run with the given series (zeros where not given)."""
    t = np.asarray(t, float)
    n = t.size

    def col(a):
        return np.zeros((n, 1)) if a is None else np.asarray(a, float).reshape(n, -1)

    def flat(a):
        return np.zeros(n) if a is None else np.asarray(a, float)

    return Result(mechanism="synthetic", coordinate_names=["a"], load_names=["f"], observable_names=["o"],
                  case_yaml="", t=t, q=col(q), qd=col(qd), qdd=col(qdd), lam=np.zeros((n, 1)), phi=col(phi),
                  phi_dot=col(phi_dot), kinetic=flat(kinetic), potential=flat(potential), work=col(work),
                  loads=np.zeros((n, 1)), generalized_forces=np.zeros((n, 1)), observables=2 * col(q),
                  observable_rates=2 * col(qd), **fields)


T = np.linspace(0.0, 1.0, 11)
CUBIC = synthetic(T, T**3, 3 * T**2, 6 * T, phi=np.sin(7 * T) * 1e-6, phi_dot=T * 1e-4,
                  kinetic=1 + T, potential=-0.5 * T, work=0.25 * T, nfev=1234, wall_time=0.5,
                  event_times=np.array([0.1, 0.5, 0.9]), backend="compiled")


def test_every_kind_is_registered_by_name():
    assert list(EXPECTATIONS) == ["status", "backend", "max_phi", "max_phi_dot", "energy_error", "wall_time",
                                  "final_time", "events", "nfev", "value"]
    assert all(cls.name == name and cls.doc for name, cls in EXPECTATIONS.items())


def test_range_contains_and_reads_as_text():
    assert Range(hi=1e-10).contains(1e-10) and not Range(hi=1e-10).contains(1.1e-10)
    assert not Range(hi=1.0).contains(math.nan)  # a run without samples never passes a bound
    assert Range(lo=2.0, hi=2.0).text() == "== 2" and Range(lo=1.0).text() == ">= 1"
    assert Range(hi=1e-10).text() == "<= 1e-10" and Range(1.0, 3.0).text() == "in [1, 3]"


def test_max_phi_is_the_largest_residual_over_the_samples_or_a_window():
    phi = np.abs(np.sin(7 * T)) * 1e-6
    whole = MaxPhi(Range(hi=1e-6)).check(CUBIC)
    assert whole.passed and whole.measured == f"{phi.max():.3g}"
    window = (T >= 0.5) & (T <= 1.0)
    late = MaxPhi(Range(hi=phi[window].max() * 0.999), (0.5, 1.0)).check(CUBIC)
    assert not late.passed and late.measured == f"{phi[window].max():.3g}"
    assert late.message.startswith("max_phi over t in [0.5, 1] s: measured ")
    empty = MaxPhi(Range(hi=1.0), (2.0, 3.0)).check(CUBIC)
    assert not empty.passed and "no output samples in the window" in empty.message
    assert MaxPhiDot(Range(lo=1e-4, hi=1e-4)).check(CUBIC).passed  # max |T| * 1e-4 = 1e-4


def test_energy_error_is_the_relative_balance_of_the_summary():
    # E = T + V - W = 1 + t - 0.5 t - 0.25 t = 1 + 0.25 t: error 0.25 t, largest 0.25 at t = 1;
    # scale = max(max T = 2, max |V - V0| = 0.5, max |W| = 0.25) = 2: relative 0.125
    assert EnergyError(Range(hi=0.125)).check(CUBIC).passed
    out = EnergyError(Range(hi=0.124)).check(CUBIC)
    assert not out.passed and out.measured == "0.125"
    assert f"{CUBIC.energy_balance[0]:.3e}" in CUBIC.summary()  # the figure the summary prints


def test_energy_error_of_a_mechanism_at_rest_is_in_joules():
    rest = synthetic(T, np.zeros(11), np.zeros(11), potential=np.full(11, 5.0) + 1e-12 * T)
    out = EnergyError(Range(hi=2e-12)).check(rest)
    assert out.passed and "in J" in out.note and float(out.measured) == pytest.approx(1e-12, rel=1e-3)


def test_counts_times_and_backend():
    assert Events(Range(3.0, 3.0)).check(CUBIC).passed and not Events(Range(4.0, 4.0)).check(CUBIC).passed
    assert Evaluations(Range(lo=1234.0)).check(CUBIC).passed and not Evaluations(Range(hi=1233.0)).check(CUBIC).passed
    assert WallTime(Range(hi=0.5)).check(CUBIC).passed and not WallTime(Range(hi=0.4)).check(CUBIC).passed
    assert FinalTime(Range(0.99, 1.01)).check(CUBIC).passed
    assert BackendExpectation("compiled").check(CUBIC).passed and not BackendExpectation("python").check(CUBIC).passed


def test_status_and_message_text():
    failed = synthetic(T[:3], T[:3], T[:3], status="failed", message="constraint violation: max |Phi| exceeds "
                                                                        "simulation.max_phi")
    assert StatusExpectation("failed", "simulation.max_phi").check(failed).passed
    assert not StatusExpectation("failed", "simulation.max_steps").check(failed).passed
    out = StatusExpectation("success").check(failed)
    assert not out.passed and out.measured.startswith("failed (constraint violation")


def test_value_at_a_sample_and_between_samples():
    # q = t^3 is a cubic: Hermite interpolation from q and qd reproduces it exactly
    assert Value("a", 0.3, 0.027, 1e-15).check(CUBIC).passed
    between = Value("a", 0.37, 0.37**3, 1e-14).check(CUBIC)
    assert between.passed and "cubic Hermite between t = 0.3 and 0.4 s" in between.note
    # the rate qd = 3 t^2 is a quadratic: Hermite from qd and qdd reproduces it exactly too
    assert Value("a", 0.37, 3 * 0.37**2, 1e-14, rate=True).check(CUBIC).passed
    # an observable (2 q) with its rate; the rate of an observable is interpolated linearly
    assert Value("o", 0.37, 2 * 0.37**3, 1e-14).check(CUBIC).passed
    linear = Value("o", 0.35, 6 * (0.3**2 + 0.4**2) / 2, 1e-14, rate=True).check(CUBIC)
    assert linear.passed and "linear" in linear.note
    miss = Value("a", 0.3, 0.028, 1e-4).check(CUBIC)
    assert not miss.passed and "|error| = 0.001" in miss.message


def test_value_after_the_run_stopped_fails_saying_where_it_stopped():
    short = synthetic(T[:4], T[:4] ** 3, 3 * T[:4] ** 2, status="failed", message="blow-up")
    out = Value("a", 0.5, 0.125, 1.0).check(short)
    assert not out.passed and out.measured == "-" and "stopped before t (t = 0.3 s)" in out.note


def test_interpolate_picks_a_sample_within_round_off():
    value, how = interpolate(T, T**2, None, 0.30000000000000004)
    assert how == "" and value == T[3] ** 2
    assert interpolate(T, T**2, None, 0.0) == (0.0, "") and interpolate(T, T**2, None, 1.0) == (1.0, "")
    assert interpolate(T[:1], T[:1] + 7, None, 0.0) == (7.0, "")


# --------------------------------------------------------------------------- parsing


@pytest.fixture(scope="module")
def pendulum():
    return load_case(CONFIGS / "pendulum.yaml", ["simulation.t_end=2"])


def test_parse_reads_shorthands_ranges_and_lists(pendulum):
    problems = []
    found = parse_expectations("e", {
        "status": {"expected": "failed", "message": "max_phi"}, "max_phi": [1e-3, {"min": 1e-9, "window": [1, 2]}],
        "events": 3, "nfev": {"max": 100}, "value": {"name": "x", "t": 2, "expected": 0.1, "tol": 1e-3},
    }, pendulum, problems)
    assert problems == []
    kinds = [type(e).__name__ for e in found]
    assert kinds == ["StatusExpectation", "MaxPhi", "MaxPhi", "Events", "Evaluations", "Value"]
    assert found[1].bounds == Range(hi=1e-3) and found[2].bounds == Range(lo=1e-9) and found[2].window == (1.0, 2.0)
    assert found[3].bounds == Range(3.0, 3.0)  # a count is exact
    assert found[4].bounds == Range(hi=100.0)


@pytest.mark.parametrize("expect, fragment", [
    ({"max_ph": 1e-3}, "e.max_ph: unknown expectation (did you mean 'max_phi'?); expected one of status, backend, "),
    ({"max_phi": "small"}, "e.max_phi: got 'small' (string); expected a number (an upper bound), or a mapping"),
    ({"max_phi": {"min": 2, "max": 1}}, "e.max_phi: got min 2 > max 1; expected min <= max"),
    ({"max_phi": {"max": 1, "window": [3, 5]}}, "e.max_phi.window: got [3, 5] (list); expected [t0, t1]"),
    ({"max_phi": {"maximum": 1}}, "e.max_phi: got {'maximum': 1} (mapping); expected a number"),
    ({"events": 2.5}, "e.events: got 2.5 (number); expected an integer >= 0 (the exact count)"),
    ({"status": "ok"}, "e.status: got 'ok' (string); expected one of success, failed"),
    ({"backend": "numba"}, "e.backend: got 'numba' (string); expected one of compiled, interpreted, python"),
    ({"value": {"name": "q1", "t": 1, "expected": 0, "tol": 1}},
     "e.value.name: got 'q1' (string); expected a coordinate or observable of pendulum: x, y"),
    ({"value": {"name": "x", "t": 3, "expected": 0, "tol": 1}}, "e.value.t: got 3 (integer); expected a time in s "
                                                                "with 0 <= t <= t_end = 2"),
    ({"value": {"name": "x", "t": 1, "tol": 0}}, "e.value.expected: missing; expected a number"),
    ({"value": {"name": "x", "t": 1, "expected": 0, "tol": 0}}, "e.value.tol: got 0 (integer); expected a number > 0"),
    ({"value": {"name": "x", "t": 1, "expected": 0, "tol": 1, "tols": 1}},
     "e.value.tols: unknown key (did you mean 'tol'?)"),
    ({"wall_time": []}, "e.wall_time: got an empty list"),
])
def test_parse_names_the_key_the_value_and_what_was_expected(pendulum, expect, fragment):
    problems = []
    assert parse_expectations("e", expect, pendulum, problems) == []
    assert any(fragment in p for p in problems), problems


def test_energy_error_of_a_kinematic_analysis_is_rejected():
    slider = load_case(CONFIGS / "slider_crank.yaml")
    problems = []
    assert parse_expectations("e", {"energy_error": 1e-9}, slider, problems) == []
    assert "e.energy_error: the case is a kinematic analysis" in problems[0]
