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
import signal
import subprocess
import sys
import time

#: a method of each copy of the kernels: the plain one and the partitioned one (minimal)
METHODS = ("none", "minimal")


def compile_for(method: str) -> str:
    """Run the default case briefly, compiled, with ``method``; "" or why it did not run compiled.

    With the plain copy, also its one-state entry points (:func:`csim.fast.runner.compile_entries`).
    Then once more on the Python path, whose calls of the core functions (:mod:`csim.physics`)
    compile them on their own, into numba's cache beside their sources: compiled inside the
    kernels they are not cached (:mod:`csim.fast.linking`), and a test session's workers would
    each compile them again (about 15 s for three methods on the 2-core machine).
    """
    from csim.case import load_case
    from csim.fast.runner import compile_entries
    from csim.io.examples import examples_dir
    from csim.pipeline import build_system, initial_state, run_case

    settings = ["simulation.t_end=0.01", f"stabilization.method={method}"]
    case = load_case(examples_dir() / "quick_return.yaml", [*settings, "simulation.backend=compiled"])
    result = run_case(case)
    if result.backend != "compiled" or not result.ok:
        return f"the compiled backend did not run ({method}): {result.message}"
    if method != "minimal":  # the plain copy's one-state entry points, which the tests call
        system = build_system(case)
        compile_entries(system, initial_state(case, system))
    run_case(load_case(examples_dir() / "quick_return.yaml", [*settings, "simulation.backend=python"]))
    return ""


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        return _method(argv[1]) if argv[:1] == ["--method"] else _all()
    except KeyboardInterrupt:
        print("csim: warm-up interrupted; the kernels compile on the first run that needs them", file=sys.stderr)
        return 130


def _method(method: str) -> int:
    """One copy, in a process of its own (:func:`_all`), which leaves Ctrl-C to its parent: a
    KeyboardInterrupt raised inside numba's compiler can land in a ctypes callback, where
    Python prints it and compiling goes on; the parent ends this process instead."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return _compile_and_report(method)


def _compile_and_report(method: str) -> int:
    """:func:`compile_for` ``method``, saying why on stderr where it did not run compiled; 0 or 1."""
    problem = compile_for(method)
    if problem:
        print(f"csim: {problem}", file=sys.stderr)
    return 1 if problem else 0


def _all() -> int:
    """Both copies: in two processes at once where there are two CPUs, else one after the other."""
    from csim.fast.support import numba_available
    from csim.model.cache import kernels_dir

    if not numba_available():
        print("csim: numba is not installed; csim runs the kernels interpreted, or on the Python path (nothing to "
              "compile)")
        return 0
    start = time.perf_counter()
    print(f"csim: compiling the kernels into {kernels_dir()} (once per installation; minutes on 2 cores) ...",
          flush=True)
    if (os.cpu_count() or 1) >= 2:
        processes = [subprocess.Popen([sys.executable, "-m", "csim.warmup", "--method", method]) for method in METHODS]
        try:
            failed = sum(process.wait() != 0 for process in processes)
        finally:  # after Ctrl-C (which the children ignore): none is left compiling
            for process in processes:
                if process.poll() is None:
                    process.terminate()
                    process.wait()
    else:
        failed = sum(_compile_and_report(method) for method in METHODS)
    if failed:
        return 1
    print(f"csim: kernels ready ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
