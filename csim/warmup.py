"""Compile the kernels once for this installation: ``python -m csim.warmup`` (``make install``).

numba compiles the kernels' one copy (:mod:`csim.fast.module`) into
:func:`csim.model.cache.kernels_dir`, so that no later command, test session included, waits
for it. Its two halves share nothing that numba caches (:mod:`csim.fast.linking`: what an
entry point calls is compiled into it): the loop, ``integrate``, and the right-hand side the
loop calls by address with the samples' evaluation and the one-state entry points. With two
CPUs or more they compile at the same time, in two processes (numba compiles on one core):
about half the wait. Then a short compiled run of the default case, with ``none`` and with
``minimal``, checks that both halves load and run. Exits 0 with a note when numba or the
compiled backend is not available (csim then runs on the Python path).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

#: the halves of the kernels' compile (:func:`compile_part`), each in a process of its own on two CPUs
PARTS = ("loop", "rhs")
#: the methods of the check after the compile: one of the plain system, and minimal's partitioned one
METHODS = ("none", "minimal")


def _case(method: str, backend: str):
    from csim.case import load_case
    from csim.io.examples import examples_dir

    settings = ["simulation.t_end=0.01", f"stabilization.method={method}", f"simulation.backend={backend}"]
    return load_case(examples_dir() / "quick_return.yaml", settings)


def compile_part(part: str) -> None:
    """Compile one half of the kernels (:data:`PARTS`): ``loop``, ``integrate`` for minimal's partitioned
    system (the same types as every other method's); ``rhs``, ``feval``, ``evaluate_samples`` and the
    one-state entry points, for the plain system.

    Then a short run on the Python path (``minimal`` after the loop, ``none`` after the right-hand
    side), whose calls of the core functions (:mod:`csim.physics`) compile them on their own into
    numba's cache beside their sources: compiled inside the kernels they are not cached
    (:mod:`csim.fast.linking`), and a test session's workers would each compile them again (about
    15 s for three methods on the 2-core machine).
    """
    from csim.fast.runner import compile_loop, compile_rhs
    from csim.pipeline import build_system, initial_state, run_case

    method = "minimal" if part == "loop" else "none"
    case = _case(method, "compiled")
    system = build_system(case)
    y0 = initial_state(case, system)
    if part == "loop":
        compile_loop(system, y0, case.integration_settings())
    else:
        compile_rhs(system, y0)
    run_case(_case(method, "python"))


def check() -> str:
    """A short compiled run of the default case with each of :data:`METHODS` (loaded from the cache,
    or compiled where a half is missing); "" or why one did not run compiled."""
    from csim.pipeline import run_case

    for method in METHODS:
        result = run_case(_case(method, "compiled"))
        if result.backend != "compiled" or not result.ok:
            return f"the compiled backend did not run ({method}): {result.message}"
    return ""


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        return _part(argv[1]) if argv[:1] == ["--part"] else _all()
    except KeyboardInterrupt:
        print("csim: warm-up interrupted; the kernels compile on the first run that needs them", file=sys.stderr)
        return 130


def _part(part: str) -> int:
    """One half, in a process of its own (:func:`_all`), which leaves Ctrl-C to its parent: a
    KeyboardInterrupt raised inside numba's compiler can land in a ctypes callback, where
    Python prints it and compiling goes on; the parent ends this process instead."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return _compile_and_report(part)


def _compile_and_report(part: str) -> int:
    """:func:`compile_part` ``part``, saying why on stderr where it failed; 0 or 1."""
    try:
        compile_part(part)
    except Exception as exc:  # numba missing a feature, a compiler error: the run falls back, say why here
        print(f"csim: compiling the kernels' {part} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    return 0


def _report(problem: str) -> int:
    if problem:
        print(f"csim: {problem}", file=sys.stderr)
    return 1 if problem else 0


def _all() -> int:
    """Both halves: in two processes at once where there are two CPUs, else one after the other; then the check."""
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
        processes = [subprocess.Popen([sys.executable, "-m", "csim.warmup", "--part", part]) for part in PARTS]
        try:
            failed = sum(process.wait() != 0 for process in processes)
        finally:  # after Ctrl-C (which the children ignore): none is left compiling
            for process in processes:
                if process.poll() is None:
                    process.terminate()
                    process.wait()
    else:
        failed = sum(_compile_and_report(part) for part in PARTS)
    if failed or _report(check()):
        return 1
    print(f"csim: kernels ready ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
