"""Compile the kernels once for this installation: ``python -m csim.warmup`` (``make install``).

numba compiles the kernels' one copy (:mod:`csim.fast.module`) into
:func:`csim.model.cache.kernels_dir`, so that no later command, test session included, waits
for it. Its two halves share nothing that numba caches (:mod:`csim.fast.linking`: what an
entry point calls is compiled into it): the loop, ``integrate``, and the right-hand side the
loop calls by address with the samples' evaluation and the one-state entry points. A third
job compiles the core functions that the Python path calls on their own. Each job runs in a
process of its own (numba compiles on one core; a process that has compiled the kernels has
the core functions compiled inside them, as callees that are never cached, and its Python
path would cache almost nothing), as many at once as there are CPUs (:func:`_slots`): on two,
the loop then the core functions beside the right-hand side, about half the wait. Then a
short compiled run of the default case, with ``none`` and with ``minimal``, checks that both
halves load and run. Exits 0 with a note when
numba is not installed (csim then runs the kernels interpreted, or on the Python path).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

#: the jobs of the warm-up (:func:`compile_part`), each in a process of its own, with what its progress line says
PARTS = {"loop": "the loop (integrate, every integrator and method)",
         "rhs": "the right-hand side, the samples' evaluation and the one-state entries",
         "core": "the core functions of the Python path"}
#: the methods of the check after the compile: one of the plain system, and minimal's partitioned one
METHODS = ("none", "minimal")


def _case(method: str, backend: str):
    """The default case for 0.01 s with ``method`` on ``backend``."""
    from csim.case import load_case
    from csim.io.examples import examples_dir

    settings = ["simulation.t_end=0.01", f"stabilization.method={method}", f"simulation.backend={backend}"]
    return load_case(examples_dir() / "quick_return.yaml", settings)


def compile_part(part: str) -> None:
    """Run one job of the warm-up (:data:`PARTS`).

    ``loop``: ``integrate``, for minimal's partitioned system (the same types as every other
    method's). ``rhs``: ``feval``, ``evaluate_samples`` and the one-state entry points, for the
    plain system. ``core``: a short run of the default case on the Python path with each of
    :data:`METHODS`, whose calls of the core functions (:mod:`csim.physics`) compile them on
    their own into numba's cache beside their sources (else a test session's workers would each
    compile them, about 15 s for three methods on the 2-core machine).
    """
    from csim.fast.runner import compile_loop, compile_rhs
    from csim.pipeline import build_system, initial_state, run_case

    if part == "core":
        for method in METHODS:
            run_case(_case(method, "python"))
        return
    case = _case("minimal" if part == "loop" else "none", "compiled")
    system = build_system(case)
    y0 = initial_state(case, system)
    if part == "loop":
        compile_loop(system, y0, case.integration_settings())
    else:
        compile_rhs(system, y0)


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
        return _part(argv[1]) if argv[:1] == ["--part"] and len(argv) == 2 else _all()
    except KeyboardInterrupt:
        print("csim: warm-up interrupted; the kernels compile on the first run that needs them", file=sys.stderr)
        return 130


def _part(part: str) -> int:
    """One job, in a process of its own (:func:`_all`), which leaves Ctrl-C to its parent: a
    KeyboardInterrupt raised inside numba's compiler can land in a ctypes callback, where
    Python prints it and compiling goes on; the parent ends this process instead. Prints a
    progress line when done (or why it failed, on stderr); returns 0, 1 (failed) or 2 (no such job)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if part not in PARTS:
        print(f"csim.warmup: --part {part!r}: expected one of {', '.join(PARTS)}", file=sys.stderr)
        return 2
    start = time.perf_counter()
    try:
        compile_part(part)
    except Exception as exc:  # numba missing a feature, a compiler error: the runs fall back, say why here
        print(f"csim: compiling {PARTS[part]} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    print(f"csim:   compiled {PARTS[part]} ({time.perf_counter() - start:.0f} s)", flush=True)
    return 0


def _all() -> int:
    """Every job in a process of its own: all at once where there are two CPUs, else one after the other;
    then :func:`check`."""
    from csim.fast.support import numba_available
    from csim.model.cache import kernels_dir

    if not numba_available():
        print("csim: numba is not installed; csim runs the kernels interpreted, or on the Python path (nothing to "
              "compile)")
        return 0
    start = time.perf_counter()
    print(f"csim: compiling the kernels into {kernels_dir()} (once per installation; about 30 s on 2 cores, "
          f"a minute on one) ...", flush=True)
    failed = _run_slots(_slots(os.cpu_count() or 1))
    problem = "" if failed else check()
    if problem:
        print(f"csim: {problem}", file=sys.stderr)
    if failed or problem:
        return 1
    print(f"csim: kernels ready ({time.perf_counter() - start:.0f} s)")
    return 0


def _slots(cpus: int) -> list[list[str]]:
    """The jobs of :data:`PARTS` as slots that run at once, each slot's jobs one after the other: a slot a
    job on three CPUs or more; on two, the loop (about 30 s on the 2-core machine) beside the
    right-hand side (24 s) then the core functions (4-8 s); on one, all in one slot."""
    if cpus >= 3:
        return [[part] for part in PARTS]
    if cpus == 2:
        return [["loop"], ["rhs", "core"]]
    return [list(PARTS)]


def _run_slots(slots: list[list[str]]) -> int:
    """Run each slot's jobs (:func:`_part`, a process each) one after the other, the slots at once; how
    many jobs failed (a failed job ends its slot). After Ctrl-C (which the jobs ignore) none is left
    running."""
    pending = [list(slot) for slot in slots]
    running: dict[int, subprocess.Popen] = {}
    failed = 0
    try:
        while any(pending) or running:
            for i, slot in enumerate(pending):
                if i not in running and slot:
                    running[i] = subprocess.Popen([sys.executable, "-m", "csim.warmup", "--part", slot.pop(0)])
            for i, process in list(running.items()):
                if process.poll() is not None:
                    del running[i]
                    if process.returncode != 0:
                        failed += 1
                        pending[i].clear()
            time.sleep(0.05)
    finally:
        for process in running.values():
            if process.poll() is None:
                process.terminate()
                process.wait()
    return failed


if __name__ == "__main__":
    sys.exit(main())
