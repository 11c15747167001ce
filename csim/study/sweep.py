"""A sweep: run every row of a plan, keep the finished rows, checkpoint them, write the file.

:func:`run_sweep` is what ``csim sweep`` calls: it runs the optional reference run, then the
plan's runs not done yet (all of them, or those an interrupted file left pending) on the
executor asked for, writing the sweep file atomically every ``checkpoint`` seconds and at
the end, so that Ctrl-C or a crash loses at most the runs since the last checkpoint and
``--resume`` goes on from there.
"""
from __future__ import annotations

import copy
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from csim.case import apply_overrides, validate_case
from csim.errors import CaseError, ResultFileError, SimulationFailure
from csim.io.units import common_unit, mechanism_units, per_time
from csim.result import Result
from csim.study import execute
from csim.study.metrics import COLUMNS, empty_row
from csim.study.plan import SweepPlan, key_unit
from csim.study.sweep_file import PENDING, SweepTable, read_sweep, write_sweep

#: keys a reference run may not change: the motion error compares samples at the same times
REFERENCE_FIXED = ("output.dt", "simulation.t_end")

#: called as ``progress(done, total)`` as runs finish
Progress = Callable[[int, int], None]


@dataclass
class Sweep:
    """The state of a sweep: its plan, the row of each finished run, the reference run.

    Attributes
    ----------
    plan : SweepPlan
    rows : list of dict or None
        One per run, None while a run is pending.
    reference : tuple (t, q) or None
        The reference run's samples, with ``reference_overrides``.
    interrupted : bool
        Ctrl-C stopped the sweep before every run finished.
    stopped : dict of int -> dict
        The runs Ctrl-C stopped while they ran: index -> their row (status pending, reason
        ``interrupted``; still pending in ``rows``).
    lost : str
        Why runs came back from no worker (a worker process died; they stay pending).
    """

    plan: SweepPlan
    rows: list
    reference: tuple[np.ndarray, np.ndarray] | None = None
    reference_overrides: list[str] = field(default_factory=list)
    interrupted: bool = False
    lost: str = ""
    stopped: dict[int, dict] = field(default_factory=dict)
    new_signals: dict[int, dict] = field(default_factory=dict)
    _units: tuple[list[str], list[str]] | None = field(default=None, repr=False)
    out: Path | None = None
    resumed: bool = False
    written: bool = False

    @property
    def done(self) -> int:
        return sum(r is not None for r in self.rows)

    @property
    def complete(self) -> bool:
        return self.done == len(self.rows)

    def counts(self) -> dict[str, int]:
        """Runs by outcome: ``success``, each failure reason, ``pending`` (not started), and
        ``interrupted (pending)`` (stopped by Ctrl-C while they ran)."""
        out: dict[str, int] = {}
        for i, row in enumerate(self.rows):
            if row is None:
                label = f"{execute.INTERRUPTED} ({PENDING})" if i in self.stopped else PENDING
            else:
                label = row["status"] if row["status"] == "success" else row["reason"]
            out[label] = out.get(label, 0) + 1
        return out

    def table(self) -> SweepTable:
        """The sweep as stored (pending runs: status "pending", NaN numbers)."""
        plan = self.plan
        rows = [r if r is not None else self.stopped.get(i) or empty_row(PENDING) for i, r in enumerate(self.rows)]
        columns = {c.name: np.array([r[c.name] for r in rows], dtype=c.dtype) for c in COLUMNS}
        variations = [dict(key=v.key, text=v.text, kind=v.kind, bounds=v.bounds) for v in plan.variations]
        attrs = dict(case=plan.case.to_yaml(), variations=variations, sampling=plan.sampling,
                     seed=-1 if plan.seed is None else int(plan.seed), reference=self.reference_overrides,
                     complete=self.complete, coordinate_names=list(plan.case.mechanism.coordinate_names))
        values = {key: plan.column(key) for key in plan.keys}
        numeric = {v.key: v.numeric for v in plan.variations}
        coords, cons = self.units()
        con, coord = common_unit(cons) if cons else "", common_unit(coords)
        column_units = {"unit of Phi": con, "unit of Phi/s": common_unit([per_time(u) if u else "" for u in cons])
                        if cons else "", "rad or m": coord}
        return SweepTable(keys=plan.keys, values=values, numeric=numeric, columns=columns,
                          units={c.name: column_units.get(c.unit, c.unit) for c in COLUMNS}, attrs=attrs,
                          reference=self.reference,
                          value_units={key: key_unit(plan.case, key, con) for key in plan.keys},
                          coordinate_units=coords, constraint_units=cons,
                          **{name: [r[name] for r in rows] for name in ("status", "reason", "message")})

    def units(self) -> tuple[list[str], list[str]]:
        """The units of the base case's coordinates and constraint functions (found once)."""
        if self._units is None:
            from csim.pipeline import numeric_model

            case = self.plan.case
            model = numeric_model(case)
            u = mechanism_units(case.mechanism, model, model.parameter_vector(case.parameters))
            self._units = (u["coordinate_units"], u["constraint_units"])
        return self._units

    def write(self, path: str | Path) -> None:
        """Write the sweep file (atomically), with the signals kept so far: those of this
        process's earlier checkpoints, and on ``--resume`` the file's own (never those of an
        unrelated file that happened to be at ``path``).

        Raises
        ------
        ResultFileError
            When the file cannot be written (the disk is full, the folder went away).
        """
        previous = Path(path) if (self.written or self.resumed) and Path(path).is_file() else None
        try:
            write_sweep(path, self.table(), self.new_signals, keep_from=previous, n_runs=len(self.rows))
        except (OSError, ValueError, TypeError) as exc:
            raise ResultFileError(f"{path}: cannot write the sweep file ({type(exc).__name__}: {exc})") from None
        self.new_signals = {}
        self.written = True



def reference_run(plan: SweepPlan, overrides: list[str]) -> Result:
    """The base case with ``overrides`` (e.g. tighter tolerances), run once in this process.

    Raises
    ------
    CaseError
        When the overrides are invalid; SimulationFailure when the reference run fails.
    """
    from csim.pipeline import run_case

    fixed = [o for o in overrides if o.split("=", 1)[0].strip() in REFERENCE_FIXED]
    if fixed:
        raise CaseError([f"--reference {o}: the reference run keeps the sweep's output times "
                         f"({', '.join(REFERENCE_FIXED)}), so that each run is compared at the same instants"
                         for o in fixed])
    try:
        data = apply_overrides(copy.deepcopy(plan.data), overrides)
        case = validate_case(data, source=f"{plan.case.source} (reference)")
    except CaseError as exc:
        raise CaseError([f"--reference: {p.removeprefix('--set ')}" for p in exc.problems]) from None
    result = run_case(case)
    if not result.ok:
        raise SimulationFailure(f"the reference run ({' '.join(overrides) or 'the base case'}) failed: "
                                f"{result.message}", result.failure)
    return result


def resumed_rows(plan: SweepPlan, stored: SweepTable) -> list:
    """The finished rows of an interrupted sweep file, when it holds the same plan.

    Raises
    ------
    CaseError
        When the file's case, keys or values differ from the plan's.
    """
    problems = []
    if stored.attrs.get("case") != plan.case.to_yaml():
        problems.append("--resume: the file was made from another case (or other --set values)")
    if stored.keys != plan.keys or stored.n != len(plan):
        problems.append(f"--resume: the file varies {stored.keys} in {stored.n} runs; this sweep {plan.keys} "
                        f"in {len(plan)} runs")
    elif any(not _same_values(stored.values[k], plan.column(k)) for k in plan.keys):
        problems.append("--resume: the file's values differ from this sweep's (give the same --vary options, "
                        "and --seed for a random design)")
    if problems:
        raise CaseError(problems)
    rows: list = []
    for i in range(stored.n):
        if stored.status[i] == PENDING:
            rows.append(None)
            continue
        row = {name: getattr(stored, name)[i] for name in ("status", "reason", "message")}
        row.update({c.name: stored.columns[c.name][i].item() for c in COLUMNS})
        rows.append(row)
    return rows


def _same_values(stored: list, planned: list) -> bool:
    """Whether a key's stored values are the plan's (numbers compared as float64, the file's type)."""
    try:
        return np.array_equal(np.asarray(stored, dtype=float), np.asarray(planned, dtype=float))
    except (TypeError, ValueError):
        return json.dumps(stored) == json.dumps(planned)


def _warm_up(plan: SweepPlan) -> None:
    """Derive the model and compile the kernels once here, before workers load them from the cache."""
    from csim.fast import prepare_compiled, resolve_backend
    from csim.pipeline import build_system, initial_state

    try:
        system = build_system(plan.case)
        if resolve_backend(plan.case) == "compiled":
            prepare_compiled(system, initial_state(plan.case, system), plan.case.integration_settings())
    except Exception:  # each run reports its own failure
        pass


def _run(sweep: Sweep, out, jobs, client, keep: bool, progress, checkpoint: float) -> execute.Outcome:
    """Run the pending rows of ``sweep``, writing the file every ``checkpoint`` seconds."""
    plan = sweep.plan
    todo = [i for i, row in enumerate(sweep.rows) if row is None]
    work = execute.Work(data=plan.data, source=plan.case.source, keys=tuple(plan.keys),
                        reference=sweep.reference, keep=keep)
    last = time.monotonic()

    def deliver(done: list) -> None:
        nonlocal last
        for i, row, signals in done:
            if execute.is_interrupted(row):  # stopped by Ctrl-C: pending, and marked so
                sweep.stopped[i] = row
                continue
            sweep.rows[i] = row
            sweep.stopped.pop(i, None)
            if signals is not None:
                sweep.new_signals[i] = signals
        if progress is not None:
            progress(sweep.done, len(sweep.rows))
        if time.monotonic() - last > checkpoint:
            sweep.write(out)
            last = time.monotonic()

    if not todo:
        return execute.Outcome()
    if client is not None:
        return execute.run_dask(work, execute.chunks(todo, plan.rows, 16), client, deliver)
    n_jobs = jobs or execute.default_jobs(len(todo))
    if n_jobs > 1:
        _warm_up(plan)
    return execute.run_local(work, execute.chunks(todo, plan.rows, n_jobs), n_jobs, deliver)


def run_sweep(plan: SweepPlan, out: str | Path, *, jobs: int | None = None, scheduler: str | None = None,
              keep: bool = False, reference: list[str] | None = None, resume: bool = False,
              progress: Progress | None = None, checkpoint: float = 10.0) -> Sweep:
    """Run a sweep and write it to ``out`` (atomically, at checkpoints and at the end).

    Parameters
    ----------
    plan : SweepPlan
    out : path
        The sweep file; with ``resume``, the interrupted file to go on with.
    jobs : int, optional
        Worker processes on this machine (default one per CPU; 1 runs in this process).
    scheduler : str, optional
        Address of a Dask distributed scheduler; the runs go there instead.
    keep : bool
        Also store each run's signals (t, q, qd, Phi, Phi_q qd, energy-balance error).
    reference : list of str, optional
        ``--set`` overrides of a reference run (the base case otherwise); each run's motion
        error is measured against it.
    resume : bool
        Go on with the pending runs of ``out``.
    progress : callable, optional
        ``progress(done, total)`` as runs finish.
    checkpoint : float
        Seconds between writes of the file while the sweep runs [s].
    """
    sweep = Sweep(plan=plan, rows=[None] * len(plan), reference_overrides=list(reference or []), out=Path(out),
                  resumed=resume)
    client = execute.connect(scheduler) if scheduler is not None else None  # fail before any run
    try:
        if resume:
            stored = read_sweep(out)
            sweep.rows = resumed_rows(plan, stored)
            sweep.reference = stored.reference
            sweep.reference_overrides = json.loads(stored.attrs.get("reference", "[]"))
        elif reference is not None:
            ref = reference_run(plan, reference)
            sweep.reference = (ref.t, ref.q)
        if progress is not None:
            progress(sweep.done, len(sweep.rows))
        outcome = _run(sweep, out, jobs, client, keep, progress, checkpoint)
    finally:
        if client is not None:
            client.close()
    sweep.interrupted, sweep.lost = outcome.interrupted, outcome.lost
    sweep.write(out)
    return sweep
