"""The installation's warm-up (csim.warmup): both halves of the kernels compiled, and Ctrl-C."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from csim import warmup
from csim.fast.module import kernels_compiled, kernels_path, load_kernels

ROOT = Path(__file__).resolve().parents[1]


def test_the_warm_up_leaves_every_entry_point_compiled(capsys):
    assert warmup.main([]) == 0  # (in this session's cache: compiled here, or loaded)
    assert "kernels ready" in capsys.readouterr().out
    kernels = load_kernels()
    assert kernels_compiled(kernels)
    cache = kernels_path() / "__pycache__"
    for entry in ("driver.integrate", "system.feval", "entries.evaluate_samples", "entries.rhs_entry",
                  "entries.rhs_repeat", "entries.project_entry"):
        assert list(cache.glob(f"{entry}-*.nbi")), entry


#: the warm-up's check in a fresh process: how many of the loaded kernels' functions numba had to compile
CHECK = """
import json
from csim import warmup
from csim.fast.module import load_kernels
problem = warmup.check()
kernels = load_kernels()
print(json.dumps(dict(problem=problem, misses={name: sum(getattr(kernels, name).stats.cache_misses.values())
                                                for name in ("integrate", "feval", "evaluate_samples")})))
"""


def test_runs_after_the_warm_up_compile_nothing():
    """The loop was compiled from its arguments' types without being called (csim.fast.runner.compile_loop):
    a run with minimal and one with none in a new process load every function from the cache."""
    assert warmup.main([]) == 0
    done = subprocess.run([sys.executable, "-c", CHECK], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.splitlines()[-1])
    assert out == dict(problem="", misses={"integrate": 0, "feval": 0, "evaluate_samples": 0}), out


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_ctrl_c_ends_the_warm_up_and_its_compiling_children_without_a_traceback(tmp_path):
    # Ctrl-C at a terminal reaches the whole process group: the children compiling each half
    # end quietly, the parent says what it means and exits 130, and no compiler is left running
    env = dict(os.environ, CSIM_CACHE_DIR=str(tmp_path), PYTHONPATH=str(ROOT))
    env.pop("CSIM_KERNELS_DIR", None)  # the session's compiled kernels (conftest): the children would be done at once
    process = subprocess.Popen([sys.executable, "-m", "csim.warmup"], env=env, cwd=tmp_path, start_new_session=True,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(8)  # the children are compiling (a cold cache takes minutes)
    children = [int(pid) for pid in subprocess.run(["pgrep", "-P", str(process.pid)], capture_output=True,
                                                   text=True).stdout.split()]
    assert len(children) == len(warmup._slots(os.cpu_count() or 1))  # a job of each slot at a time
    os.killpg(process.pid, signal.SIGINT)
    out, err = process.communicate(timeout=60)
    assert process.returncode == 130, (out, err)
    assert "warm-up interrupted" in err and "Traceback" not in err
    for pid in children:  # ended and reaped by the parent
        assert not Path(f"/proc/{pid}").exists()
