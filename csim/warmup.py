"""Compile the kernels once for this installation: ``python -m csim.warmup`` (``make install``).

numba compiles the kernels' one copy (:mod:`csim.fast.module`) into
:func:`csim.model.cache.kernels_dir`, so that no later command, test session included, waits
for it. Its two halves share nothing that numba caches (:mod:`csim.fast.linking`: what an
entry point calls is compiled into it): the loop, ``integrate``, with the projection's entry
point, and the right-hand side the loop calls by address with the elimination's solve, the
samples' evaluation and the right-hand side's entry points. The second job first compiles the
core functions that the Python path calls on their own (a short Python-path run), which its
right-hand side then calls as they are (typed once, not twice: 2 s less). Each job runs in a
process of its own (numba compiles on one core; in a process that has compiled the kernels the
functions they call have no machine code of their own, :func:`csim.fast.linking.entry_points_only`),
both at once where there are two CPUs (:func:`_slots`), about half the wait. Then a short
compiled run of the default case, with ``none`` and with ``minimal``, checks that both halves
load and run. Exits 0 with a note when numba is not installed (csim then runs the kernels
interpreted, or on the Python path).
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

#: the jobs of the warm-up (:func:`compile_part`), each in a process of its own, with what its progress line says
PARTS = {"loop": "the loop (integrate, every integrator and method) and the projection's entry",
         "rhs": "the Python path's core functions, then the right-hand side, the elimination's solve, the "
                "samples' evaluation and the right-hand side's entries"}
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

    ``loop``: ``integrate`` and ``project_entry``, for minimal's partitioned system (the same types as
    every other method's; :func:`csim.fast.runner.compile_loop`). ``rhs``: first a short run of the
    default case on the Python path with each of :data:`METHODS`, whose calls of the core functions
    (:mod:`csim.physics`) compile them on their own into numba's cache beside their sources (else a
    test session's workers would each compile them, about 15 s for three methods on the 2-core
    machine); then ``feval``, ``eliminated``, ``evaluate_samples``, ``rhs_entry`` and ``rhs_repeat``, for
    the plain system (:func:`csim.fast.runner.compile_rhs`), which call those core functions as they
    are. Neither gives the functions their entry points call machine code of their own
    (:func:`csim.fast.linking.entry_points_only`), from the kernels' compile on.
    """
    from csim.fast import linking
    from csim.fast.runner import compile_loop, compile_rhs
    from csim.pipeline import build_system, initial_state, run_case

    core_failed = None
    if part == "rhs":
        try:
            for method in METHODS:
                run_case(_case(method, "python"))
        except Exception as exc:  # the right-hand side compiles all the same; the job fails after it
            core_failed = exc
    linking.entry_points_only()  # this process calls only entry points: no machine code for their callees
    case = _case("minimal" if part == "loop" else "none", "compiled")
    system = build_system(case)
    y0 = initial_state(case, system)
    if part == "loop":
        compile_loop(system, y0, case.integration_settings())
    else:
        compile_rhs(system, y0)
    if core_failed is not None:
        raise RuntimeError(f"the Python path's run (its core functions; the right-hand side compiled): "
                           f"{type(core_failed).__name__}: {core_failed}") from core_failed


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
    """``python -m csim.warmup``: every job (:func:`_all`); ``--part JOB``: one job (:func:`_part`). Returns the
    exit status: 0, 1 (a job or the check failed), 2 (a command line it does not take), 130 (Ctrl-C)."""
    argv = sys.argv[1:] if argv is None else argv
    try:
        if not argv:
            return _all()
        if len(argv) == 2 and argv[0] == "--part" and argv[1] in PARTS:
            return _part(argv[1])
        print(f"usage: python -m csim.warmup [--part {{{','.join(PARTS)}}}] (got {' '.join(argv)!r})",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("csim: warm-up interrupted; the kernels compile on the first run that needs them", file=sys.stderr)
        return 130


def _part(part: str) -> int:
    """One job of :data:`PARTS`, in a process of its own (:func:`_run_slots` starts it in a process group of
    its own, so a Ctrl-C at the terminal reaches only the parent, which ends it: a KeyboardInterrupt raised
    inside numba's compiler can land in a ctypes callback, where Python prints it and compiling goes on).
    Prints a progress line when done, or why it failed on stderr; returns 0 or 1 (failed)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # (and so when run by hand)
    start = time.perf_counter()
    try:
        compile_part(part)
    except Exception as exc:  # numba missing a feature, a compiler error: the runs fall back, say why here
        print(f"csim: compiling {PARTS[part]} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    print(f"csim:   compiled {PARTS[part]} ({time.perf_counter() - start:.0f} s)", flush=True)
    return 0


def _all() -> int:
    """Every job of :data:`PARTS`, each in a process of its own, as many at once as there are CPUs
    (:func:`_slots`); then :func:`check`. Returns 0, or 1 where a job or the check failed."""
    from csim.fast.support import numba_available
    from csim.model.cache import kernels_dir

    if not numba_available():
        print("csim: numba is not installed; csim runs the kernels interpreted, or on the Python path (nothing to "
              "compile)")
        return 0
    start = time.perf_counter()
    print(f"csim: compiling the kernels into {kernels_dir()} (once per installation; about 30 s on 2 cores, "
          f"twice that on one) ...", flush=True)
    failed = _run_slots(_slots(_cpus()))
    if failed:
        print(f"csim: {failed} of {len(PARTS)} jobs of the warm-up failed (see above); the runs that need what "
              f"they compile compile it on first use", file=sys.stderr)
        return 1
    problem = check()
    if problem:
        print(f"csim: {problem}", file=sys.stderr)
        return 1
    print(f"csim: kernels ready ({time.perf_counter() - start:.0f} s)")
    return 0


def _cpus() -> int:
    """The CPUs this process may run on (its affinity, where the system tells it; else all of them)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _slots(cpus: int) -> list[list[str]]:
    """The jobs of :data:`PARTS` as slots that run at once, each slot's jobs one after the other.

    Parameters
    ----------
    cpus : int
        The CPUs to use: a slot a job on two or more (on the 2-core machine, 2026-11-27, the loop
        27 s beside the core functions and the right-hand side 5 + 21 s); on one, both jobs in one slot.

    Returns
    -------
    list of list of str
        The slots, each a list of job names.
    """
    if cpus >= 2:
        return [[part] for part in PARTS]
    return [list(PARTS)]


def _run_slots(slots: list[list[str]]) -> int:
    """Run each slot's jobs one after the other (``python -m csim.warmup --part JOB``, a process each, in a
    process group of its own), the slots at once, every job whatever the others do: they are independent.

    Returns
    -------
    int
        How many jobs failed. After Ctrl-C none is left running: the KeyboardInterrupt comes here (Ctrl-C
        is held back while a process starts, so that each one started is one waited for) and every
        running job is ended.
    """
    pending = [list(slot) for slot in slots]
    running: dict[int, subprocess.Popen] = {}
    failed = 0
    try:
        while any(pending) or running:
            for i, slot in enumerate(pending):
                if i not in running and slot:
                    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
                    try:
                        running[i] = subprocess.Popen([sys.executable, "-m", "csim.warmup", "--part", slot.pop(0)],
                                                      process_group=0)
                    finally:
                        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
            for i, process in list(running.items()):
                if process.poll() is not None:
                    del running[i]
                    failed += process.returncode != 0
            time.sleep(0.05)
    finally:
        for process in running.values():
            if process.poll() is None:
                process.terminate()
                process.wait()
    return failed


if __name__ == "__main__":
    sys.exit(main())
