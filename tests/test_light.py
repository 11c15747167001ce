"""The light definitions of registered mechanisms: plain data from a snapshot, sympy on demand."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest
from conftest import ROOT

from csim.mechanisms import MECHANISMS, MODULES, get_mechanism, light_mechanism
from csim.model.cache import definition_key
from csim.model.light import LightDefinition, full_definition, light_definition


def test_light_data_equals_the_full_definitions():
    for name in MODULES:
        light, full = light_mechanism(name), get_mechanism(name)
        assert isinstance(light, LightDefinition)
        assert light.coordinate_names == full.coordinate_names and light.coordinate_units == full.coordinate_units
        assert light.parameters == full.parameters and light.n_constraints == len(full.constraints)
        assert [ld.name for ld in light.loads] == [ld.name for ld in full.loads]
        assert [(o.name, o.unit) for o in light.observables] == [(o.name, o.unit) for o in full.observables]
        assert light.default_independent == full.default_independent
        assert light.default_guess == full.default_guess
        assert light.key == definition_key(full)  # the generated code's cache entry


def test_the_snapshot_is_read_back_without_building_the_mechanism(tmp_path, monkeypatch):
    monkeypatch.setenv("CSIM_CACHE_DIR", str(tmp_path))
    built = []

    def factory():
        built.append(1)
        return MECHANISMS["pendulum"]()
    first = light_definition("pendulum", MODULES["pendulum"], factory)
    second = light_definition("pendulum", MODULES["pendulum"], factory)
    assert len(built) == 1 and second.key == first.key
    # a symbolic attribute builds the full definition, once
    assert [str(c) for c in second.constraints] == [str(c) for c in first.full().constraints]
    assert len(built) == 2 and full_definition(second) is second.full()


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_a_warm_run_imports_no_sympy(backend):
    # the snapshot and the generated code (and the compiled model) are in the test cache after the first run
    code = ("import sys; from csim.case import load_case; from csim.pipeline import run_case; "
            f"c = load_case('configs/quick_return.yaml', ['simulation.t_end=0.05', 'simulation.backend={backend}']); "
            "r = run_case(c); assert r.ok, r.message; print('sympy' in sys.modules)")
    env = dict(os.environ)
    outs = [subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True,
                           check=True).stdout.split()[-1] for _ in range(2)]
    assert outs[1] == "False", outs


def test_no_snapshot_is_written_from_sources_changed_after_the_process_loaded_them(tmp_path, monkeypatch):
    """An upgrade or an edit while a process runs: what the old code built must not be filed
    under the new sources' key (later processes would read a stale model)."""
    import csim.model.light as light

    monkeypatch.setenv("CSIM_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(light, "_LOADED_AT", 0.0)  # every source is newer than this process
    definition = light_definition("pendulum", MODULES["pendulum"], MECHANISMS["pendulum"])
    assert definition.key == definition_key(get_mechanism("pendulum"))
    assert not list(tmp_path.rglob("*.json"))
    monkeypatch.setattr(light, "_LOADED_AT", float("inf"))
    light_definition("pendulum", MODULES["pendulum"], MECHANISMS["pendulum"])
    assert len(list(tmp_path.rglob("*.json"))) == 1
