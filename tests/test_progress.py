"""The progress bar and the status of slow steps (csim.progress), and the run summary's wording."""
from __future__ import annotations

import io

import numpy as np
from rich.console import Console

from csim.progress import RunProgress, reporting, status
from csim.result import Result


def terminal() -> Console:
    """A console that writes to a string and claims to be a terminal."""
    return Console(file=io.StringIO(), force_terminal=True, width=100, color_system=None)


def plain() -> Console:
    return Console(file=io.StringIO(), force_terminal=False, width=100)


def test_the_bar_shows_time_and_eta_on_a_terminal():
    console = terminal()
    with reporting(console=console), RunProgress(2.0, delay=0.0) as bar:
        bar(0.5)
        bar(1.0)
        assert bar.drawn
    text = console.file.getvalue()
    assert "simulating" in text and "t = 1/2 s" in text and "ETA" in text and "50%" in text


def test_the_bar_waits_for_its_delay():
    console = terminal()
    with reporting(console=console), RunProgress(2.0, delay=60.0) as bar:
        bar(1.0)
        assert not bar.drawn
    assert console.file.getvalue() == ""


def test_no_bar_when_quiet_off_a_terminal_or_outside_reporting():
    for kwargs in (dict(enabled=False, console=terminal()), dict(console=plain())):
        console = kwargs["console"]
        with reporting(**kwargs), RunProgress(1.0, delay=0.0) as bar:
            bar(0.5)
            assert not bar.enabled
        assert console.file.getvalue() == ""
    bar = RunProgress(1.0, delay=0.0)  # library use: no reporting() around it
    bar(0.5)
    assert not bar.enabled and not bar.drawn


def test_status_is_a_spinner_on_a_terminal_and_draws_with_the_bar():
    console = terminal()
    with reporting(console=console), status("compiling kernels (first run of this mechanism, ~30 s)"), \
            RunProgress(1.0, delay=0.0) as bar:  # both at once: drawn one above the other
        bar(0.25)
    text = console.file.getvalue()
    assert "compiling kernels (first run of this mechanism, ~30 s)" in text
    assert "t = 0.25/1 s" in text


def test_status_off_a_terminal_is_one_plain_line_for_a_slow_step_only():
    console = plain()
    with reporting(console=console):
        with status("deriving the model", delay=0.0):
            pass
        with status("loading the model", delay=60.0):  # a fast step leaves no trace
            pass
    assert console.file.getvalue() == "csim: deriving the model ...\n"


def test_status_shows_nothing_outside_reporting_or_when_quiet(capsys):
    with status("deriving the model", delay=0.0):
        pass
    console = plain()
    with reporting(enabled=False, console=console), status("deriving the model", delay=0.0):
        pass
    assert console.file.getvalue() == "" and capsys.readouterr().err == ""


def rest_result(kinetic, potential) -> Result:
    n = len(kinetic)
    return Result(mechanism="pendulum", coordinate_names=["x", "y"], load_names=[], observable_names=[],
                  case_yaml="", t=np.linspace(0, 1, n), q=np.zeros((n, 2)), qd=np.zeros((n, 2)), qdd=np.zeros((n, 2)),
                  lam=np.zeros((n, 1)), phi=np.zeros((n, 1)), phi_dot=np.zeros((n, 1)),
                  kinetic=np.asarray(kinetic, float), potential=np.asarray(potential, float), work=np.zeros((n, 0)),
                  loads=np.zeros((n, 0)), generalized_forces=np.zeros((n, 2)), observables=np.zeros((n, 0)),
                  observable_rates=np.zeros((n, 0)))


def test_the_energy_balance_of_a_run_at_rest_is_in_joules():
    for kinetic, potential, shown in (([0, 0, 0], [0, 0, 0], "0.000e+00 J"),
                                      ([0, 1e-20, 0], [-8.0, -8.0 + 2**-48, -8.0], "3.553e-15 J")):
        res = rest_result(kinetic, potential)
        assert res.energy_scale_is_zero
        line = [x for x in res.summary().splitlines() if x.startswith("energy balance:")][0]
        assert line.startswith(f"energy balance:    {shown} (max |T + V - T0 - V0 - W|, in J")
        assert "e-308" not in res.summary()


def test_the_energy_balance_of_a_moving_run_is_relative():
    res = rest_result([0, 2.0, 4.0], [0, -2.0, -4.0 + 1e-6])
    assert not res.energy_scale_is_zero
    assert "energy balance:    2.500e-07 (max |T + V - T0 - V0 - W| / 4 J)" in res.summary()


def test_the_summary_gives_the_reason_for_a_python_fallback():
    res = rest_result([0, 1.0], [0, -1.0])
    assert "python backend:" not in res.summary()
    res.backend_reason = "numba is not installed"
    assert "python backend:    not compiled because numba is not installed" in res.summary()
