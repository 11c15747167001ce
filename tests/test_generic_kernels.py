"""The kernels compiled once per installation, a mechanism's model functions built apart (issue 12).

A second mechanism, in a fresh process, loads the kernels' machine code from numba's cache
without compiling anything of them; the numba cfunc fallback (no C compiler) gives the
results of the C path; a mechanism whose sizes have no copy with constant sizes in the
kernels runs the same steps as the Python path.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import CONFIGS, qr_case

from csim.case import load_case
from csim.pipeline import run_case

pytest.importorskip("numba")

ROOT = Path(__file__).resolve().parents[1]

PROBE = """
import json, sys
from csim.case import load_case
from csim.fast import module
from csim.pipeline import run_case
res = run_case(load_case(sys.argv[1], ["simulation.t_end=0.2", "simulation.backend=compiled"]))
kernels = module.load_kernels()
stats = {name: getattr(kernels, name).stats for name in ("integrate", "evaluate_samples")}
print(json.dumps(dict(backend=res.backend, ok=res.ok,
                      hits={k: sum(s.cache_hits.values()) for k, s in stats.items()},
                      misses={k: sum(s.cache_misses.values()) for k, s in stats.items()},
                      models=sorted(p.name for d in {module.cache_dir() / "fast", module.kernels_path().parent}
                                    for p in d.iterdir()))))
"""


def _fresh_process(config: str) -> dict:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run([sys.executable, "-c", PROBE, str(CONFIGS / config)], env=env, cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def test_a_second_mechanism_in_a_fresh_process_loads_the_kernels_from_the_cache():
    # this session's cache holds the kernels once the quick-return has run compiled (in this process)
    assert run_case(qr_case("simulation.t_end=0.1", "simulation.backend=compiled")).backend == "compiled"
    probe = _fresh_process("pendulum.yaml")  # another mechanism, another process
    assert probe["backend"] == "compiled" and probe["ok"]
    assert probe["misses"] == {"integrate": 0, "evaluate_samples": 0}, probe
    assert probe["hits"]["integrate"] >= 1 and probe["hits"]["evaluate_samples"] >= 1, probe
    # one copy of the kernels for every method; a cache kept across test sessions (CSIM_TEST_CACHE_DIR) may
    # also hold copies of earlier sources
    from csim.fast.module import kernels_key

    copies = [name for name in probe["models"] if name.startswith("kernels") and kernels_key() in name]
    assert copies == [f"kernels_{kernels_key()}"], copies
    if any(name.startswith("pendulum_") and name.endswith(".so") for name in probe["models"]):
        return  # built by the C compiler
    assert any(name.startswith("pendulum_") and name.endswith("_cfunc.py") for name in probe["models"])


@pytest.fixture
def fresh_models(monkeypatch):
    """Model functions loaded anew in this test (the process keeps loaded ones by key)."""
    from csim.fast import module

    monkeypatch.setattr(module, "_MODELS", {})
    monkeypatch.setattr(module, "_BY_DEFINITION", {})
    return module


@pytest.mark.parametrize("force", ["CSIM_MODEL_BACKEND=numba", "CC=false"])
def test_the_numba_fallback_gives_the_results_of_the_c_path(fresh_models, monkeypatch, force):
    """The same steps, events and recorded quantities to round-off, with and without a C compiler."""
    module = fresh_models
    if module.c_compiler() is None:
        pytest.skip("no C compiler: every run here is the fallback")
    sets = ["simulation.t_end=1", "stabilization.method=projection", "simulation.backend=compiled"]
    with_c = run_case(qr_case(*sets))
    model = module.load_model(module._BY_DEFINITION[next(iter(module._BY_DEFINITION))][0])
    assert model.backend == "c" and model.reason == ""
    monkeypatch.setattr(module, "_MODELS", {})
    monkeypatch.setattr(module, "_BY_DEFINITION", {})
    name, value = force.split("=")
    monkeypatch.setenv(name, value)
    if name == "CC":  # a cache where no model is built yet: the compiler must run, and fails
        monkeypatch.setenv("CSIM_CACHE_DIR", str(Path(os.environ["CSIM_CACHE_DIR"]) / "no-cc"))
    without = run_case(qr_case(*sets))
    fallback = module._BY_DEFINITION[next(iter(module._BY_DEFINITION))][1]
    assert fallback.backend == "numba"
    assert ("CSIM_MODEL_BACKEND" in fallback.reason) if name == "CSIM_MODEL_BACKEND" else ("false" in fallback.reason)
    assert with_c.ok and without.ok and with_c.backend == without.backend == "compiled"
    assert (with_c.nfev, with_c.nsteps) == (without.nfev, without.nsteps)
    np.testing.assert_allclose(without.event_times, with_c.event_times, rtol=0, atol=1e-12)
    for field in ("q", "qd", "lam", "phi", "kinetic", "observables"):
        a, b = getattr(with_c, field), getattr(without, field)
        np.testing.assert_allclose(b, a, rtol=1e-12, atol=1e-12 * max(1.0, float(np.max(np.abs(a)))), err_msg=field)


def test_a_c_compiler_error_under_model_backend_c_is_reported(fresh_models, monkeypatch):
    monkeypatch.setenv("CSIM_MODEL_BACKEND", "c")
    monkeypatch.setenv("CC", "false")
    monkeypatch.setenv("CSIM_CACHE_DIR", str(Path(os.environ["CSIM_CACHE_DIR"]) / "c-fails"))  # nothing built yet
    res = run_case(qr_case("simulation.t_end=0.1", "simulation.backend=compiled"))
    assert res.status == "failed" and "false failed" in res.message


def test_sizes_without_a_constant_copy_run_the_steps_of_the_python_path():
    """Andrews' mechanism (m = 7, r = 6) runs the right-hand side with the sizes read at run time."""
    sets = ["simulation.t_end=0.01", "simulation.rtol=1e-8", "simulation.atol=1e-8"]
    fast = run_case(load_case(CONFIGS / "andrews.yaml", [*sets, "simulation.backend=compiled"]))
    slow = run_case(load_case(CONFIGS / "andrews.yaml", [*sets, "simulation.backend=python"]))
    assert fast.ok and slow.ok, (fast.message, slow.message)
    assert (fast.nfev, fast.nsteps) == (slow.nfev, slow.nsteps)
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-10)


def test_integers_beyond_64_bits_are_printed_as_doubles_in_c():
    """sympy keeps exact integers (10^19 from a rationalized float inertia): as C integer
    literals they overflow, and the compiled kinetic energy of such a model came out wrong."""
    import sympy as sp

    from csim.fast.ccodegen import _Printer

    x = sp.Symbol("x")
    assert _Printer().doprint(10**19 * x) == "1e+19*s_x"
    assert _Printer().doprint(12 * x) == "12*s_x"


def test_the_copy_of_the_kernels_is_importable_by_name(monkeypatch):
    """numba rebuilds a cached function's environment by importing its module by name: a process
    that has not loaded the kernels yet must find the copy and its files by their names."""
    import importlib
    import sys

    from csim.fast import module

    module.load_kernels()
    name = f"csim_fast_{module.kernels_path().name}"
    for loaded in [m for m in sys.modules if m == name or m.startswith(name + ".")]:
        monkeypatch.delitem(sys.modules, loaded)
    imported = importlib.import_module(name)
    assert Path(imported.__file__).parent == module.kernels_path() and imported.COMPILED is True
    driver = importlib.import_module(f"{name}.driver")  # its files, from the copy
    assert Path(driver.__file__).parent == module.kernels_path() and driver.COMPILED is True


def test_the_kernels_key_is_fixed_for_the_process(monkeypatch, tmp_path):
    # the copy a process writes carries the key it loaded with, and the text that key hashed, even if a
    # source file changes under the process
    from csim.fast import module

    key, text = module.kernels_key(), module.kernels_source()
    edited = tmp_path / "kernels"
    shutil.copytree(module.KERNELS, edited, ignore=shutil.ignore_patterns("__pycache__"))
    (edited / "driver.py").write_text((edited / "driver.py").read_text() + "\n# edited while a process runs\n")
    monkeypatch.setattr(module, "KERNELS", edited)
    assert module._kernels_snapshot.__wrapped__()[0] != key  # the edit is a new key for a new process
    assert module.kernels_key() == key
    assert module.kernels_path().name == f"kernels_{key}"
    assert module.kernels_source() == text  # and the copy holds the text the key hashed


def test_a_copy_of_the_kernels_is_written_whole_and_never_replaced(tmp_path):
    """Workers may race to write one copy: the first one written is kept (numba's cache is keyed
    on its files' stamps), a loser leaves no temporary folder, and one a killed process left an
    hour ago is removed."""
    from csim.fast import module

    path = tmp_path / "kernels_k"
    module._write_package(path, {"__init__.py": "A = 1\n", "variant.py": "COMPILED = True\n"})
    stamp = (path / "__init__.py").stat().st_mtime_ns
    module._write_package(path, {"__init__.py": "A = 2\n", "variant.py": "COMPILED = True\n"})  # a loser
    assert (path / "__init__.py").read_text() == "A = 1\n" and (path / "__init__.py").stat().st_mtime_ns == stamp
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kernels_k"]
    assert oct(path.stat().st_mode & 0o777) == "0o755" and oct((path / "variant.py").stat().st_mode & 0o777) == "0o644"
    stale, fresh = tmp_path / ".kernels_j-stale", tmp_path / ".kernels_j-writing"
    stale.mkdir()
    fresh.mkdir()
    os.utime(stale, (0, 0))
    module._write_package(tmp_path / "kernels_j", {"__init__.py": ""})
    assert sorted(p.name for p in tmp_path.iterdir()) == [".kernels_j-writing", "kernels_j", "kernels_k"]


def test_copies_of_other_keys_unused_for_a_month_are_removed(tmp_path):
    """An upgrade leaves the copy of the old key (3.3 MB with its machine code) behind: it goes once no
    process has loaded it for UNUSED_DAYS, with the single-file copies of older csims and their machine
    code. This process's copy, recent ones (another installation sharing the cache), a copy whose machine
    code was read lately (an older csim, which sets no stamp), the models' files and other names stay."""
    from csim.fast import module

    now = 1.0e9
    old, recent = now - (module.UNUSED_DAYS + 1) * 86400, now - 5 * 86400
    key = {c: c * 24 for c in "abcdef"}
    pycache = tmp_path / "__pycache__"
    pycache.mkdir()
    files = {tmp_path / module.kernels_path().name: old, tmp_path / f"kernels_partitioned_{key['f']}": recent,
             tmp_path / f"kernels_{key['a']}": old, tmp_path / f"kernels_partitioned_{key['b']}": recent,
             tmp_path / f"kernels_partitioned_{key['a']}": old,
             tmp_path / f"kernels_{key['e']}": old, tmp_path / f"kernels_{key['e']}" / "__pycache__": old,
             tmp_path / f"kernels_{key['c']}.py": old, pycache / f"kernels_{key['c']}.integrate-300.py311.nbi": old,
             tmp_path / f"kernels_{key['d']}.py": old, pycache / f"kernels_{key['d']}.integrate-300.py311.nbi": recent,
             pycache / "pendulum_ddd_cfunc.terms-12.py311.nbc": old, tmp_path / "pendulum_ddd.so": old,
             tmp_path / "kernels_notes": old}
    for path, stamp in files.items():
        path.mkdir() if not path.suffix else path.write_text("")  # the copies are folders
        os.utime(path, (stamp, stamp))
    used = tmp_path / f"kernels_{key['e']}" / "__pycache__" / "driver.integrate-40.py311.nbi"
    used.write_text("")
    os.utime(used, (recent, old))  # read five days ago: an older csim still loads this copy
    os.utime(tmp_path / f"kernels_{key['e']}", (old, old))
    removed = module.prune_kernels(tmp_path, now=now)
    assert sorted(p.name for p in removed) == [f"kernels_{key['a']}", f"kernels_{key['c']}.py",
                                               f"kernels_partitioned_{key['a']}"]
    assert not (pycache / f"kernels_{key['c']}.integrate-300.py311.nbi").exists()
    kept = set(files) - set(removed) - {pycache / f"kernels_{key['c']}.integrate-300.py311.nbi"}
    assert all(p.exists() for p in kept), sorted(p.name for p in kept if not p.exists())


def test_a_new_copy_prunes_and_a_load_stamps_its_copy(tmp_path, monkeypatch):
    """The wiring: writing a copy prunes the folder, and every load stamps the copy it loads."""
    from csim.fast import module

    monkeypatch.setenv("CSIM_KERNELS_DIR", str(tmp_path))
    stale = tmp_path / f"kernels_{'a' * 24}"
    stale.mkdir()
    os.utime(stale, (0, 0))
    copy = module._kernels_copy()
    assert copy.parent == tmp_path and not stale.exists()
    os.utime(copy, (0, 0))
    assert module._kernels_copy() == copy and time.time() - copy.stat().st_mtime < 60


def test_an_editors_lock_file_beside_the_kernels_is_not_a_source(tmp_path):
    from csim.fast import module

    (tmp_path / "driver.py").write_text("x = 1\n")
    (tmp_path / ".#driver.py").symlink_to(tmp_path / "missing")  # how Emacs marks a file being edited
    (tmp_path / "__pycache__").mkdir()
    assert [p.name for p in module._sources(tmp_path)] == ["driver.py"]
