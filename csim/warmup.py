"""Compile the kernels once for this installation: ``python -m csim.warmup`` (``make install``).

Runs the default case for a few steps with the compiled backend, once with a method of the
plain kernels and once with ``minimal`` (the partitioned copy), so that numba compiles both
copies into :func:`csim.model.cache.kernels_dir` and no later command, test session
included, waits for them. With two CPUs or more the two copies compile at the same time, in
two processes (numba compiles on one core): about half the wait. Exits 0 with a note when
numba or the compiled backend is not available (csim then runs on the Python path).
"""
from __future__ import annotations

import os
import subprocess
import sys
import time

#: a method of each copy of the kernels: the plain one and the partitioned one (minimal)
METHODS = ("none", "minimal")


def compile_for(method: str) -> str:
    """Run the default case briefly, compiled, with ``method``; "" or why it did not run compiled."""
    from csim.case import load_case
    from csim.io.examples import examples_dir
    from csim.pipeline import run_case

    settings = ["simulation.t_end=0.01", "simulation.backend=compiled", f"stabilization.method={method}"]
    result = run_case(load_case(examples_dir() / "quick_return.yaml", settings))
    if result.backend != "compiled" or not result.ok:
        return f"the compiled backend did not run ({method}): {result.message}"
    return ""


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--method"]:  # one copy, in a process of its own (below)
        problem = compile_for(argv[1])
        if problem:
            print(f"csim: {problem}", file=sys.stderr)
        return 1 if problem else 0
    from csim.fast.support import numba_available
    from csim.model.cache import kernels_dir

    if not numba_available():
        print("csim: numba is not installed; csim runs on the Python path (nothing to compile)")
        return 0
    start = time.perf_counter()
    print(f"csim: compiling the kernels into {kernels_dir()} (once per installation; minutes on 2 cores) ...",
          flush=True)
    if (os.cpu_count() or 1) >= 2:
        processes = [subprocess.Popen([sys.executable, "-m", "csim.warmup", "--method", method]) for method in METHODS]
        failed = sum(process.wait() != 0 for process in processes)
    else:
        problems = [problem for problem in map(compile_for, METHODS) if problem]
        for problem in problems:
            print(f"csim: {problem}", file=sys.stderr)
        failed = len(problems)
    if failed:
        return 1
    print(f"csim: kernels ready ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
