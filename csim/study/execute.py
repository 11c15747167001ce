"""Running a sweep's runs: in this process, in worker processes, or on a Dask cluster.

The unit of work is a chunk of runs, :func:`run_chunk`: it rebuilds each run's case from the
base case's data and the run's values, runs it in the calling process and returns one row
per run. A worker process (or Dask worker) keeps the mechanism's numeric model and compiled
kernels loaded from one chunk to the next (:func:`csim.pipeline.numeric_model` and
:func:`csim.fast.module.load_module` cache them per process), so a run costs its
integration and its post-processing, not a process start or a model derivation.

Every executor calls ``deliver(done)`` with the finished runs of each chunk, as they
finish, and returns an :class:`Outcome`: whether Ctrl-C stopped it, and whether runs were
lost with a worker that died (the runs not delivered stay pending).

Ctrl-C stops the runs under way: on a worker they end with :data:`csim.parallel.STOP_SIGNAL`,
and each chunk comes back with the runs it finished and, for the run it had under way, a
row of status ``pending`` and reason :data:`INTERRUPTED` (:func:`interrupted_row`): the
sweep file says which runs were stopped, and ``--resume`` runs them again.
"""
from __future__ import annotations

import contextlib
import copy
import dataclasses
import math
import os
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from csim.case import apply_overrides, validate_case
from csim.errors import CaseError, CsimError
from csim.parallel import InterruptFlag, run_in_workers, stop_requested, stoppable_run
from csim.study.metrics import empty_row, failed_row, run_row
from csim.study.plan import override
from csim.study.sweep_file import PENDING

#: (run index, row, signals or None)
Done = tuple[int, dict, dict | None]

#: the signals ``--keep`` records of each run: Result attribute -> dataset name
SIGNALS = ("t", "q", "qd", "phi", "phi_dot", "energy_error")

#: the reason of a run that Ctrl-C stopped while it ran (its status stays ``pending``)
INTERRUPTED = "interrupted"


def interrupted_row(message: str = "") -> dict:
    """The row of a run that Ctrl-C stopped while it ran: pending (``--resume`` runs it
    again), with the reason :data:`INTERRUPTED` and how far it got."""
    text = "stopped by Ctrl-C while it ran" + (f" ({message})" if message else "") + "; --resume runs it again"
    return empty_row(PENDING, INTERRUPTED, text)


def is_interrupted(row: dict) -> bool:
    """Whether ``row`` is an :func:`interrupted_row` (a run stopped, not finished)."""
    return row["status"] == PENDING


@dataclass(frozen=True)
class Work:
    """What every chunk needs besides its runs (sent once per chunk; small)."""

    data: dict  # the base case's data as read (with --set applied), before validation
    source: str
    keys: tuple[str, ...]
    reference: tuple[np.ndarray, np.ndarray] | None = None  # (t, q) of the reference run
    keep: bool = False
    stop_event: str | None = None  # on a Dask cluster: the name of the Event that asks chunks to stop


#: how often a chunk on a Dask cluster asks the scheduler whether to stop [s]
STOP_POLL = 0.25
#: how long Ctrl-C waits for the chunks under way on a Dask cluster to bring back their runs [s]
DASK_GRACE = 5.0


def _stop_check(name: str | None) -> Callable[[], bool]:
    """Whether the sweep's parent asked to stop, asked of the Dask Event ``name`` at most
    every :data:`STOP_POLL` seconds (a scheduler round trip); always False without one."""
    if name is None:
        return lambda: False
    from distributed import Event

    event, last = Event(name), [-math.inf]  # asked before the first run, then every STOP_POLL s

    def check() -> bool:
        if time.monotonic() - last[0] < STOP_POLL:
            return False
        last[0] = time.monotonic()
        try:
            return event.is_set()
        except Exception:  # the scheduler is gone: the parent will not take the rows anyway
            return True
    return check


def run_chunk(work: Work, chunk: Sequence[tuple[int, tuple]]) -> list[Done]:
    """Run ``chunk`` ((index, values) pairs) in this process; an exception fails its run, not the chunk.

    Ctrl-C (in a worker, the parent's :data:`csim.parallel.STOP_SIGNAL`) ends the chunk: it
    returns the runs finished so far and an :func:`interrupted_row` for the run under way.
    """
    from csim.pipeline import run_case

    out = []
    stop_asked = _stop_check(work.stop_event)
    for i, values in chunk:
        if stop_requested() or stop_asked():  # the parent asked to stop between two runs: start no other
            break
        try:
            data = apply_overrides(copy.deepcopy(work.data), [override(k, v) for k, v in zip(work.keys, values)])
            case = validate_case(data, source=f"{work.source} (sweep run {i})")
        except CaseError as exc:
            out.append((i, failed_row("case: " + "; ".join(exc.problems), "invalid"), None))
            continue
        try:
            with stoppable_run():  # in a worker, the parent's Ctrl-C ends the run
                result = run_case(case)
        except KeyboardInterrupt:
            out.append((i, interrupted_row(), None))
            break
        except Exception as exc:  # a bug or an unexpected numerical error: a failed row, not a crash
            out.append((i, failed_row(f"{type(exc).__name__}: {exc}", "other"), None))
            continue
        if result.failure == INTERRUPTED:  # the integration turned Ctrl-C into a failed run
            out.append((i, interrupted_row(result.message), None))
            break
        signals = {name: np.asarray(getattr(result, name)) for name in SIGNALS} if work.keep else None
        out.append((i, run_row(result, work.reference), signals))
    return out


def chunks(todo: Sequence[int], rows: Sequence[tuple], workers: int) -> list[list[tuple[int, tuple]]]:
    """The runs ``todo`` in chunks: about four per worker, at most 64 runs each (for progress and Ctrl-C)."""
    size = max(1, min(64, math.ceil(len(todo) / (4 * max(workers, 1)))))
    return [[(i, rows[i]) for i in todo[s:s + size]] for s in range(0, len(todo), size)]


@dataclass
class Outcome:
    """How an executor stopped: every run delivered, Ctrl-C, or runs lost with their workers.

    Runs not delivered stay pending in the sweep (``--resume`` runs them).
    """

    interrupted: bool = False
    lost: str = ""  # why some runs came back from no worker ("" when none was lost)


def run_serial(work: Work, todo: list[tuple[int, tuple]], deliver: Callable[[list[Done]], None]) -> Outcome:
    """Every run in this process, one at a time (Ctrl-C keeps every run finished before it)."""
    with InterruptFlag() as flag:
        for run in todo:
            try:
                done = run_chunk(work, [run])
            except KeyboardInterrupt:  # between runs, or before its integration started
                return Outcome(interrupted=True)
            deliver(done)  # a run that Ctrl-C stopped comes back as an interrupted row
            if flag.set or any(is_interrupted(row) for _, row, _ in done):
                return Outcome(interrupted=True)
    return Outcome()


def run_local(work: Work, parts: list, jobs: int, deliver: Callable[[list[Done]], None]) -> Outcome:
    """The chunks in ``jobs`` worker processes (:func:`csim.parallel.run_in_workers`: "spawn",
    one BLAS thread each; at Ctrl-C the chunks under way come back with the runs they finished)."""
    if jobs == 1:
        return run_serial(work, [run for part in parts for run in part], deliver)
    lost = []

    def done(index: int, rows, error: BaseException | None) -> None:
        if error is not None:
            lost.append(_worker_failed(error))
        deliver(rows or [])

    interrupted = run_in_workers(run_chunk, [(work, part) for part in parts], jobs, done)
    return Outcome(interrupted=interrupted, lost=lost[0] if lost else "")


def _chunk_result(future) -> tuple[list[Done], str]:
    """A chunk's rows, or none and why (the worker died, or its result could not come back)."""
    try:
        return future.result(), ""
    except Exception as exc:
        return [], _worker_failed(exc)


def _worker_failed(exc: BaseException) -> str:
    """Why a chunk's runs came back from no worker (:attr:`Outcome.lost`)."""
    return f"a worker failed ({type(exc).__name__}: {exc})"


def connect(address: str):
    """A Dask client of the scheduler at ``address`` (``--scheduler``).

    Raises
    ------
    CsimError
        When dask's distributed package is missing or the scheduler cannot be reached.
    """
    try:
        from distributed import Client
    except ImportError:
        raise CsimError("--scheduler: Dask's distributed package is not installed; "
                        "pip install 'csim-multibody[dask]'") from None
    try:
        return Client(address, set_as_default=False, timeout="10s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise CsimError(f"--scheduler {address}: cannot reach a Dask scheduler there ({type(exc).__name__}: "
                        f"{exc}); expected an address such as tcp://HOST:8786") from None


def run_dask(work: Work, parts: list, client, deliver: Callable[[list[Done]], None],
             grace: float = DASK_GRACE) -> Outcome:
    """The chunks on the Dask cluster of ``client`` (from :func:`connect`).

    Ctrl-C sets a Dask Event that every chunk reads between its runs: a chunk under way
    finishes the run it has started (a remote run cannot be signalled), starts no other and
    comes back with the runs it finished, for at most ``grace`` seconds; the chunks still
    out then are cancelled, and their runs stay pending (``--resume`` runs them).
    """
    from distributed import Event, as_completed

    stop = Event(f"csim-sweep-stop-{uuid.uuid4().hex}", client=client)
    scattered = client.scatter(dataclasses.replace(work, stop_event=stop.name), broadcast=True)  # sent once
    pending = {client.submit(run_chunk, scattered, part, pure=False): part for part in parts}
    lost = ""
    try:
        for future in as_completed(list(pending), loop=client.loop):
            pending.pop(future)
            done, why = _chunk_result(future)
            deliver(done)
            lost = lost or why
    except KeyboardInterrupt:
        with contextlib.suppress(Exception):  # a scheduler gone: nothing to wait for
            stop.set()
        try:
            deadline = time.monotonic() + grace
            while pending and time.monotonic() < deadline:
                for future in [f for f in pending if f.done()]:
                    pending.pop(future)
                    done, why = _chunk_result(future)
                    deliver(done)  # (a failure to store them is the sweep's error, raised)
                    lost = lost or why
                time.sleep(0.02)
        except KeyboardInterrupt:  # a second Ctrl-C skips the wait
            pass
        with contextlib.suppress(Exception):
            client.cancel(list(pending))
        return Outcome(interrupted=True, lost=lost)
    return Outcome(lost=lost)


def default_jobs(n_runs: int) -> int:
    """One worker process per CPU, at most one per chunk of runs."""
    return max(1, min(os.cpu_count() or 1, n_runs))
