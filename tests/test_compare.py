"""``csim compare``: one case with several stabilization methods, measured against a reference run."""
from __future__ import annotations

import contextlib
import math
import pickle
import signal
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

import csim.compare as compare_module
from csim.cli import app
from csim.compare import INTERRUPTED, ReferenceSettings, compare, split_method
from csim.errors import CaseError, ResultFileError
from csim.io.hdf5 import read_comparison, read_result
from csim.solver.stabilizers import STABILIZERS

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
QR = CONFIGS / "quick_return.yaml"
PENDULUM = CONFIGS / "pendulum.yaml"

#: a short, loose quick-return case: every run takes a fraction of a second
SHORT = ["simulation.t_end=0.5", "output.dt=0.01", "simulation.rtol=1e-6", "simulation.atol=1e-6"]
METHODS = ["none", "baumgarte", "sliding_mode", "projection"]
#: Baumgarte with w h = 100, far beyond RK4's stability bound (about 2.8): it blows up at once
BLOW_UP = ["stabilization.w=1e5", "simulation.integrator=RK4", "simulation.step=1e-3"]


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def sets(overrides):
    return [x for item in overrides for x in ("--set", item)]


def assert_clean_exit(result, code: int) -> None:
    assert result.exit_code == code, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exc_info
    assert "Traceback" not in result.output


def row(stdout: str, method: str) -> list[str]:
    """The fields of the first table row of ``method``."""
    return next(line.split() for line in stdout.splitlines() if line.split()[:1] == [method])


def text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


# --------------------------------------------------------------------------- end to end


@pytest.fixture(scope="module")
def compared(tmp_path_factory):
    """``csim compare`` of four methods on the short quick-return case (default jobs)."""
    out = tmp_path_factory.mktemp("compare") / "qr_compare.h5"
    result = invoke("compare", QR, "--methods", ",".join(METHODS), "-o", out, *sets(SHORT))
    return out, result


def test_cli_writes_a_group_per_method_and_prints_a_row_each(compared):
    out, result = compared
    assert_clean_exit(result, 0)
    assert out.is_file()
    with h5py.File(out, "r") as fh:
        assert text(fh.attrs["kind"]) == "comparison"
        assert [text(m) for m in fh.attrs["methods"]] == METHODS
        assert {"csim_version", "format_version", "case", "reference_method", "reference_tol"} <= set(fh.attrs)
        assert set(fh) == {*METHODS, "reference", "summary"}  # no /work_precision without --tolerances
        for name, ds in fh["summary"].items():
            assert ds.shape == (len(METHODS),), name
            assert "units" in ds.attrs, name
    for method in METHODS:
        run = read_result(out, group=method)
        assert run.status == "success", (method, run.message)
        assert run.t.size == 51 and run.t[-1] == pytest.approx(0.5)
        assert run.q.shape == (51, 3) and run.phi.shape == (51, 2)
        assert yaml.safe_load(run.case_yaml)["stabilization"]["method"] == method
        assert row(result.stdout, method)[1] == "success"
    ref = read_result(out, group="reference")
    ref_case = yaml.safe_load(ref.case_yaml)
    assert ref.status == "success" and ref.t.size == 51
    assert ref_case["stabilization"]["method"] == "projection"
    assert ref_case["simulation"]["integrator"] == "DOP853"
    assert ref_case["simulation"]["rtol"] == ref_case["simulation"]["atol"] == 1e-12
    stdout = result.stdout
    for label in ("reference:  projection, DOP853, rtol = atol = 1e-12: success", "rtol = atol = 1e-06",
                  "max|Phi|", "final|Phi|", "max|Phi_q qd|", "motion err", "wall [s]", "RHS evals", "jobs = ",
                  f"result:     {out}"):
        assert label in stdout, label
    with pytest.raises(ResultFileError, match="a comparison file.*group=NAME"):
        read_result(out)  # the root is not a run


def test_motion_error_is_max_abs_q_minus_reference_from_the_file(compared):
    out, result = compared
    assert_clean_exit(result, 0)
    table = read_comparison(out)
    assert table.methods == METHODS and table.has_reference and table.work_precision is None
    assert list(table.summary["method"]) == METHODS
    ref = read_result(out, group="reference")
    for i, method in enumerate(METHODS):
        run = read_result(out, group=method)
        error = np.max(np.abs(run.q - ref.q))
        assert 0 < error < 1e-3
        assert table.summary["motion_error"][i] == pytest.approx(error, rel=1e-12)
        assert table.summary["final_error"][i] == pytest.approx(np.max(np.abs(run.q[-1] - ref.q[-1])), rel=1e-12)
        assert table.summary["max_phi"][i] == pytest.approx(np.max(np.abs(run.phi)), rel=1e-12)
        assert table.summary["max_phi_dot"][i] == pytest.approx(np.max(np.abs(run.phi_dot)), rel=1e-12)
        assert table.summary["nfev"][i] == run.nfev > 0
        assert table.summary["wall_time"][i] == run.wall_time > 0
        fields = row(result.stdout, method)
        assert fields[2] == f"{np.max(np.abs(run.phi)):.2e}"
        assert fields[5] == f"{error:.2e}"
        assert fields[8] == str(run.nfev)
    # projection keeps the constraints to its tolerance; no stabilization does not
    assert table.summary["max_phi"][METHODS.index("projection")] < 1e-12
    assert table.summary["max_phi"][METHODS.index("none")] > 1e-8


def test_jobs_1_and_2_give_the_same_numbers():
    kw = dict(methods=["none", "projection"], overrides=["simulation.t_end=0.5"])
    serial, parallel = compare(PENDULUM, jobs=1, **kw), compare(PENDULUM, jobs=2, **kw)
    assert (serial.jobs, parallel.jobs) == (1, 2)
    for a, b in zip([serial.reference_run, *serial.runs], [parallel.reference_run, *parallel.runs], strict=True):
        for name in ("method", "tolerance", "status", "nfev", "nsteps"):
            assert getattr(a, name) == getattr(b, name), name
        for name in ("max_phi", "final_phi", "max_phi_dot", "motion_error", "final_error", "error_until"):
            assert getattr(a, name) == pytest.approx(getattr(b, name), rel=1e-12, nan_ok=True), name
        np.testing.assert_allclose(a.result.q, b.result.q, rtol=1e-12, atol=0)
        assert b.wall_time > 0
    assert all(r.ok and math.isfinite(r.motion_error) for r in parallel.runs)
    back = pickle.loads(pickle.dumps(serial.runs[0].result))  # what a worker sends back
    np.testing.assert_array_equal(back.q, serial.runs[0].result.q)


def test_a_method_that_blows_up_is_a_failed_row_and_the_others_finish(tmp_path):
    out = tmp_path / "blow_up.h5"
    result = invoke("compare", QR, "--methods", "none,baumgarte,projection", "-o", out, "--jobs", "1",
                    *sets([*SHORT, *BLOW_UP]))
    assert_clean_exit(result, 0)  # every run ran: a failed one is a finding (--strict: exit 1)
    assert "1 run(s) failed, each a row of" in result.stderr and str(out) in result.stderr
    assert "baumgarte" in result.stderr.split("failed, each a row of", 1)[1]
    assert row(result.stdout, "baumgarte")[1] == "failed"
    assert "baumgarte: failed: " in result.stdout
    assert row(result.stdout, "none")[1] == row(result.stdout, "projection")[1] == "success"
    # csim run's warning before the run, once, for the method and step it concerns
    warnings = [line for line in result.stderr.splitlines() if line.startswith("csim: warning:")]
    assert warnings == ["csim: warning: baumgarte at step = 1.00e-03 s: stabilization.w * simulation.step = 100 "
                        "lies outside RK4's stability interval (2.785): the constraint error will grow; choose "
                        "simulation.step <= 2.51e-05 s or a smaller gain"]
    assert read_result(out, group="baumgarte").failure in ("blow-up", "drift")
    table = read_comparison(out)
    status = dict(zip(table.summary["method"], table.summary["status"]))
    assert status == {"none": "success", "baumgarte": "failed", "projection": "success"}
    failed = read_result(out, group="baumgarte")
    assert failed.status == "failed" and failed.message
    assert failed.t[-1] < 0.5  # stopped at the blow-up
    assert yaml.safe_load(failed.case_yaml)["simulation"]["step"] == 1e-3
    for i, method in enumerate(table.summary["method"]):
        finite = math.isfinite(table.summary["final_error"][i])
        assert finite == (method != "baumgarte")  # no final error for a run that did not reach t_end


def test_stability_warnings_come_once_per_method_and_step():
    from csim.compare.comparison import case_warnings
    from csim.compare.plan import plan_comparison

    plan = plan_comparison(QR, ["none", "baumgarte", "sliding_mode"], [1e-3, 2e-4], [*SHORT, *BLOW_UP],
                           ReferenceSettings(), 1)
    warnings = case_warnings(plan, "projection")
    assert [w.split(":")[0] for w in warnings] == ["baumgarte at step = 1.00e-03 s", "baumgarte at step = 2.00e-04 s"]
    assert "stabilization.w * simulation.step = 20 lies outside" in warnings[1]
    heard = []
    compare(QR, ["none"], overrides=[*SHORT, *BLOW_UP], jobs=1, warn=heard.append)
    assert heard == []  # no gain: nothing to warn of


def test_an_exception_in_a_run_is_a_failed_row(monkeypatch, tmp_path):
    real = compare_module.run_case

    def run_case(case):
        if case.data["stabilization"]["method"] == "baumgarte":
            raise RuntimeError("boom")
        return real(case)

    monkeypatch.setattr(compare_module, "run_case", run_case)
    c = compare(PENDULUM, methods=["none", "baumgarte"], overrides=["simulation.t_end=0.2"], jobs=1)
    by_method = {r.method: r for r in c.runs}
    assert by_method["none"].ok and math.isfinite(by_method["none"].motion_error)
    assert not by_method["baumgarte"].ok and by_method["baumgarte"].message == "RuntimeError: boom"
    assert not c.ok and "baumgarte: failed: RuntimeError: boom" in c.table()
    c.write(tmp_path / "c.h5")
    assert read_result(tmp_path / "c.h5", group="baumgarte").status == "failed"


@pytest.mark.parametrize("how", ["raised", "caught_by_the_driver"])
def test_ctrl_c_stops_the_comparison(monkeypatch, python_sigint, how):
    real, calls = compare_module.run_case, []

    def run_case(case):
        calls.append(case.data["stabilization"]["method"])
        if len(calls) == 2:  # during the first method, after the reference
            if how == "raised":
                raise KeyboardInterrupt
            with contextlib.suppress(KeyboardInterrupt):  # as the driver: Ctrl-C makes a failed run
                signal.raise_signal(signal.SIGINT)
        return real(case)

    monkeypatch.setattr(compare_module, "run_case", run_case)
    c = compare(PENDULUM, methods=["none", "baumgarte", "projection"], overrides=["simulation.t_end=0.2"], jobs=1)
    assert c.interrupted and not c.ok
    assert len(calls) == 2  # nothing ran after the interrupt
    assert c.reference_run.ok
    assert [r.message for r in c.runs[1:]] == [INTERRUPTED, INTERRUPTED]
    assert "interrupted" in c.table()


def test_reference_failure_leaves_errors_unavailable():
    bad_reference = ReferenceSettings(method="baumgarte", integrator="RK4", tol=1e-3)
    c = compare(QR, methods=["none"], overrides=[*SHORT, *BLOW_UP], reference=bad_reference, jobs=1)
    assert not c.reference_run.ok and c.runs[0].ok
    assert math.isnan(c.runs[0].motion_error) and math.isnan(c.runs[0].final_error)
    assert "reference run failed" in c.runs[0].error_note
    assert "reference: failed:" in c.table() and "motion errors are unavailable" in c.table()


# --------------------------------------------------------------------------- work-precision study


def test_tolerance_study_records_work_against_precision(tmp_path):
    out = tmp_path / "wp.h5"
    result = invoke("compare", QR, "--methods", "none,projection", "--tolerances", "1e-8,1e-4,1e-6", "-o", out,
                    "--jobs", "1", *sets(SHORT))
    assert_clean_exit(result, 0)
    wp = read_comparison(out).work_precision
    columns = ("method", "tolerance", "wall_time", "nfev", "nsteps", "motion_error", "final_error", "max_phi",
               "max_phi_dot", "status")
    assert set(columns) <= set(wp)
    assert {len(v) for v in wp.values()} == {6}
    assert all(read_comparison(out).units[f"work_precision/{c}"] is not None for c in columns)
    assert list(wp["method"]) == ["none"] * 3 + ["projection"] * 3
    np.testing.assert_array_equal(wp["tolerance"], [1e-4, 1e-6, 1e-8] * 2)  # loosest first
    assert set(wp["status"]) == {"success"}
    for method in ("none", "projection"):
        sel = wp["method"] == method
        assert np.all(np.diff(wp["motion_error"][sel]) < 0), method  # tighter is more accurate ...
        assert np.all(np.diff(wp["nfev"][sel]) > 0), method  # ... and costs more
    assert "work-precision (rtol = atol = 1e-04, 1e-06, 1e-08)" in result.stdout
    wp_lines = [line for line in result.stdout.split("work-precision")[1].splitlines() if line.split()[:1] in
                (["none"], ["projection"])]
    assert len(wp_lines) == 6
    # the method groups hold the tightest run
    assert yaml.safe_load(read_result(out, group="none").case_yaml)["simulation"]["rtol"] == 1e-8
    with h5py.File(out) as fh:
        assert text(fh.attrs["tolerance_kind"]) == "rtol=atol"
        assert fh["work_precision/motion_error"].attrs["units"]


def test_tolerances_of_a_fixed_step_integrator_are_steps():
    c = compare(PENDULUM, methods=["none"], tolerances=[1e-2, 5e-3],
                overrides=["simulation.t_end=0.5", "simulation.integrator=RK4", "initial.q_offset={}"], jobs=1)
    assert c.tolerance_kind == "step"
    assert [r.nsteps for r in c.runs] == [50, 100]
    assert [yaml.safe_load(r.result.case_yaml)["simulation"]["step"] for r in c.runs] == [1e-2, 5e-3]
    assert c.runs[1].motion_error < c.runs[0].motion_error


def test_default_methods_are_every_registered_one_each_with_an_integrator_that_runs_it():
    c = compare(PENDULUM, overrides=["simulation.t_end=0.1"], jobs=1)
    assert [split_method(m)[0] for m in c.methods] == list(STABILIZERS)  # registry order
    # the case integrates with DOP853; GGL is a DAE and gets the Radau it needs
    assert "ggl:Radau" in c.methods and not c.skipped
    assert all(r.ok for r in c.runs)
    assert c.method_runs["ggl:Radau"].result.max_phi < 1e-10


def test_a_method_may_name_its_own_integrator():
    c = compare(PENDULUM, methods=["none", "none:RK45"], overrides=["simulation.t_end=0.1"], jobs=1)
    integrators = [yaml.safe_load(r.result.case_yaml)["simulation"]["integrator"] for r in c.runs]
    assert integrators == ["DOP853", "RK45"]
    with pytest.raises(CaseError, match="unknown integrator 'Euler'"):
        compare(PENDULUM, methods=["none:Euler"], jobs=1)
    with pytest.raises(CaseError, match="ggl"):
        compare(PENDULUM, methods=["ggl"], jobs=1)  # named without an integrator: strict


def test_each_row_records_the_setting_its_own_integrator_ran_at(tmp_path):
    # an RK4 case: the RK4 rows ran at the step, the Radau row at the case's rtol and atol
    out = tmp_path / "c.h5"
    c = compare(PENDULUM, methods=["none", "none:Radau"], jobs=1,
                overrides=["simulation.t_end=0.1", "simulation.integrator=RK4", "simulation.step=1e-2",
                           "simulation.rtol=1e-6", "simulation.atol=1e-9"])
    assert [(r.tolerance, r.tolerance_kind) for r in c.runs] == [(1e-2, "step"), (1e-6, "rtol")]
    assert "rtol 1e-06" in c.table() and "step 1e-02" in c.table()
    c.write(out)
    table = read_comparison(out).summary
    assert [text(k) for k in table["tolerance_kind"]] == ["step", "rtol"]
    np.testing.assert_array_equal(table["tolerance"], [1e-2, 1e-6])


def test_a_study_does_not_mix_steps_and_tolerances():
    with pytest.raises(CaseError, match="separate studies"):
        compare(PENDULUM, methods=["none", "none:RK4"], tolerances=[1e-3], jobs=1)
    # by default, the methods of the other kind are left out, and say why
    c = compare(PENDULUM, tolerances=[1e-4], jobs=1,
                overrides=["simulation.t_end=0.05", "simulation.integrator=RK4"])
    assert "ggl:Radau" in c.skipped and "one study sets one kind" in c.skipped["ggl:Radau"]
    assert {r.tolerance_kind for r in c.runs} == {"step"}


def test_the_reference_may_name_its_own_integrator():
    c = compare(PENDULUM, methods=["none"], overrides=["simulation.t_end=0.1"], jobs=1,
                reference=ReferenceSettings(method="projection:Radau", tol=1e-10))
    assert c.reference_run.ok
    assert yaml.safe_load(c.reference_run.result.case_yaml)["simulation"]["integrator"] == "Radau"
    assert "projection, Radau, rtol = atol = 1e-10" in c.table()


def test_one_backend_for_every_run_keeps_wall_times_comparable(monkeypatch):
    import csim.compare.plan as plan_module

    # every built-in ODE method has a compiled path now: stand one in that has none
    real = plan_module.resolve_backend
    monkeypatch.setattr(plan_module, "resolve_backend",
                        lambda case: "python" if case.stabilization.method == "baumgarte" else real(case))
    c = compare(PENDULUM, methods=["none", "baumgarte"], overrides=["simulation.t_end=0.1"], jobs=1)
    assert {r.result.backend for r in c.runs} == {"python"}
    assert "baumgarte has no compiled path" in c.backend_note and "backend:    python for every run" in c.table()
    monkeypatch.undo()
    c = compare(PENDULUM, methods=["none", "baumgarte"], overrides=["simulation.t_end=0.1"], jobs=1)
    assert {r.result.backend for r in c.runs} == {"compiled"} and not c.backend_note
    assert c.table_columns(c.runs)["backend"] == ["compiled", "compiled"]


def test_a_method_whose_integrator_only_python_has_runs_there_alone():
    # scipy's BDF runs on the Python path only: it keeps the others off Python no longer (the default set, ggl
    # included, runs compiled)
    c = compare(PENDULUM, methods=["none", "ggl:Radau", "projection:BDF"], overrides=["simulation.t_end=0.1"], jobs=1)
    assert c.table_columns(c.runs)["backend"] == ["compiled", "compiled", "python"]
    assert c.backend_note.startswith("python for projection:BDF (no compiled path for its integrator)")


# --------------------------------------------------------------------------- bad input


BAD = [
    ("unknown_method", ["--methods", "none,bogus"],
     ["--methods: unknown method 'bogus'", "valid names: " + ", ".join(STABILIZERS)]),
    ("duplicate_method", ["--methods", "none,baumgarte,none"], ["--methods: method 'none' given twice"]),
    ("empty_methods", ["--methods", ""], ["--methods"]),
    ("tolerance_not_a_number", ["--tolerances", "1e-6,abc"], ["--tolerances: got 'abc'", "positive numbers"]),
    ("tolerance_negative", ["--tolerances", "-1"], ["--tolerances: got '-1'", "positive numbers"]),
    ("tolerance_twice", ["--tolerances", "1e-6,1e-6"], ["--tolerances: 1e-06 given twice"]),
    ("tolerance_below_the_validator_limit", ["--tolerances", "1e-20"], ["simulation.rtol", "1e-20"]),
    ("jobs_zero", ["--jobs", "0"], ["--jobs: got 0", ">= 1"]),
    ("reference_method", ["--reference-method", "bogus"], ["--reference-method: unknown method 'bogus'"]),
    ("reference_tol", ["--reference-tol", "0"], ["--reference-tol: got '0'"]),
    ("combination_the_case_rejects", ["--methods", "none,projection", "--set", "simulation.integrator=LSODA"],
     ["method projection: ", "LSODA"]),
    ("bad_set", ["--set", "simulation.tend=3"], ["--set simulation.tend: unknown key"]),
]


@pytest.mark.parametrize("extra, fragments", [b[1:] for b in BAD], ids=[b[0] for b in BAD])
def test_bad_input_exits_2_before_running(tmp_path, extra, fragments):
    out = tmp_path / "out.h5"
    result = invoke("compare", QR, "-o", out, *extra)
    assert_clean_exit(result, 2)
    assert result.stderr.startswith("csim: error:")
    assert result.stdout == ""
    for fragment in fragments:
        assert fragment in result.stderr, (fragment, result.stderr)
    assert not out.exists()


def test_missing_case_file_and_unwritable_output(tmp_path):
    result = invoke("compare", tmp_path / "nope.yaml")
    assert_clean_exit(result, 2)
    assert "no such case file" in result.stderr
    (tmp_path / "adir").mkdir()
    result = invoke("compare", QR, "-o", tmp_path / "adir", "--methods", "none")
    assert_clean_exit(result, 2)
    assert "cannot write, it is a directory" in result.stderr


def test_library_rejects_bad_input_before_running():
    with pytest.raises(CaseError, match="unknown method 'nope'"):
        compare(PENDULUM, methods=["none", "nope"])
    with pytest.raises(CaseError, match="jobs: got 0"):
        compare(PENDULUM, methods=["none"], jobs=0)
    with pytest.raises(CaseError, match=r"tolerances: got -1\.0"):
        compare(PENDULUM, methods=["none"], tolerances=[1e-6, -1.0])


def test_help_has_an_example():
    result = invoke("compare", "--help")
    assert_clean_exit(result, 0)
    for fragment in ("Example", "--methods", "--tolerances", "--jobs", "--reference-method", "--reference-tol",
                     "--set", "--quiet", "--output"):
        assert fragment in result.stdout, fragment


FAILING = ("--methods", "none,baumgarte", "--set", "simulation.integrator=RK4", "--set", "simulation.step=1e-2",
           "--set", "stabilization.w=400", "--set", "simulation.t_end=1", "-j", "1", "-q")


def test_a_failed_run_is_a_finding_and_strict_makes_it_an_error(tmp_path):
    """w h = 4 is beyond RK4's bound for Baumgarte: that run fails, every run ran."""
    result = invoke("compare", QR, *FAILING, "-o", tmp_path / "a.h5")
    assert result.exit_code == 0, result.output
    assert "1 run(s) failed" in result.output and "baumgarte" in result.output
    assert read_comparison(tmp_path / "a.h5").summary["status"].tolist() == ["success", "failed"]
    strict = invoke("compare", QR, *FAILING, "--strict", "-o", tmp_path / "b.h5")
    assert strict.exit_code == 1 and "comparison incomplete" in strict.output
    assert (tmp_path / "b.h5").is_file()


def test_repeat_keeps_the_median_wall_time_and_says_so(tmp_path, monkeypatch):
    import csim.compare as package

    times = iter([3.0, 1.0, 2.0] * 4)
    real = package.run_case

    def timed(case):
        result = real(case)
        result.wall_time = next(times)
        return result

    monkeypatch.setattr(package, "run_case", timed)
    result = invoke("compare", QR, "--methods", "none", "--repeat", "3", "-j", "1", "-q", "--set",
                    "simulation.t_end=0.1", "-o", tmp_path / "r.h5")
    assert result.exit_code == 0, result.output
    file = read_comparison(tmp_path / "r.h5")
    assert file.summary["wall_time"].tolist() == [2.0] and int(file.attrs["repeat"]) == 3
    bad = invoke("compare", QR, "--repeat", "0", "-o", tmp_path / "x.h5")
    assert bad.exit_code == 2 and "--repeat" in bad.output
