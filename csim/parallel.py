"""Worker processes for studies of many runs (``csim compare``, ``csim batch``, ``csim sweep``).

What every pool of runs needs, once: worker processes started by "spawn" (no fork of a
threaded process; the same on every OS) with one BLAS thread each and Ctrl-C blocked (the
parent stops them), a record of Ctrl-C in the parent, and the stop of every worker after it;
and the one loop that hands work to them and takes the results back, :func:`run_in_workers`
(a comparison's or a batch's runs, :mod:`csim.compare.pool`; a sweep's chunks of runs,
:mod:`csim.study.execute`).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Sequence
from contextlib import contextmanager, suppress

#: environment variables that set the thread count of numpy's linear algebra
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def process_pool(jobs: int) -> cf.ProcessPoolExecutor:
    """A pool of ``jobs`` "spawn" worker processes that ignore Ctrl-C (start them inside
    :func:`worker_environment`)."""
    return cf.ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                                  initializer=worker_init)


def worker_processes(executor: cf.ProcessPoolExecutor) -> list:
    """The pool's worker processes (read them before ``shutdown``, which forgets them)."""
    return list((getattr(executor, "_processes", None) or {}).values())


def stop_processes(executor: cf.ProcessPoolExecutor, processes: list | None = None) -> None:
    """End the pool's worker processes now (after Ctrl-C), without waiting for their runs
    (``processes``: as :func:`worker_processes` gave them before a shutdown)."""
    processes = worker_processes(executor) if processes is None else processes
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(5)


def run_in_workers(function: Callable, tasks: Sequence[tuple], jobs: int,
                   done: Callable[[int, object, BaseException | None], None]) -> bool:
    """``function(*task)`` for every task in ``jobs`` worker processes (:func:`process_pool`).

    Parameters
    ----------
    function : callable
        A module-level function (the workers import it by name).
    tasks : sequence of tuple
        Its arguments, one tuple a call, submitted in this order.
    jobs : int
        Worker processes.
    done : callable
        ``done(index, value, error)`` in this process as each call comes back, with ``index``
        the task's position and either its return value (error None) or the exception that
        kept it from coming back (value None): the worker died, or the value could not be
        sent.

    Returns
    -------
    bool
        Whether Ctrl-C stopped the work. The workers are then asked to end their calls
        (:func:`stop_workers`: a run ends with its samples so far); the calls that come back
        within :data:`STOP_GRACE` go to ``done`` too, the others never do.
    """
    executor = process_pool(jobs)
    futures: dict[cf.Future, int] = {}
    try:
        with worker_environment():  # the workers start while the first tasks are submitted
            futures = {executor.submit(function, *task): index for index, task in enumerate(tasks)}
        for future in cf.as_completed(list(futures)):
            index = futures.pop(future)
            try:
                value = future.result()
            except Exception as exc:
                done(index, None, exc)
            else:
                done(index, value, None)
    except KeyboardInterrupt:
        for future in stop_workers(executor, list(futures)):
            done(futures[future], future.result(), None)
        return True
    finally:
        executor.shutdown(wait=True, cancel_futures=True)
    return False


class InterruptFlag:
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


#: the signal by which a parent asks a worker to end its run with the samples so far
#: (:func:`ask_to_stop`; POSIX only)
STOP_SIGNAL = getattr(signal, "SIGUSR1", None)
#: whether this (worker) process is inside a run that :data:`STOP_SIGNAL` may end, and
#: whether the parent has sent it
_IN_RUN = {"active": False, "stop": False}


def worker_init() -> None:
    """Workers ignore Ctrl-C (the parent process stops them), end a run on :data:`STOP_SIGNAL`
    (:func:`stoppable_run`), and end when the parent dies (:func:`end_with_parent`)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if STOP_SIGNAL is not None:
        signal.signal(STOP_SIGNAL, _stop_requested)
    end_with_parent()


def _stop_requested(signum, frame) -> None:
    """:data:`STOP_SIGNAL` in a worker: Ctrl-C for the run under way (a run stopped this way
    comes back with its samples so far); between runs it is only recorded
    (:func:`stop_requested`: a chunk of runs starts no further run)."""
    _IN_RUN["stop"] = True
    if _IN_RUN["active"]:
        raise KeyboardInterrupt


def stop_requested() -> bool:
    """Whether the parent asked this worker process to stop (:func:`ask_to_stop`)."""
    return _IN_RUN["stop"]


@contextmanager
def stoppable_run():
    """The block is a run that :data:`STOP_SIGNAL` (the parent's Ctrl-C) may end; one asked
    to stop already (the signal came between the caller's check and here, while the run
    was being prepared) ends at once."""
    _IN_RUN["active"] = True
    try:
        if _IN_RUN["stop"]:
            raise KeyboardInterrupt
        yield
    finally:
        _IN_RUN["active"] = False


#: the longest the workers have, after Ctrl-C, to send back their runs' samples so far [s]
#: (a run on the Python path evaluates its recorded quantities at every sample first)
STOP_GRACE = 3.0


def wait_for_stopped(futures, grace: float = STOP_GRACE) -> None:
    """After :func:`ask_to_stop`: wait up to ``grace`` seconds for ``futures`` (the work the
    workers had under way) to come back; a second Ctrl-C ends the wait.

    Polled, not ``concurrent.futures.wait``: the executor cancels the work not started in
    its own thread, after ``shutdown``, and a future cancelled there is never reported to
    ``wait``, which would then always sit out the whole grace.
    """
    deadline = time.monotonic() + grace
    with suppress(KeyboardInterrupt):
        while time.monotonic() < deadline and not all(f.done() for f in futures):
            time.sleep(0.02)


def stop_workers(executor: cf.ProcessPoolExecutor, futures) -> list:
    """After Ctrl-C: ask the workers to end their runs (:func:`ask_to_stop`), wait the grace
    for ``futures`` (:func:`wait_for_stopped`), then end the workers (:func:`stop_processes`).
    Returns the futures among ``futures`` that came back with a result within the grace."""
    processes = ask_to_stop(executor)
    wait_for_stopped(futures)
    back = [f for f in futures if f.done() and not f.cancelled() and f.exception() is None]
    stop_processes(executor, processes)
    return back


def ask_to_stop(executor: cf.ProcessPoolExecutor) -> list:
    """After Ctrl-C: cancel the runs not started, and ask the workers to end theirs with the
    samples so far (:data:`STOP_SIGNAL`). Returns the worker processes, for
    :func:`stop_processes` to end after."""
    processes = worker_processes(executor)
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes if STOP_SIGNAL is not None else ():
        with suppress(OSError):
            os.kill(process.pid, STOP_SIGNAL)
    return processes


#: PR_SET_PDEATHSIG of Linux's prctl(2): the signal a process gets when its parent ends
PR_SET_PDEATHSIG = 1
#: how often the watchdog of a system without PR_SET_PDEATHSIG looks for its parent [s]
WATCHDOG_PERIOD = 0.2


def end_with_parent() -> None:
    """End this worker process when the process that started it ends, however it ends.

    A parent killed with SIGKILL (``kill -9``, the out-of-memory killer) runs no clean-up,
    and its workers would go on computing runs nobody collects, for minutes, as orphans.
    On Linux the kernel sends this process SIGKILL when the parent ends (``prctl(2)``
    PR_SET_PDEATHSIG, through ctypes); elsewhere a daemon thread looks for a new parent
    process id every :data:`WATCHDOG_PERIOD` seconds and ends the process. Either way the
    parent's death is checked once more after the arrangement, for a parent that died
    before it.
    """
    parent = multiprocessing.parent_process()
    expected = parent.pid if parent is not None else os.getppid()
    if not _parent_death_signal():
        def watch() -> None:
            while os.getppid() == expected:
                time.sleep(WATCHDOG_PERIOD)
            os._exit(1)
        threading.Thread(target=watch, name="csim-parent-watchdog", daemon=True).start()
    if os.getppid() != expected:  # the parent died before the arrangement
        os._exit(1)


def _parent_death_signal() -> bool:
    """Ask Linux to send this process SIGKILL when its parent ends; False where not available."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


@contextmanager
def worker_environment():
    """Worker processes started inside the block get one BLAS thread (unless the user chose
    a number: the runs' matrices are small, the processes are the parallelism, and idle BLAS
    threads spinning on shared cores slow every run down several times) and ignore Ctrl-C."""
    saved = {name: os.environ.get(name) for name in BLAS_THREADS}
    for name in BLAS_THREADS:
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
