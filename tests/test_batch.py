"""``csim batch``: a passing and a failing batch through the command line, the JUnit report
parsed back, result files, runs that raise, Ctrl-C, and parallel workers.

The expectations are independent of csim: the pendulum's start from its case file (x0 = 0.5,
L = 1, y0 on the hanging branch, offset by -0.01 m: y0 = -sqrt(L^2 - x0^2) - 0.01), the
projection's tolerance, and conservation of energy (no loads: T + V constant).
"""
from __future__ import annotations

import contextlib
import math
import shutil
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml
from conftest import CONFIGS, invoke

import csim.compare as compare_module
from csim.batch import load_manifest, run_batch
from csim.compare import INTERRUPTED
from csim.io.hdf5 import read_result

Y0 = -math.sqrt(1.0 - 0.5**2) - 0.01
#: short pendulum runs on the Python path: no compilation, a fraction of a second each
SHORT = ["simulation.t_end=0.3", "simulation.backend=python"]

PASSING = {
    "defaults": {"set": SHORT, "expect": {"wall_time": 60}},
    "cases": [
        {"name": "start", "case": "cases/p.yaml",
         "expect": {"value": [{"name": "x", "t": 0, "expected": 0.5, "tol": 1e-12},
                              {"name": "y", "t": 0, "expected": Y0, "tol": 1e-12}]}},
        {"name": "projection", "case": "cases/p.yaml",
         "set": ["stabilization.method=projection", "initial.q_offset={}"],
         "expect": {"max_phi": 1e-13, "energy_error": 1e-6, "events": 0, "backend": "python"}},
        {"name": "comes_apart", "case": "cases/p.yaml",  # Baumgarte far beyond RK4's stability bound
         "set": ["stabilization.w=1e5", "simulation.integrator=RK4", "simulation.step=1e-3"],
         "expect": {"status": {"expected": "failed", "message": "simulation.max_phi"}, "final_time": {"max": 0.1}}},
    ]}

FAILING = {
    "defaults": {"set": SHORT},
    "cases": [
        {"name": "good", "case": "cases/p.yaml", "expect": {"value": {"name": "y", "t": 0, "expected": Y0,
                                                                       "tol": 1e-12}}},
        {"name": "bad", "case": "cases/p.yaml",
         "expect": {"max_phi": 1e-20, "value": {"name": "y", "t": 0, "expected": 0.0, "tol": 1e-3}}},
        {"name": "expected_failure", "case": "cases/p.yaml", "expect": {"status": "failed"}},
    ]}


def manifest(folder: Path, data: dict) -> Path:
    (folder / "cases").mkdir(exist_ok=True)
    shutil.copy(CONFIGS / "pendulum.yaml", folder / "cases" / "p.yaml")
    path = folder / "m.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def junit_cases(report: Path) -> dict[str, ET.Element]:
    root = ET.parse(report).getroot()
    assert root.tag == "testsuites" and len(root.findall("testsuite")) == 1
    return {case.get("name"): case for case in root.iter("testcase")}


def test_passing_batch_exits_0_with_a_clean_report_and_the_result_files(tmp_path):
    path, report = manifest(tmp_path, PASSING), tmp_path / "out" / "report.xml"
    result = invoke("batch", path, "--junit", report, "-o", tmp_path / "runs", "--jobs", "1")
    assert result.exit_code == 0, result.output
    assert "3 of 3 cases passed" in result.stdout
    rows = {line.split()[0]: line.split() for line in result.stdout.splitlines() if line.split()}
    assert rows["start"][1:3] == ["pass", "success"] and rows["comes_apart"][1:3] == ["pass", "failed"]
    suite = ET.parse(report).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures"), suite.get("errors")) == ("3", "0", "0")
    cases = junit_cases(report)
    assert list(cases) == ["start", "projection", "comes_apart"]
    assert all(c.find("failure") is None for c in cases.values())
    for name, case in cases.items():
        run = read_result(tmp_path / "runs" / f"{name}.h5")  # -o keeps each run, failed ones too
        assert case.get("time") == f"{run.wall_time:.6f}" and case.get("classname") == "csim.batch.m"
        assert run.status == ("failed" if name == "comes_apart" else "success")
    assert "pass  max_phi: measured" in cases["projection"].find("system-out").text


def test_failing_batch_exits_1_with_a_failure_per_missed_expectation(tmp_path):
    path, report = manifest(tmp_path, FAILING), tmp_path / "report.xml"
    result = invoke("batch", path, "--junit", report, "--jobs", "1")
    assert result.exit_code == 1, result.output
    assert "1 of 3 cases passed, 2 failed: bad, expected_failure" in result.stdout
    assert "batch failed: 2 of 3 case(s) missed an expectation: bad, expected_failure" in result.stderr
    assert "  bad: max_phi: measured " in result.stdout and "expected <= 1e-20" in result.stdout
    suite = ET.parse(report).getroot().find("testsuite")
    assert (suite.get("tests"), suite.get("failures")) == ("3", "3")
    cases = junit_cases(report)
    assert cases["good"].find("failure") is None
    failures = {f.get("type"): f.get("message") for f in cases["bad"].findall("failure")}
    assert set(failures) == {"max_phi", "value"}
    assert failures["max_phi"].startswith("max_phi: measured ") and failures["max_phi"].endswith("expected <= 1e-20")
    assert f"|error| = {abs(Y0):.3g}" in failures["value"]  # y(0) against 0
    (status,) = cases["expected_failure"].findall("failure")
    assert status.get("message").startswith("status: measured success (") and "expected failed" in status.text


def test_a_run_that_raises_fails_its_status_and_is_written_marked(monkeypatch, tmp_path):
    real = compare_module.run_case

    def run_case(case):
        if case.data["stabilization"]["method"] == "projection":
            raise RuntimeError("boom")
        return real(case)

    monkeypatch.setattr(compare_module, "run_case", run_case)
    batch = run_batch(load_manifest(manifest(tmp_path, PASSING)), jobs=1)
    by_name = {r.entry.name: r for r in batch.runs}
    assert not batch.passed and [r.entry.name for r in batch.failed] == ["projection"]
    messages = [o.message for o in by_name["projection"].failures]
    assert messages[0] == "status: measured failed (RuntimeError: boom), expected success"
    assert "max_phi: measured -, expected <= 1e-13 (no output samples)" in messages
    table = batch.report().tables()[0]  # the pass/fail table's cells
    assert table.column("case") == ["start", "projection", "comes_apart"]
    assert table.column("result") == ["pass", "FAIL", "pass"]
    row = table.record("projection")
    assert (row["status"], row["wall [s]"], row["max|Phi|"], row["backend"]) == ("failed", "-", "-", "-")
    outcomes = by_name["projection"].outcomes
    assert row["checks"] == f"{sum(o.passed for o in outcomes)}/{len(outcomes)}" == "3/6"
    assert table.record("comes_apart")["status"] == "failed" and table.record("start")["backend"] == "python"
    assert batch.table() == batch.report().plain() and batch.table().splitlines()[-1].startswith("2 of 3 cases")
    batch.write_results(tmp_path / "runs")
    failed = read_result(tmp_path / "runs" / "projection.h5")
    assert failed.status == "failed" and failed.message == "RuntimeError: boom" and failed.t.size == 0


@pytest.mark.parametrize("how", ["raised", "caught_by_the_driver"])
def test_ctrl_c_stops_the_batch_exits_130_and_reports_the_rest_unfinished(monkeypatch, python_sigint, tmp_path, how):
    real, calls = compare_module.run_case, []

    def run_case(case):
        calls.append(case)
        if len(calls) == 2:
            if how == "raised":
                raise KeyboardInterrupt
            with contextlib.suppress(KeyboardInterrupt):  # as the driver: Ctrl-C makes a failed run
                import signal

                signal.raise_signal(signal.SIGINT)
        return real(case)

    monkeypatch.setattr(compare_module, "run_case", run_case)
    report = tmp_path / "report.xml"
    result = invoke("batch", manifest(tmp_path, PASSING), "--junit", report, "--jobs", "1")
    assert result.exit_code == 130, result.output
    assert "batch interrupted (Ctrl-C)" in result.stderr and len(calls) == 2
    cases = junit_cases(report)
    assert cases["start"].find("failure") is None
    assert INTERRUPTED in cases["comes_apart"].find("failure").get("message")


@pytest.mark.slow  # about 8 s: two spawned workers start and import csim
def test_parallel_workers_give_the_same_outcomes(tmp_path):
    m = load_manifest(manifest(tmp_path, FAILING))
    serial, parallel = run_batch(m, jobs=1), run_batch(m, jobs=2)
    assert (serial.jobs, parallel.jobs) == (1, 2)
    for a, b in zip(serial.runs, parallel.runs, strict=True):
        assert [(o.passed, o.measured) for o in a.outcomes if o.kind != "wall_time"] == \
            [(o.passed, o.measured) for o in b.outcomes if o.kind != "wall_time"]
        assert b.result is not None and b.result.wall_time > 0


def test_compiled_runs_start_each_mechanism_first(tmp_path):
    # on a cold cache a compiled run compiles its mechanism's kernels: the first run of each
    # mechanism goes first, then the Python path, so that two workers never compile the same
    from csim.batch.runner import CaseRun, schedule

    data = {"cases": [{"name": n, "case": str(CONFIGS / c), "set": s} for n, c, s in [
        ("p1", "pendulum.yaml", []), ("py", "pendulum.yaml", ["simulation.backend=python"]),
        ("q1", "quick_return.yaml", []), ("p2", "pendulum.yaml", []), ("q2", "quick_return.yaml", [])]]}
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(data))
    runs = [CaseRun(e) for e in load_manifest(path).entries]
    assert [r.entry.name for r in schedule(runs)] == ["p1", "q1", "py", "p2", "q2"]
