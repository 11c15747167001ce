"""The comparison file: its tables' columns, its attributes, and a group per method run.

:func:`write_file` hands everything to :func:`csim.io.hdf5.write_comparison`, which owns
the layout (``/METHOD``, ``/reference``, ``/summary``, ``/work_precision``) and writes it
atomically. A run that has no result (it raised, or never ran) gets an empty failed one, so
that every method has its group.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from csim.compare.runs import Run
from csim.io.hdf5 import write_comparison
from csim.result import Result

if TYPE_CHECKING:
    from csim.compare.comparison import Comparison


def table_columns(runs: Sequence[Run]) -> dict[str, list]:
    """The columns of a table of ``runs``, one entry per run (units in
    :data:`csim.io.hdf5.COMPARISON_UNITS`)."""
    return {
        "method": [r.method for r in runs],
        "tolerance": [float(r.tolerance) for r in runs],
        "tolerance_kind": [r.tolerance_kind for r in runs],
        "status": [r.status for r in runs],
        "message": [r.message for r in runs],
        "max_phi": [r.max_phi for r in runs],
        "final_phi": [r.final_phi for r in runs],
        "max_phi_dot": [r.max_phi_dot for r in runs],
        "motion_error": [r.motion_error for r in runs],
        "final_error": [r.final_error for r in runs],
        "error_until": [r.error_until for r in runs],
        "wall_time": [r.wall_time for r in runs],
        "nfev": [int(r.nfev) for r in runs],
        "nsteps": [int(r.nsteps) for r in runs],
        "backend": [r.result.backend if r.result is not None else "" for r in runs],
    }


def write_file(comparison: Comparison, path: str | Path) -> None:
    """Write ``comparison`` to ``path`` (atomically; layout in :mod:`csim.io.hdf5`)."""
    c = comparison
    tables = {"summary": table_columns(list(c.method_runs.values()))}
    if c.tolerances is not None:
        tables["work_precision"] = table_columns(c.runs)
    runs = {m: _result_or_empty(r, c.mechanism) for m, r in c.method_runs.items()}
    write_comparison(path, runs, _result_or_empty(c.reference_run, c.mechanism), _root_attributes(c), tables,
                     c.coordinate_units)


def _root_attributes(c: Comparison) -> dict:
    """The file's root attributes: the case, the settings and how the comparison went."""
    ref = c.reference_run
    return dict(
        case=c.case_yaml, source=c.source, mechanism=c.mechanism,
        integrator=c.integrator, tolerance_kind=c.tolerance_kind,
        tolerances=c.tolerances if c.tolerances is not None else [],
        reference_method=c.reference.method, reference_integrator=c.reference.integrator,
        reference_tol=c.reference.tol, reference_status=ref.status, reference_message=ref.message,
        jobs=c.jobs, repeat=c.repeat, interrupted=c.interrupted, setting=c.setting,
        skipped_methods=list(c.skipped), skipped_reasons=[c.skipped[m] for m in c.skipped],
    )


def _result_or_empty(run: Run, mechanism: str) -> Result:
    """The run's result, or an empty failed one (a run that raised or never ran)."""
    if run.result is not None:
        return run.result
    return Result(
        mechanism=mechanism, coordinate_names=[], load_names=[], observable_names=[],
        case_yaml=run.case_yaml, t=np.zeros(0), q=np.zeros((0, 0)), qd=np.zeros((0, 0)), qdd=np.zeros((0, 0)),
        lam=np.zeros((0, 0)), phi=np.zeros((0, 0)), phi_dot=np.zeros((0, 0)), kinetic=np.zeros(0),
        potential=np.zeros(0), work=np.zeros((0, 0)), loads=np.zeros((0, 0)),
        generalized_forces=np.zeros((0, 0)), observables=np.zeros((0, 0)), observable_rates=np.zeros((0, 0)),
        status="failed", message=run.message, wall_time=0.0 if math.isnan(run.wall_time) else run.wall_time,
    )
