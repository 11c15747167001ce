"""Running the cases of a comparison (or a batch): in this process, or in a pool of worker processes.

:func:`run_tasks` runs (Run, Case) pairs and fills each Run with its result: a
:class:`csim.compare.runs.Run`, or any object with a ``result`` attribute (None until it
ran) and a ``set_result(result, message)`` method (``csim batch``'s
:class:`csim.batch.runner.CaseRun`). One job runs
them in order in this process; more go to fresh ("spawn") worker processes that ignore
Ctrl-C, with one BLAS thread each. Ctrl-C stops the whole comparison: runs that finished
keep their results, the others stay failed rows with the message
:data:`csim.compare.runs.INTERRUPTED`. An exception in a run (or a worker that dies)
becomes that run's failure, not an exception of the comparison.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import copy
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from contextlib import contextmanager

from csim.case import Case, validate_case
from csim.compare.runs import INTERRUPTED, Run
from csim.pipeline import numeric_model
from csim.result import Result

#: a run to make: the Run to fill in, and its validated case
Task = tuple[Run, Case]

#: called as ``progress(run, done, total)`` after each run finishes
Progress = Callable[[Run, int, int], None]

#: environment variables that set the thread count of numpy's linear algebra
_BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def job_count(jobs: int | None, n_tasks: int) -> int:
    """Processes for ``n_tasks`` runs: ``jobs`` (at most one per run), default one per CPU."""
    return min(jobs, n_tasks) if jobs is not None else max(1, min(n_tasks, os.cpu_count() or 1))


def run_tasks(tasks: Sequence[Task], n_jobs: int, progress: Progress | None = None) -> bool:
    """Run every task (the longest first, for a pool) and set each Run's result.

    Parameters
    ----------
    tasks : sequence of (Run, Case)
    n_jobs : int
        1: in this process, one after another; more: that many worker processes.
    progress : callable, optional
        Called as ``progress(run, done, total)`` after each run finishes.

    Returns
    -------
    bool
        Whether Ctrl-C stopped the runs (those unfinished keep the message INTERRUPTED).
    """
    with _InterruptFlag() as flag:
        return (_run_serial if n_jobs == 1 else _run_parallel)(tasks, n_jobs, progress, flag)


def _execute(case_data: dict, source: str) -> tuple[Result | None, str]:
    """Run one validated case in this process; an exception becomes (None, message).

    The numeric model is built (or loaded from the cache) before the run, so that the run's
    wall time is the simulation's alone. The run itself is ``csim.compare.run_case``, looked
    up on the package at each call: that is the name a caller (a test) may replace.
    """
    try:
        case = validate_case(copy.deepcopy(case_data), source=source)
        numeric_model(case)
        return sys.modules[__package__].run_case(case), ""
    except Exception as exc:  # a bug or an unexpected numerical error: a failed row, not a crash
        return None, f"{type(exc).__name__}: {exc}"


class _InterruptFlag:
    """Records Ctrl-C in the main thread while passing it on (as KeyboardInterrupt).

    The driver turns a KeyboardInterrupt inside an integration into a failed run; the flag
    tells the comparison to stop there instead of going on with the next run.
    """

    def __init__(self):
        self.set = False
        self._old = None

    def __enter__(self):
        old = signal.getsignal(signal.SIGINT)
        if threading.current_thread() is threading.main_thread() and callable(old):
            self._old = old

            def handler(signum, frame):
                self.set = True
                self._old(signum, frame)
            signal.signal(signal.SIGINT, handler)
        return self

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
        return False


def _run_serial(tasks: Sequence[Task], n_jobs: int, progress: Progress | None, flag: _InterruptFlag) -> bool:
    """Run the tasks one after another in this process; stop at Ctrl-C (returns True)."""
    total = len(tasks)
    for done, (run, case) in enumerate(tasks, start=1):
        try:
            result, message = _execute(case.data, case.source)
        except KeyboardInterrupt:
            flag.set = True
            result, message = None, INTERRUPTED
        run.set_result(result, message)  # a run that Ctrl-C stopped says so itself
        if flag.set:  # the remaining runs keep their message INTERRUPTED
            return True
        if progress is not None:
            progress(run, done, total)
    return False


def _run_parallel(tasks: Sequence[Task], n_jobs: int, progress: Progress | None, flag: _InterruptFlag) -> bool:
    """Run the tasks in ``n_jobs`` worker processes; stop them all at Ctrl-C (returns True)."""
    # derive (and cache on disk) each mechanism's model once, not in every worker at the same
    # time (a batch has several mechanisms); should that fail, each worker reports the
    # failure as its run's
    for _, case in tasks:
        with contextlib.suppress(Exception):
            numeric_model(case)
    context = multiprocessing.get_context("spawn")  # no fork of a threaded process; same on every OS
    executor = cf.ProcessPoolExecutor(max_workers=n_jobs, mp_context=context, initializer=_worker_init)
    futures: dict[cf.Future, Run] = {}
    try:
        with _worker_environment():  # the workers start while the first runs are submitted
            for run, case in tasks:  # the reference first: it is the longest
                futures[executor.submit(_execute, case.data, case.source)] = run
        _collect(futures, progress)
    except KeyboardInterrupt:
        _stop(executor, futures)
        return True
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
    return False


def _collect(futures: dict[cf.Future, Run], progress: Progress | None) -> None:
    """Set each run's result as its worker finishes."""
    total = len(futures)
    for done, future in enumerate(cf.as_completed(futures), start=1):
        run = futures[future]
        try:
            result, message = future.result()
        except Exception as exc:  # the worker died, or its result could not come back
            result, message = None, f"worker process failed: {type(exc).__name__}: {exc}"
        run.set_result(result, message)
        if progress is not None:
            progress(run, done, total)


def _stop(executor: cf.ProcessPoolExecutor, futures: dict[cf.Future, Run]) -> None:
    """After Ctrl-C: keep the results that came in, end the workers, mark the rest interrupted."""
    for future, run in futures.items():  # runs that finished before the interrupt keep their results
        if run.result is None and future.done() and not future.cancelled() and future.exception() is None:
            run.set_result(*future.result())
    processes = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(5)
    for future, run in futures.items():
        if run.result is None and (not future.done() or future.cancelled()):
            run.set_result(None, INTERRUPTED)


def _worker_init() -> None:
    """Workers ignore Ctrl-C: the parent process stops them."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@contextmanager
def _worker_environment():
    """Worker processes started inside the block get one BLAS thread (unless the user chose
    a number: the runs' matrices are small, the processes are the parallelism, and idle BLAS
    threads spinning on shared cores slow every run down several times) and ignore Ctrl-C."""
    saved = {name: os.environ.get(name) for name in _BLAS_THREADS}
    for name in _BLAS_THREADS:
        os.environ.setdefault(name, "1")
    # Ctrl-C at a terminal reaches every process of the group: workers start with SIGINT
    # blocked (the mask survives exec), so that only this process handles it; a Ctrl-C
    # during the few milliseconds of the block is delivered here when it ends.
    block = hasattr(signal, "pthread_sigmask") and threading.current_thread() is threading.main_thread()
    if block:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        if block:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
