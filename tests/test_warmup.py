"""The installation's warm-up (csim.warmup): the kernels' halves and the core compiled, the jobs' schedule,
its command line, and Ctrl-C."""
from __future__ import annotations

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from csim import warmup
from csim.fast.module import kernels_compiled, kernels_path, load_kernels

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def warmed():
    """One warm-up for the module's tests (in this session's cache: compiled here, or loaded); its output."""
    done = subprocess.run([sys.executable, "-m", "csim.warmup"], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout


def test_the_warm_up_leaves_every_entry_point_compiled(warmed):
    assert "kernels ready" in warmed and warmed.count("csim:   compiled ") == len(warmup.PARTS)
    kernels = load_kernels()
    assert kernels_compiled(kernels)
    cache = kernels_path() / "__pycache__"
    for entry in ("driver.integrate", "system.feval", "entries.evaluate_samples", "entries.rhs_entry",
                  "entries.rhs_repeat", "entries.project_entry"):
        assert list(cache.glob(f"{entry}-*.nbi")), entry


#: compile_rhs (feval, the samples' evaluation, the right-hand side's entries) in a fresh
#: kernels' cache; the types of ``located`` that numba compiled ``rhs`` for
RHS_TYPES = """
import json
from numba.core import event
from csim.fast.runner import compile_rhs
from csim.pipeline import build_system, initial_state
from csim.warmup import _case
case = _case("none", "compiled")
system = build_system(case)
y0 = initial_state(case, system)
with event.install_recorder("numba:compile") as compiled:
    compile_rhs(system, y0)
print(json.dumps([str(ev.data["args"][3]) for _, ev in compiled.buffer
                  if ev.is_start and ev.data["dispatcher"].py_func.__name__ == "rhs"]))
"""


@pytest.mark.slow
def test_the_right_hand_side_is_compiled_once_for_its_every_caller(tmp_path):
    """feval and the entry points call rhs with ``located`` typed ``boolean``: a literal True was typed
    ``Literal[bool](True)``, for which numba compiled the whole right-hand side a second time (10 s).
    (In a fresh cache: LLVM inlines rhs into its callers, so no cached module names it.)"""
    env = dict(os.environ, PYTHONPATH=str(ROOT), CSIM_CACHE_DIR=str(tmp_path), CSIM_KERNELS_DIR=str(tmp_path / "k"))
    done = subprocess.run([sys.executable, "-c", RHS_TYPES], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout.splitlines()[-1]) == ["bool"]


def test_every_entry_point_is_filed_with_the_names_its_module_defines(warmed):
    """csim.fast.cache_load: numba's cache entry of each entry point carries its bitcode's names."""
    from csim.fast.cache_load import SharedBitcode

    load_kernels()  # (the finder numba's environments are rebuilt through)
    files = sorted((kernels_path() / "__pycache__").glob("*.nbc"))
    assert files
    for path in files:
        shared = _shared_bitcode(pickle.loads(path.read_bytes()), SharedBitcode)
        assert shared is not None and shared.symbols, path.name


def _shared_bitcode(data, kind):
    """The SharedBitcode inside numba's pickled cache entry, or None."""
    if isinstance(data, kind):
        return data
    for item in data if isinstance(data, tuple | list) else ():
        found = _shared_bitcode(item, kind)
        if found is not None:
            return found
    return None


#: after the warm-up, in a fresh process: its check, then the Python path; what numba had to compile
CHECK = """
import json
from numba.core import event
from csim import warmup
from csim.fast.module import load_kernels
from csim.pipeline import run_case
with event.install_recorder("numba:compile") as compiled:
    problem = warmup.check()
    kernels = load_kernels()
    for method in warmup.METHODS:
        assert run_case(warmup._case(method, "python")).ok
print(json.dumps(dict(problem=problem, compiles=len(compiled.buffer),
                      misses={name: sum(getattr(kernels, name).stats.cache_misses.values())
                              for name in ("integrate", "feval", "evaluate_samples")})))
"""


def test_runs_after_the_warm_up_compile_nothing(warmed):
    """The loop was compiled from its arguments' types without being called (csim.fast.runner.compile_loop),
    and the core functions by a Python-path run before the right-hand side: compiled runs with minimal and
    none, and the same on the Python path, in a new process load every function from the cache."""
    done = subprocess.run([sys.executable, "-c", CHECK], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.splitlines()[-1])
    assert out == dict(problem="", compiles=0, misses={"integrate": 0, "feval": 0, "evaluate_samples": 0}), out


def test_the_slots_use_the_cpus():
    assert warmup._slots(1) == [["loop", "rhs"]]
    assert warmup._slots(2) == [["loop"], ["rhs"]]
    assert warmup._slots(16) == [["loop"], ["rhs"]]


class _FakeJob:
    """A stand-in for subprocess.Popen: the job named last on the command line, done at once with its status."""

    def __init__(self, command, process_group=None, log=None, codes=None):
        self.job, self.returncode = command[-1], codes[command[-1]]
        log.append((self.job, process_group))

    def poll(self):
        return self.returncode


@pytest.mark.parametrize("cpus", [1, 2])
def test_every_job_runs_whatever_the_others_do(monkeypatch, cpus):
    """The jobs are independent: a failed one is counted, the others all run (each in a process group of its
    own, so that a Ctrl-C at the terminal reaches only the parent)."""
    log, codes = [], {"loop": 1, "rhs": 0}
    monkeypatch.setattr(warmup.subprocess, "Popen", lambda command, **kw: _FakeJob(command, log=log, codes=codes,
                                                                                   **kw))
    assert warmup._run_slots(warmup._slots(cpus)) == 1
    assert sorted(log) == [("loop", 0), ("rhs", 0)]


def test_a_failed_python_path_run_still_compiles_the_right_hand_side_then_fails_the_job(monkeypatch):
    import csim.fast.runner
    import csim.pipeline
    from csim.fast import linking

    compiled = []

    def broken(case):
        raise ValueError("core broke")
    monkeypatch.setattr(csim.pipeline, "run_case", broken)
    monkeypatch.setattr(csim.fast.runner, "compile_rhs", lambda system, y0: compiled.append("rhs"))
    monkeypatch.setattr(linking, "entry_points_only", lambda: None)  # (this process goes on calling callees)
    with pytest.raises(RuntimeError, match=r"the Python path's run .*ValueError: core broke"):
        warmup.compile_part("rhs")
    assert compiled == ["rhs"]


@pytest.mark.parametrize("argv", [["--part"], ["--bogus"], ["--part", "loop", "extra"], ["--part", "nope"], ["-h"]])
def test_a_command_line_it_does_not_take_is_refused(argv, capsys, monkeypatch):
    monkeypatch.setattr(warmup, "_all", lambda: pytest.fail("ran the warm-up"))
    monkeypatch.setattr(warmup, "_part", lambda part: pytest.fail("ran a job"))
    assert warmup.main(argv) == 2
    assert "usage: python -m csim.warmup [--part {loop,rhs}]" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_ends_the_warm_up_and_its_compiling_children_without_a_traceback(tmp_path):
    # Ctrl-C at a terminal reaches the parent's process group: the parent ends the jobs compiling in
    # groups of their own, says what it means and exits 130, and no compiler is left running
    env = dict(os.environ, CSIM_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    env.pop("CSIM_KERNELS_DIR", None)  # the session's compiled kernels (conftest): the children would be done at once
    process = subprocess.Popen([sys.executable, "-m", "csim.warmup"], env=env, cwd=tmp_path, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(8)  # the kernels' halves are compiling (a cold cache takes half a minute or more)
    children = [int(pid) for pid in subprocess.run(["pgrep", "-P", str(process.pid)], capture_output=True,
                                                   text=True).stdout.split()]
    jobs = {Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[-2].decode() for pid in children}
    slots = warmup._slots(warmup._cpus())  # the first job of each slot runs
    assert {slot[0] for slot in slots} <= jobs and len(children) <= len(slots), jobs
    os.killpg(process.pid, signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 130, (out, err)
    assert "warm-up interrupted" in err and "Traceback" not in err
    for pid in children:  # ended and reaped by the parent
        assert not Path(f"/proc/{pid}").exists()
