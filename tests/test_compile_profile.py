"""bench/compile_profile.py: numba's compile events turned into each function's own compile time."""
from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from compile_profile import exclusive_times

numba = pytest.importorskip("numba")
from numba.core import event  # noqa: E402


def _dispatcher(module, name):
    def fn():
        pass

    fn.__module__, fn.__qualname__ = module, name
    return SimpleNamespace(py_func=fn)


def _events(*spans):
    """(timestamp, Event) pairs of numba:compile from (name, start, end) spans, ordered in time."""
    marks = []
    for name, start, end in spans:
        data = {"dispatcher": _dispatcher(f"csim_fast_kernels_x.{name.split('.')[0]}", name.split(".")[1])}
        marks.append((start, event.Event("numba:compile", event.EventStatus.START, data)))
        marks.append((end, event.Event("numba:compile", event.EventStatus.END, data)))
    return sorted(marks, key=lambda mark: mark[0])


def test_a_nested_compile_is_counted_once_in_its_own_function():
    # driver.integrate compiles from 0 to 10 s, and within it system.rhs (2-7 s), which compiles calls.terms (3-4 s)
    times = exclusive_times(_events(("driver.integrate", 0.0, 10.0), ("system.rhs", 2.0, 7.0),
                                    ("calls.terms", 3.0, 4.0), ("radau._radau_step", 8.0, 9.5)))
    assert times == pytest.approx({"driver:integrate": 3.5, "system:rhs": 4.0, "calls:terms": 1.0,
                                   "radau:_radau_step": 1.5})
    assert sum(times.values()) == pytest.approx(10.0)  # the outermost compile's wall time, shared out


def test_the_events_of_a_real_compile_name_its_function():
    @numba.njit
    def probe_profiled(x):
        return x + 1

    with event.install_recorder("numba:compile") as recorder:
        probe_profiled(1)
    times = exclusive_times(recorder.buffer)
    assert any(name.endswith(":test_the_events_of_a_real_compile_name_its_function.<locals>.probe_profiled")
               for name in times), times
    assert all(seconds >= 0 for seconds in times.values())
