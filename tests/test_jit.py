"""csim.physics.jit: core functions compiled on first use, and commands that never import numba."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import CONFIGS, ROOT

from csim.physics.jit import LazyKernel, kernel

#: run csim's CLI in a fresh process, then say whether numba was imported
CLI = ("import sys; from csim.cli import app\n"
       "try:\n    app(args=sys.argv[1:], prog_name='csim')\nexcept SystemExit as exc:\n"
       "    assert not exc.code, exc.code\n"
       "print('numba' in sys.modules)")


def _numba_imported(*args: str, code: str = CLI) -> bool:
    done = subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, env=dict(os.environ), capture_output=True,
                          text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    return done.stdout.split()[-1] == "True"


@pytest.fixture(scope="module")
def result_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("jit") / "pendulum.h5"
    subprocess.run([sys.executable, "-m", "csim", "run", str(CONFIGS / "pendulum.yaml"), "--set",
                    "simulation.t_end=0.05", "-o", str(out), "--quiet"], cwd=ROOT, check=True, capture_output=True)
    return out


def test_validation_imports_no_numba():
    code = ("import sys; from csim.case import load_case; "
            "load_case('configs/quick_return.yaml', ['stabilization.method=minimal']); print('numba' in sys.modules)")
    assert not _numba_imported(code=code)


@pytest.mark.parametrize("args", [("describe", "configs/quick_return_tables.yaml"), ("schema",)])
def test_describe_and_schema_import_no_numba(args):
    assert not _numba_imported(*args)


def test_plot_imports_no_numba(result_file, tmp_path):
    assert not _numba_imported("plot", str(result_file), "-o", str(tmp_path), "--quiet")
    assert list(tmp_path.glob("*.png"))


def test_a_run_does_import_it(tmp_path):
    # the checks above can fail: a run needs numba
    assert _numba_imported("run", "configs/pendulum.yaml", "--set", "simulation.t_end=0.01", "-o",
                           str(tmp_path / "run.h5"), "--quiet")


def test_a_lazy_kernel_compiles_on_first_call_and_is_typed_in_compiled_callers():
    pytest.importorskip("numba")
    from numba import njit

    @kernel
    def twice(x):
        return 2.0 * x

    # lazy until numba loads; a dispatcher once it has (so that numba inlines and resolves it statically)
    assert isinstance(twice, LazyKernel) or hasattr(twice, "signatures")
    assert twice(1.5) == 3.0

    @njit
    def caller(x):
        return twice(x) + 1.0

    assert caller(2.0) == 5.0
    compiled = twice.compiled() if isinstance(twice, LazyKernel) else twice
    assert compiled.signatures  # a numba dispatcher
    assert np.isclose(twice(np.float64(0.25)), 0.5)


def test_an_inline_kernel_is_inlined_in_numbas_ir_into_an_inlining_root_only():
    """Into a root, numba inlines the function's IR (it never compiles it on its own); into any other
    caller, a call (it compiles it for the caller). The same numbers either way."""
    pytest.importorskip("numba")
    from numba import njit

    from csim.physics import jit
    if jit.pure_python():
        pytest.skip("CSIM_PURE_PYTHON: nothing compiles")

    def _add_one(x):
        return x + 1.0
    add_one = jit.inline_kernel(_add_one)
    add_one = add_one.compiled() if isinstance(add_one, LazyKernel) else add_one  # what a csim module binds

    @njit
    @jit.inlining_root
    def root(x):
        return add_one(x) * 2.0

    @njit
    def other(x):
        return add_one(x) * 3.0

    @njit
    def callee(x):
        return add_one(x) - 1.0

    @njit
    @jit.inlining_root
    def root_of_callee(x):
        return callee(x) * 4.0

    assert root(1.0) == 4.0
    assert root_of_callee(1.0) == 4.0
    assert not add_one.signatures  # inlined into the root and into its callee: no compile of its own
    assert other(1.0) == 6.0
    assert add_one.signatures  # called by the other one
    assert jit._INLINING["open"] == [] and not jit._INLINING["on"]


def test_the_inlining_switch_takes_the_end_of_a_compile_it_did_not_see_start():
    """csim's listeners may come in while a compile is under way (numba loaded inside another
    package's typing): that compile's end finds nothing open, and nothing is left switched on."""
    pytest.importorskip("numba")
    from numba.core import event

    from csim.physics import jit
    if jit.activate() is None:
        pytest.skip("CSIM_PURE_PYTHON: nothing compiles")
    event.end_event("numba:compile", data={"dispatcher": None, "args": (), "return_type": None})
    assert jit._INLINING["open"] == [] and not jit._INLINING["on"]


def test_plain_runs_a_core_function_not_yet_compiled_as_python(monkeypatch):
    """Inside ``plain()`` a LazyKernel that has not been compiled calls its Python function and
    leaves numba alone; outside, or once compiled, it is the compiled one."""
    from csim.physics import jit

    calls = []

    def fn(x):
        calls.append(x)
        return x + 1

    lazy = jit.LazyKernel(fn, {})
    monkeypatch.setattr(lazy, "compiled", lambda: pytest.fail("compiled inside plain()"))
    with jit.plain():
        assert lazy(1) == 2
    assert calls == [1] and jit._PLAIN["depth"] == 0


#: a compiled run twice (the first fills the cache), then a compile of a new function: whether the
#: core's and the kernels' functions were dispatchers after the warm run, and after that compile
BIND = """
import json, sys
from numba import njit
from csim.case import load_case
from csim.fast.module import load_kernels
from csim.physics import jit
from csim.pipeline import run_case
case = load_case(sys.argv[1], ["simulation.t_end=0.05", "simulation.backend=compiled"])
result = run_case(case)
kernels = sys.modules[load_kernels().integrate.py_func.__module__.rsplit(".", 1)[0] + ".system"]
def state():
    from csim.physics import kkt
    return dict(bound=jit._NUMBA["bound"], rhs=type(kernels.rhs).__name__, kkt=type(kkt.kkt_solve).__name__)
warm = state()
njit(lambda x: x + 1.0)(1.0)
print(json.dumps(dict(ok=result.ok, warm=warm, compiled=state())))
"""


def test_the_dispatchers_are_made_at_the_first_compile_not_by_a_warm_run():
    """A warm run loads the entry points from the cache and makes no dispatcher of the functions they call;
    the first compile in the process makes them all (numba types and inlines callees it sees as dispatchers)."""
    run = [sys.executable, "-c", BIND, str(CONFIGS / "pendulum.yaml")]
    subprocess.run(run, cwd=ROOT, env=dict(os.environ), capture_output=True, check=True)  # fills the cache
    done = subprocess.run(run, cwd=ROOT, env=dict(os.environ), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    out = json.loads(done.stdout.splitlines()[-1])
    assert out["ok"]
    assert out["warm"] == dict(bound=False, rhs="LazyKernel", kkt="LazyKernel"), out
    assert out["compiled"] == dict(bound=True, rhs="CPUDispatcher", kkt="CPUDispatcher"), out
