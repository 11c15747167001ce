"""What a sweep records of each run: its outcome, why it failed, and its figures of merit.

A row is a plain dict (it travels back from worker processes and Dask workers): the
columns of :data:`COLUMNS`, in their units, NaN where a run has no value (a failed run
that wrote no sample, or no reference run).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.compare.metrics import constraint_errors, motion_error
from csim.result import FAILURE_KINDS, Result, failure_kind

NAN = float("nan")


@dataclass(frozen=True)
class Column:
    """One per-run number of a sweep: name (HDF5 dataset and table header), unit, description."""

    name: str
    unit: str
    doc: str
    dtype: str = "f8"


#: the numbers of each run, in their order in the file and the table
COLUMNS = (
    Column("max_phi", "unit of Phi", "max |Phi_i| over the run"),
    Column("final_phi", "unit of Phi", "max |Phi_i| at the last sample"),
    Column("max_phi_dot", "unit of Phi/s", "max |(Phi_q qd)_i| over the run"),
    Column("energy_error", "1", "max |T + V - T0 - V0 - W| / energy scale (NaN for a kinematic analysis)"),
    Column("energy_error_abs", "J", "max |T + V - T0 - V0 - W|"),
    Column("error", "rad or m", "max |q - q_ref| against the reference run, over the samples both reached"),
    Column("final_error", "rad or m", "max |q(t_end) - q_ref(t_end)| (NaN when either run stopped early)"),
    Column("t_reached", "s", "the last sample's time"),
    Column("wall_time", "s", "the integration's wall time (the run's own; not its post-processing)"),
    Column("nfev", "1", "right-hand-side evaluations", "i8"),
    Column("nsteps", "1", "integration steps", "i8"),
    Column("events", "1", "located switching events", "i8"),
)

#: why a run failed (the kinds of :attr:`csim.result.Result.failure`)
REASONS = FAILURE_KINDS


def failure_reason(status: str, message: str, failure: str = "") -> str:
    """A short name of why a run failed ("" for a success; "other" for a message not listed):
    ``failure`` where given (a result's :attr:`~csim.result.Result.failure`), else the kind
    its message names (:func:`csim.result.failure_kind`)."""
    if status == "success":
        return ""
    return failure or failure_kind(message)


def run_row(result: Result, reference: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """The row of one run: ``status``, ``reason``, ``message`` and every :data:`COLUMNS` value;
    ``reference`` is the reference run's (t (N,) [s], q (N, m))."""
    max_phi, final_phi, max_phi_dot = constraint_errors(result.phi, result.phi_dot)
    row = dict(status=result.status, reason=failure_reason(result.status, result.message, result.failure),
               message=result.message, max_phi=max_phi, final_phi=final_phi, max_phi_dot=max_phi_dot,
               energy_error=NAN, energy_error_abs=NAN, error=NAN, final_error=NAN,
               t_reached=float(result.t[-1]) if result.t.size else NAN, wall_time=float(result.wall_time),
               nfev=int(result.nfev), nsteps=int(result.nsteps), events=int(len(result.event_times)))
    if result.t.size and result.run_kind != "kinematic":
        with np.errstate(invalid="ignore", over="ignore"):
            row["energy_error"] = result.energy_error_relative
            row["energy_error_abs"] = result.energy_error_max
    if reference is not None and reference[0].size and result.t.size:
        err = motion_error(result.t, result.q, *reference)
        row["error"], row["final_error"] = err.motion, err.final
    return row


def empty_row(status: str, reason: str = "", message: str = "") -> dict:
    """The row of a run without a result: no numbers (NaN, counts 0)."""
    row = {c.name: (0 if c.dtype == "i8" else NAN) for c in COLUMNS}
    return dict(status=status, reason=reason, message=message, **row)


def failed_row(message: str, reason: str) -> dict:
    """The row of a run that produced no result (its case was rejected, or its worker died)."""
    return empty_row("failed", reason, message)
