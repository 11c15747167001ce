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

import contextlib
import copy
import itertools
import os
import sys
from collections.abc import Callable, Sequence

import numpy as np

from csim.case import Case, validate_case
from csim.compare.runs import INTERRUPTED, Run
from csim.parallel import InterruptFlag, run_in_workers, stop_requested, stoppable_run
from csim.pipeline import numeric_model
from csim.result import Result

#: a run to make: the Run to fill in, and its validated case
Task = tuple[Run, Case]

#: called as ``progress(run, done, total)`` after each run finishes
Progress = Callable[[Run, int, int], None]



def job_count(jobs: int | None, n_tasks: int) -> int:
    """Processes for ``n_tasks`` runs: ``jobs`` (at most one per run), default one per CPU."""
    return min(jobs, n_tasks) if jobs is not None else max(1, min(n_tasks, os.cpu_count() or 1))


def run_tasks(tasks: Sequence[Task], n_jobs: int, progress: Progress | None = None, repeat: int = 1) -> bool:
    """Run every task (the longest first, for a pool) and set each Run's result.

    Parameters
    ----------
    tasks : sequence of (Run, Case)
    n_jobs : int
        1: in this process, one after another; more: that many worker processes.
    progress : callable, optional
        Called as ``progress(run, done, total)`` after each run finishes.
    repeat : int
        Run each case this many times; its result is the last run's, with the median of the
        runs' wall times (a work-precision chart's timings, less at the mercy of one busy
        moment of the machine).

    Returns
    -------
    bool
        Whether Ctrl-C stopped the runs (those unfinished keep the message INTERRUPTED).
    """
    with InterruptFlag() as flag:
        return (_run_serial if n_jobs == 1 else _run_parallel)(tasks, n_jobs, progress, flag, repeat)


def _execute(case_data: dict, source: str, repeat: int = 1) -> tuple[Result | None, str]:
    """Run one validated case in this process; an exception becomes (None, message).

    The numeric model is built (or loaded from the cache) before the run, so that the run's
    wall time is the simulation's alone. The run itself is ``csim.compare.run_case``, looked
    up on the package at each call: that is the name a caller (a test) may replace.
    """
    try:
        case = validate_case(copy.deepcopy(case_data), source=source)
        numeric_model(case)
        run_case = sys.modules[__package__].run_case
        with stoppable_run():  # in a worker, the parent's Ctrl-C ends the run with its samples so far
            results = [run_case(case) for _ in range(max(1, repeat))]
        result = results[-1]
        result.wall_time = float(np.median([r.wall_time for r in results]))
        return result, ""
    except KeyboardInterrupt:
        if stop_requested():  # a worker asked to stop before its run began: it ran nothing
            return None, INTERRUPTED
        raise  # Ctrl-C in this process (jobs 1): the caller stops every run
    except Exception as exc:  # a bug or an unexpected numerical error: a failed row, not a crash
        return None, f"{type(exc).__name__}: {exc}"


def _run_serial(tasks: Sequence[Task], n_jobs: int, progress: Progress | None, flag: InterruptFlag,
                repeat: int = 1) -> bool:
    """Run the tasks one after another in this process; stop at Ctrl-C (returns True)."""
    total = len(tasks)
    for done, (run, case) in enumerate(tasks, start=1):
        try:
            result, message = _execute(case.data, case.source, repeat)
        except KeyboardInterrupt:
            flag.set = True
            result, message = None, INTERRUPTED
        run.set_result(result, message)  # a run that Ctrl-C stopped says so itself
        if flag.set:  # the remaining runs keep their message INTERRUPTED
            return True
        if progress is not None:
            progress(run, done, total)
    return False


def _run_parallel(tasks: Sequence[Task], n_jobs: int, progress: Progress | None, flag: InterruptFlag,
                  repeat: int = 1) -> bool:
    """Run the tasks in ``n_jobs`` worker processes (:func:`csim.parallel.run_in_workers`);
    stop them all at Ctrl-C (returns True: the runs that did not come back say INTERRUPTED)."""
    # derive (and cache on disk) each mechanism's model once, not in every worker at the same
    # time (a batch has several mechanisms); should that fail, each worker reports the
    # failure as its run's
    for _, case in tasks:
        with contextlib.suppress(Exception):
            numeric_model(case)
    runs, count = [run for run, _ in tasks], itertools.count(1)

    def done(index: int, value, error: BaseException | None) -> None:
        run = runs[index]
        if error is not None:  # the worker died, or its result could not come back
            value = None, f"worker process failed: {type(error).__name__}: {error}"
        run.set_result(*value)
        if progress is not None:
            progress(run, next(count), len(runs))

    # the reference first: it is the longest
    interrupted = run_in_workers(_execute, [(case.data, case.source, repeat) for _, case in tasks], n_jobs, done)
    for run in runs if interrupted else ():  # not started, or not back within the grace
        if run.result is None:
            run.set_result(None, INTERRUPTED)
    return interrupted
