"""Worker processes for studies of many runs (``csim compare``, ``csim batch``, ``csim sweep``).

What every pool of runs needs, once: worker processes started by "spawn" (no fork of a
threaded process; the same on every OS) with one BLAS thread each and Ctrl-C blocked (the
parent stops them), a record of Ctrl-C in the parent, and the stop of every worker after it.
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import signal
import threading
from contextlib import contextmanager

#: environment variables that set the thread count of numpy's linear algebra
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "VECLIB_MAXIMUM_THREADS")


def process_pool(jobs: int) -> cf.ProcessPoolExecutor:
    """A pool of ``jobs`` "spawn" worker processes that ignore Ctrl-C (start them inside
    :func:`worker_environment`)."""
    return cf.ProcessPoolExecutor(max_workers=jobs, mp_context=multiprocessing.get_context("spawn"),
                                  initializer=worker_init)


def stop_processes(executor: cf.ProcessPoolExecutor) -> None:
    """End the pool's worker processes now (after Ctrl-C), without waiting for their runs."""
    processes = list((getattr(executor, "_processes", None) or {}).values())
    executor.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(5)


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


def worker_init() -> None:
    """Workers ignore Ctrl-C: the parent process stops them."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


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
