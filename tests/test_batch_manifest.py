"""Batch manifests: reading, defaults, and every problem reported at once with its key path
(the library's ManifestError, and exit 2 without a traceback at the command line)."""
from __future__ import annotations

import shutil
from pathlib import Path

import pytest
import yaml
from conftest import CONFIGS, assert_bad_input, invoke

from csim.batch import load_manifest
from csim.batch.expectations import MaxPhi, StatusExpectation, WallTime
from csim.errors import CaseError, ManifestError


def write(folder: Path, data, name: str = "m.yaml") -> Path:
    path = folder / name
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture
def folder(tmp_path):
    """A manifest folder with a case file in a subfolder (case paths are relative to the manifest)."""
    (tmp_path / "cases").mkdir()
    shutil.copy(CONFIGS / "pendulum.yaml", tmp_path / "cases" / "p.yaml")
    return tmp_path


def problems_of(path: Path, **kw) -> list[str]:
    with pytest.raises(ManifestError) as info:
        load_manifest(path, **kw)
    assert isinstance(info.value, CaseError)  # the CLI reports it as bad input (exit 2)
    return info.value.problems


def test_entries_with_defaults_and_relative_case_paths(folder):
    path = write(folder, {
        "defaults": {"set": ["simulation.t_end=0.5"], "expect": {"wall_time": 30, "max_phi": 1.0}},
        "cases": [
            {"name": "a", "case": "cases/p.yaml", "set": ["simulation.t_end=0.2"], "expect": {"max_phi": 1e-3}},
            {"name": "b.c-d_e", "case": "cases/p.yaml", "expect": {"status": "failed"}},
        ]})
    m = load_manifest(path)
    a, b = m.entries
    assert a.case_file == folder / "cases" / "p.yaml"
    assert a.overrides == ["simulation.t_end=0.5", "simulation.t_end=0.2"]  # the entry's own last
    assert a.case.data["simulation"]["t_end"] == 0.2 and b.case.data["simulation"]["t_end"] == 0.5
    # an entry's own kind replaces the default's; status success is implied where none is stated
    assert [type(e) for e in a.expectations] == [StatusExpectation, MaxPhi, WallTime]
    assert a.expectations[0].expected == "success" and a.expectations[1].bounds.hi == 1e-3
    assert [type(e) for e in b.expectations] == [StatusExpectation, WallTime, MaxPhi]
    assert b.expectations[0].expected == "failed" and b.expectations[2].bounds.hi == 1.0
    assert [e.name for e in load_manifest(path, only=["b.c-d_e"]).entries] == ["b.c-d_e"]


def test_every_problem_at_once_each_naming_its_key(folder):
    path = write(folder, {
        "default": {},
        "cases": [
            {"name": "ok", "case": "cases/p.yaml", "expct": {}},
            {"name": "ok", "case": "cases/p.yaml"},
            {"name": "bad name", "case": "cases/p.yaml"},
            {"name": "missing", "case": "cases/nowhere.yaml"},
            {"name": "badset", "case": "cases/p.yaml", "set": ["simulation.t_endd=1"]},
            {"name": "badvalue", "case": "cases/p.yaml", "set": ["simulation.t_end=-1"]},
            {"name": "unknown", "case": "cases/p.yaml", "expect": {"max_ph": 1e-3}},
            {"name": "notlist", "case": "cases/p.yaml", "set": "simulation.t_end=1"},
            "just text",
        ]})
    problems = "\n".join(problems_of(path))
    for fragment in [
        "default: unknown key (did you mean 'defaults'?); valid keys here: defaults, cases",
        "cases[0].expct: unknown key (did you mean 'expect'?); valid keys here: name, case, set, expect",
        "cases[1].name: got 'ok' again; expected a name not used by another entry",
        "cases[2].name: got 'bad name' (string); expected a name of letters, digits",
        "cases[3] (missing): ", "nowhere.yaml: no such case file",
        "cases[4] (badset): --set simulation.t_endd: unknown key (did you mean 'simulation.t_end'?)",
        "cases[5] (badvalue): simulation.t_end: got -1.0 (number); expected a number > 0",
        "cases[6].expect.max_ph: unknown expectation (did you mean 'max_phi'?); expected one of status, backend, "
        "max_phi, max_phi_dot, energy_error, wall_time, final_time, events, nfev, value",
        "cases[7].set: got 'simulation.t_end=1' (string); expected a list of KEY=VALUE strings",
        "cases[8]: got 'just text' (string); expected a mapping with keys name, case, set, expect",
    ]:
        assert fragment in problems, problems


def test_defaults_are_checked_against_each_entrys_case(folder):
    path = write(folder, {"defaults": {"expect": {"value": {"name": "q1", "t": 0, "expected": 0, "tol": 1}}},
                          "cases": [{"name": "p", "case": "cases/p.yaml"}]})
    assert problems_of(path) == ["defaults.expect (for cases[0]).value.name: got 'q1' (string); expected a "
                                 "coordinate or observable of pendulum: x, y, angle"]


@pytest.mark.parametrize("text, fragment", [
    ("cases: [", "not valid YAML"),
    ("- a\n- b\n", "at the top level; expected a mapping with keys defaults, cases"),
    ("defaults: {}\n", "cases: missing; expected a list of entries"),
    ("cases: []\n", "cases: got [] (list); expected a list of entries"),
    ("cases:\n  - {name: a}\n", "cases[0].case: missing; expected the path of a case file, relative to the manifest"),
    ("cases:\n  - {name: a, case: cases/p.yaml, expect: [max_phi]}\n",
     "cases[0].expect: got ['max_phi'] (list); expected a mapping of expectation kind: spec"),
    ("cases:\n  - {name: a, case: cases/p.yaml}\n  - {name: a, case: cases/p.yaml, name: b}\n", "duplicate key 'name'"),
])
def test_malformed_manifests(folder, text, fragment):
    assert any(fragment in p for p in problems_of(write(folder, text))), problems_of(write(folder, text))


def test_missing_manifest_and_unknown_only_name(folder):
    assert problems_of(folder / "none.yaml") == [f"{folder / 'none.yaml'}: no such manifest file"]
    path = write(folder, {"cases": [{"name": "p", "case": "cases/p.yaml"}]})
    assert problems_of(path, only=["q"]) == ["--only q: no entry of that name; expected one of p"]


# --------------------------------------------------------------------------- the command line


def test_cli_bad_manifest_exits_2_naming_the_key(folder):
    path = write(folder, {"cases": [{"name": "p", "case": "cases/p.yaml", "expect": {"energy_err": 1e-3}}]})
    assert_bad_input(invoke("batch", path), "cases[0].expect.energy_err: unknown expectation (did you mean "
                                            "'energy_error'?)", "expected one of status, backend")


def test_cli_missing_case_file_exits_2(folder):
    path = write(folder, {"cases": [{"name": "p", "case": "cases/gone.yaml"}]})
    assert_bad_input(invoke("batch", path), "cases[0] (p): ", "gone.yaml: no such case file")


def test_cli_bad_options_exit_2_before_running(folder):
    path = write(folder, {"cases": [{"name": "p", "case": "cases/p.yaml"}]})
    assert_bad_input(invoke("batch", path, "--jobs", "0"), "--jobs: got 0; expected a whole number >= 1")
    assert_bad_input(invoke("batch", path, "--junit", folder / "report.txt"),
                     "--junit", "report.txt: expected an XML file name ending in .xml")
    assert_bad_input(invoke("batch", path, "--junit", path), "that is an input file")
    assert_bad_input(invoke("batch", path, "-o", path), "that is a file; expected a folder for the result files")
    assert_bad_input(invoke("batch", path, "--only", "q"), "--only q: no entry of that name; expected one of p")
    assert not (folder / "report.txt").exists()


def test_the_shipped_accuracy_manifest_is_valid_and_run_by_ci():
    """configs/batch/accuracy.yaml loads without a problem (its runs are CI's `make batch`)."""
    root = CONFIGS.parent
    m = load_manifest(CONFIGS / "batch" / "accuracy.yaml")
    names = [e.name for e in m.entries]
    assert len(names) == len(set(names)) >= 25
    assert all(e.expectations for e in m.entries)
    assert "make batch" in (root / ".ci" / "run").read_text()
    assert "csim batch configs/batch/accuracy.yaml --junit results/batch_junit.xml" in (root / "Makefile").read_text()
