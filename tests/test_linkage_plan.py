"""A linkage's plan: its plain data filed beside the cached build, read by a warm run without sympy."""
from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys

import numpy as np
import pytest
from conftest import CONFIGS, ROOT

from csim.errors import CacheError
from csim.linkage.plan import LightLinkage, LinkagePlan, load_linkage, plan_path, read_plan, write_plan

#: a short run of each case
SHORT = ["simulation.t_end=0.2"]


def _sections(config: str) -> tuple[dict, dict]:
    """The ``mechanism`` and ``initial`` sections of a case, validated (as case validation builds them)."""
    from csim.case import SCHEMA, read_case_file
    from csim.schema import validate_section

    out = validate_section("", read_case_file(CONFIGS / config), SCHEMA, [])
    out["mechanism"].pop("name", None)
    return out["mechanism"], out["initial"]


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CSIM_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("CSIM_LINKAGE_CACHE", raising=False)
    return tmp_path / "linkage"


def _load(config: str) -> LightLinkage:
    mechanism, initial = _sections(config)
    return load_linkage(mechanism, initial, tol=initial["tol"], max_iter=initial["max_iter"])


def test_the_plan_is_filed_by_the_build_and_read_back_without_the_symbolic_linkage(cache):
    built = _load("iftomm/a05_flyball_governor.yaml")
    assert built.loaded and len(list(cache.glob("*_plan.json"))) == 1
    read = _load("iftomm/a05_flyball_governor.yaml")
    assert not read.loaded
    assert read.plan == built.plan == built.full().plan()
    full = built.full()
    assert read.drive_names == list(full.drive)
    assert read.driven_indices == [full.variable_names.index(n) for n in full.drive]
    assert read.equation_labels == [e.label for e in full.reduction.kept] and read.dof == full.dof
    assert read.definition.key == built.definition.key
    assert read.definition.constraint_units == built.full().definition.recursive.constraint_units
    keep = read.definition.parameter_names
    assert read.drive_expressions(read.parameters, keep) == built.full().drive_expressions(read.parameters, keep)
    assert not read.loaded
    assert read.drive == full.drive  # the symbolic linkage's: each driven variable's expression
    assert read.loaded


def test_drive_expressions_put_in_the_values_of_parameters_not_kept(cache):
    _load("iftomm/a05_flyball_governor.yaml")
    read = _load("iftomm/a05_flyball_governor.yaml")
    used = read.plan.drive_parameters
    assert used  # the governor's drive reads its parameters
    keep = [name for name in read.parameters if name not in used]
    assert read.drive_expressions(read.parameters, keep) == read.full().drive_expressions(read.parameters, keep)
    assert read.loaded


def _refile(path, filed: dict) -> None:
    """Write ``filed`` (a plan file's data, edited) to ``path`` with the digest of its plan."""
    from csim.linkage.plan import _digest

    path.write_text(json.dumps({**filed, "digest": _digest(filed["plan"])}))


@pytest.mark.parametrize("damage", ["not json", "foreign", "inner key", "version", "edited", "truncated"])
def test_a_damaged_or_stale_plan_is_built_again(cache, damage):
    first = _load("iftomm/a04_bricard.yaml")
    path = plan_path(first.build_key)
    filed = json.loads(path.read_text())
    if damage == "not json":
        path.write_bytes(b"\x00 not a plan")
    elif damage == "foreign":  # a valid plan, filed under another key
        filed["key"] = "0" * 24
        path.write_text(json.dumps(filed))
    elif damage == "inner key":  # filed under its key, with a hash that matches, but another build's plan
        filed["plan"]["build_key"] = "0" * 24
        _refile(path, filed)
    elif damage == "version":
        filed["version"] = "0"
        path.write_text(json.dumps(filed))
    elif damage == "edited":  # its content no longer matches its hash
        filed["plan"]["generic_rank"] += 1
        path.write_text(json.dumps(filed))
    else:
        path.write_text(json.dumps(filed)[:200])
    assert read_plan(first.build_key) is None
    again = _load("iftomm/a04_bricard.yaml")
    assert again.loaded and again.plan == first.plan  # built again (from the cached linkage), and filed anew
    assert read_plan(first.build_key) == first.plan


def test_a_plan_whose_definition_cannot_be_read_is_built_again(cache):
    first = _load("iftomm/a04_bricard.yaml")
    path = plan_path(first.build_key)
    filed = json.loads(path.read_text())
    del filed["plan"]["definition"]["coordinate_names"]
    _refile(path, filed)
    assert read_plan(first.build_key) is not None  # the plan itself reads back
    again = _load("iftomm/a04_bricard.yaml")
    assert again.loaded and again.plan == first.plan
    assert read_plan(first.build_key) == first.plan  # and is filed anew


def test_a_symbolic_linkage_that_does_not_match_its_plan_stops_the_run(cache):
    # the pickled linkage and the plan are separate files: one read back with a plan that is
    # not its own must not run the plan's numbers (the plan is removed, the next run rebuilds)
    first = _load("iftomm/a04_bricard.yaml")
    path = plan_path(first.build_key)
    filed = json.loads(path.read_text())
    assert filed["plan"]["equations"][0]["status"] == "dependent"
    filed["plan"]["equations"][0]["status"] = "kept"
    _refile(path, filed)
    read = _load("iftomm/a04_bricard.yaml")
    assert not read.loaded
    with pytest.raises(CacheError, match="equations differ"):
        read.full()
    assert not path.exists()
    assert _load("iftomm/a04_bricard.yaml").plan == first.plan


def test_a_plan_that_json_cannot_hold_raises(cache):
    # a cache that cannot be written is no error; a value JSON cannot take is a programming error
    import dataclasses

    plan = _load("slider_crank.yaml").plan
    with pytest.raises(TypeError):
        write_plan(dataclasses.replace(plan, start={"q1": object()}))


def test_no_plan_is_filed_without_the_linkage_cache(cache, monkeypatch):
    monkeypatch.setenv("CSIM_LINKAGE_CACHE", "0")
    linkage = _load("slider_crank.yaml")
    assert linkage.loaded and linkage.build_key == "" and not list(cache.glob("*_plan.json"))


@pytest.mark.parametrize("warm", [False, True])
def test_the_light_and_the_symbolic_definition_take_the_drives_start(cache, warm):
    # a kinematic analysis starts at the drives' rates, which the case sets on its definition
    # (csim.case._drive_start): the symbolic definition, built with the case or after, agrees
    from csim.case import load_case

    if warm:
        load_case(CONFIGS / "slider_crank.yaml")
    case = load_case(CONFIGS / "slider_crank.yaml")
    assert case.linkage.loaded != warm
    light = case.mechanism.default_independent_velocities
    assert light == case.linkage.full().definition.default_independent_velocities
    assert light == case.mechanism.full().default_independent_velocities
    (name,) = case.linkage.drive_names
    assert light[name] == pytest.approx(2 * np.pi)


def test_the_light_definition_says_which_loads_have_a_law(cache):
    from csim.case import load_case

    definition = load_case(CONFIGS / "iftomm" / "a05_flyball_governor.yaml").mechanism
    assert [ld.has_law for ld in definition.loads] == [ld.law is not None for ld in definition.full().loads]
    assert any(ld.has_law for ld in definition.loads)


def test_the_plan_reads_back_as_written():
    plan = LinkagePlan(variables=["q1"], start={"q1": 0.5}, drive_names=[], drive_expressions=[], drive_parameters=[],
                       drive_substituted=[],
                       dof=1, planar=True, parameters={"a": 0.1}, link_labels={0: "ground", 1: "crank"},
                       mass_links=[1], equations=[], generic_rank=0, cut_joints=[], tree_joints=[],
                       definition={"name": "m"}, build_key="k")
    assert LinkagePlan.from_json(json.loads(json.dumps(plan.to_json()))) == plan
    with pytest.raises(KeyError):
        LinkagePlan.from_json({**plan.to_json(), "extra": 1})


def test_a_light_linkage_pickles_without_its_symbolic_linkage(cache):
    # a case is sent to worker processes (csim compare, csim sweep)
    built = _load("slider_crank.yaml")
    f = built.drive_function(built.parameters)  # derived and filed
    read = _load("slider_crank.yaml")
    copy = pickle.loads(pickle.dumps(read))
    assert not copy.loaded and copy.plan == read.plan and copy.definition.key == read.definition.key
    for t in (0.0, 0.3):
        for a, b in zip(copy.drive_function(copy.parameters)(t), f(t)):
            np.testing.assert_array_equal(a, b)
    assert copy.full().plan() == read.plan  # built in the worker, from the sections it carries


@pytest.mark.parametrize("config", ["iftomm/a05_flyball_governor.yaml", "iftomm/a04_bricard.yaml"])
def test_a_warm_run_records_what_a_cold_one_does(cache, monkeypatch, config):
    from csim.case import load_case
    from csim.pipeline import run_case

    monkeypatch.setenv("CSIM_LINKAGE_CACHE", "0")
    cold = run_case(load_case(CONFIGS / config, SHORT))
    monkeypatch.delenv("CSIM_LINKAGE_CACHE")
    run_case(load_case(CONFIGS / config, SHORT))  # files the plan and the functions
    case = load_case(CONFIGS / config, SHORT)
    warm = run_case(case)
    assert not case.linkage.loaded
    _assert_same_run(warm, cold)


def _assert_same_run(warm, cold) -> None:
    """Two runs' results are the same to the bit."""
    assert warm.ok and cold.ok
    for name in ("q", "qd", "qdd", "lam", "phi", "removed_phi"):
        np.testing.assert_array_equal(getattr(warm, name), getattr(cold, name))
    assert warm.constraint_units == cold.constraint_units and warm.removed_names == cold.removed_names
    assert [r.label for r in warm.reactions] == [r.label for r in cold.reactions]
    for a, b in zip(warm.reactions, cold.reactions):
        for field in ("force_global", "torque_global", "force_joint", "torque_joint"):
            np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
        assert a.undetermined == b.undetermined
    if cold.drive_forces is not None:
        np.testing.assert_array_equal(warm.drive_forces, cold.drive_forces)


def test_a_case_edited_between_runs_runs_as_a_cold_one(cache, monkeypatch, tmp_path):
    # a parameter changed in the file between two runs: the second files a plan of its own
    # (the build key hashes the sections as written) and records what a cold run does
    from csim.case import load_case
    from csim.pipeline import run_case

    path = tmp_path / "slider_crank.yaml"
    text = (CONFIGS / "slider_crank.yaml").read_text()
    assert text.count("r: 0.1,") == 1
    path.write_text(text)
    before = run_case(load_case(path, SHORT))
    path.write_text(text.replace("r: 0.1,", "r: 0.12,"))
    edited = [run_case(load_case(path, SHORT)) for _ in range(2)]  # the plan filed, then read back
    monkeypatch.setenv("CSIM_LINKAGE_CACHE", "0")
    cold = run_case(load_case(path, SHORT))
    assert not np.array_equal(before.q, cold.q)  # the edit changed the motion
    for run in edited:
        _assert_same_run(run, cold)
    assert len(list(cache.glob("*_plan.json"))) == 2


@pytest.mark.parametrize("config", ["iftomm/a05_flyball_governor.yaml", "iftomm/a04_bricard.yaml",
                                    "slider_crank.yaml"])
def test_a_warm_linkage_run_imports_no_sympy(tmp_path, config):
    # driven dynamics with force elements, an overconstrained mechanism (the constraint watch's
    # removed equations), a kinematic analysis: the second run reads everything from the cache
    # (a cache of its own: the first run is cold, and imports sympy to derive)
    from csim.model.cache import kernels_dir

    env = {**os.environ, "CSIM_CACHE_DIR": str(tmp_path / "cache"), "CSIM_KERNELS_DIR": str(kernels_dir())}
    env.pop("CSIM_LINKAGE_CACHE", None)
    code = ("import runpy, sys\n"
            f"sys.argv = ['csim', 'run', {str(CONFIGS / config)!r}, '-o', {str(tmp_path / 'run.h5')!r}, "
            f"'-s', {SHORT[0]!r}]\n"
            "try:\n    runpy.run_module('csim', run_name='__main__')\n"
            "except SystemExit as exc:\n    assert not exc.code, exc.code\n"
            "print('sympy' in sys.modules)")
    outs = [subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True,
                           text=True, check=True).stdout.split()[-1] for _ in range(2)]
    assert outs == ["True", "False"], outs
