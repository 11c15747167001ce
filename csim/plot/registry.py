"""The figures ``csim plot`` knows, by name: generic ones for every run, the ones a
mechanism declares, and those of comparison files.

A figure kind has a name (the file name stem and the ``--only`` name), a description, a
builder and a test of whether a file has the data for it.
"""
from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from csim.model.definition import DeclaredFigure
from csim.plot import comparison_figures as cf
from csim.plot import run_figures as rf
from csim.plot import sweep_figures as sf
from csim.plot.errors import PlotError
from csim.plot.source import ComparisonData, RunData


@dataclass(frozen=True)
class FigureKind:
    """A figure ``csim plot`` can make.

    Attributes
    ----------
    name : str
        File name stem and ``--only`` name.
    description : str
        One line for a person (``csim plot --help``, error messages).
    build : callable
        ``build(data) -> Figure``, data a RunData (run figures) or ComparisonData.
    missing : callable
        ``missing(data) -> str or None``: why the file cannot give this figure (None: it can).
    """

    name: str
    description: str
    build: Callable[[Any], Figure]
    missing: Callable[[Any], str | None] = lambda data: None


def _no_constraints(run: RunData) -> str | None:
    return None if run.result.phi.shape[1] else "the mechanism has no constraints"


def _no_forces(run: RunData) -> str | None:
    if run.result.run_kind == "kinematic":
        return "a kinematic analysis of prescribed motion has no forces"
    return _no_constraints(run)


def _no_forces_at_all(run: RunData) -> str | None:
    if run.result.run_kind == "kinematic":
        return "a kinematic analysis of prescribed motion has no forces (no work, no energy balance)"
    return None


def _no_loads(run: RunData) -> str | None:
    return None if run.result.load_names else "the mechanism has no loads"


def _no_reactions(run: RunData) -> str | None:
    if run.result.run_kind == "kinematic":
        return "a kinematic analysis of prescribed motion has no forces"
    return None if run.result.reactions else "the run records no joint reactions (not a link-coupling mechanism)"


def _no_drives(run: RunData) -> str | None:
    return None if run.result.drive_forces is not None else \
        "the run has no drives (driven dynamics: mechanism.drive with drive_mode: dynamic)"


def _no_drawing(run: RunData) -> str | None:
    if run.definition is None:
        return run.unavailable or f"mechanism {run.result.mechanism!r} is not known to this csim"
    if run.definition.drawing is None:
        return f"mechanism {run.result.mechanism!r} declares no drawing"
    return None


#: figures of every run, in the order they are made
RUN_FIGURES: dict[str, FigureKind] = {k.name: k for k in (
    FigureKind("coordinates", "generalized coordinates q against time", rf.coordinates_figure),
    FigureKind("velocities", "generalized velocities qd against time", rf.velocities_figure),
    FigureKind("constraints", "constraint residuals |Phi_i| and |(Phi_q qd)_i| against time, log scale",
               rf.constraints_figure, _no_constraints),
    FigureKind("energy", "energies, work of the loads and the energy-balance error", rf.energy_figure,
               _no_forces_at_all),
    FigureKind("multipliers", "Lagrange multipliers against time", rf.multipliers_figure, _no_forces),
    FigureKind("loads", "applied loads against time", rf.loads_figure, _no_loads),
    FigureKind("drive", "drive torques and forces of driven dynamics against time", rf.drive_figure, _no_drives),
    FigureKind("reactions", "force and torque of every joint against time", rf.reactions_figure,
               _no_reactions),
    FigureKind("mechanism", "the mechanism drawn at six instants of the run", rf.snapshots_figure, _no_drawing),
)}


def _no_study(data: ComparisonData) -> str | None:
    return None if data.file.work_precision is not None else \
        "the file holds no tolerance study (csim compare --tolerances ...)"


def _no_reference(data: ComparisonData) -> str | None:
    if data.reference is None:
        return "the file holds no reference run"
    if not data.reference.result.ok:
        return "the reference run failed"
    if all(cf.motion_error(data, m) is None for m in data.runs):
        return "no method run shares the reference's output times"
    return None


def _no_pair(data: ComparisonData) -> str | None:
    have = {m.split(":", 1)[0] for m in data.runs}
    lacking = [m for m in ("baumgarte", "sliding_mode") if m not in have]
    return f"the file has no {' and no '.join(lacking)} run" if lacking else None


#: figures of a comparison file, in the order they are made
COMPARISON_FIGURES: dict[str, FigureKind] = {k.name: k for k in (
    FigureKind("constraint_errors", "constraint error of every method on one log axis; no stabilization "
               "against the stabilized methods (paper fig. H.8)", cf.stabilized_figure),
    FigureKind("baumgarte_vs_sliding_mode", "constraint error, Baumgarte against sliding mode (paper fig. H.9)",
               cf.baumgarte_sliding_figure, _no_pair),
    FigureKind("velocity_constraint_errors", "velocity-level constraint error of every method, log scale",
               functools.partial(cf.constraint_errors_figure, velocity=True)),
    FigureKind("motion_errors", "motion error against the reference run, every method, log scale",
               cf.motion_errors_figure, _no_reference),
    FigureKind("work_precision_time", "work-precision: motion and constraint errors against wall time, log-log",
               functools.partial(cf.work_precision_figure, cost="wall_time"), _no_study),
    FigureKind("work_precision_nfev", "work-precision: motion and constraint errors against RHS evaluations, "
               "log-log", functools.partial(cf.work_precision_figure, cost="nfev"), _no_study),
)}


def declared_kind(figure: DeclaredFigure) -> FigureKind:
    """The figure kind of a figure a mechanism declares."""
    description = figure.title + (f" ({figure.reference})" if figure.reference else "")
    missing = _no_drawing if figure.snapshots > 0 else (lambda run: None)
    return FigureKind(figure.name, description, functools.partial(rf.declared_figure, figure=figure), missing)


def run_figure_kinds(run: RunData) -> dict[str, FigureKind]:
    """Figures of ``run``: the mechanism's declared figures first, then the generic ones.

    A declared figure replaces a generic one of the same name; a mechanism that declares
    snapshots of itself replaces the generic ``mechanism`` figure.
    """
    declared = list(run.definition.figures) if run.definition is not None else []
    kinds = {f.name: declared_kind(f) for f in declared}
    for name, kind in RUN_FIGURES.items():
        if name == "mechanism" and any(f.snapshots > 0 for f in declared):
            continue
        kinds.setdefault(name, kind)
    return kinds


def select(kinds: dict[str, FigureKind], data, only: Sequence[str] | None, what: str
           ) -> tuple[list[FigureKind], dict[str, str]]:
    """The figures to make, and those left out with the reason.

    Parameters
    ----------
    kinds : dict
        The figures of this kind of file.
    data : RunData or ComparisonData
    only : sequence of str, optional
        Names asked for; default every figure the file has the data for.
    what : str
        How messages name the file.

    Raises
    ------
    PlotError
        For a name not in ``kinds`` (listing the valid ones), or one the file cannot give
        (saying why).
    """
    if only:
        unknown = [n for n in only if n not in kinds]
        if unknown:
            raise PlotError(f"--only: unknown figure(s) {', '.join(map(repr, unknown))} for {what}; "
                            f"valid names: {', '.join(kinds)}")
        chosen = [kinds[n] for n in dict.fromkeys(only)]
        for kind in chosen:
            reason = kind.missing(data)
            if reason:
                raise PlotError(f"--only {kind.name}: not available for {what}: {reason}")
        return chosen, {}
    chosen, skipped = [], {}
    for kind in kinds.values():
        reason = kind.missing(data)
        if reason:
            skipped[kind.name] = reason
        else:
            chosen.append(kind)
    return chosen, skipped


def _not_two_keys(table) -> str | None:
    keys = sf.map_keys(table)
    return None if len(keys) >= 2 else f"a map needs two varied keys (this sweep varies: {', '.join(table.keys)})"


def _not_one_key(table) -> str | None:
    return None if sf.numeric_keys(table) else "curves need a numeric varied key"


def _no_values(column: str):
    def missing(table) -> str | None:
        if _not_two_keys(table):
            return _not_two_keys(table)
        ok = [i for i in range(table.n) if table.status[i] == "success"]
        if not any(np.isfinite(table.columns[column][i]) for i in ok):
            no_reference = column == "error" and table.reference is None
            return f"no successful run has a value of {column}" + (" (no --reference run)" if no_reference else "")
        return None
    return missing


#: the figures of a sweep file (csim sweep)
SWEEP_FIGURES: dict[str, FigureKind] = {k.name: k for k in (
    FigureKind("outcome", "stability map: each run stable, or failed and why, over two varied keys",
               sf.outcome_figure, _not_two_keys),
    *(FigureKind(f"{column}_map", f"stability map: {text} (log colour scale), failed runs marked",
                 functools.partial(sf.metric_figure, column=column), _no_values(column))
      for column, text in sf.METRICS.items()),
    FigureKind("curves", "max |Phi|, motion error, energy error and RHS evaluations against one varied key",
               sf.curves_figure, _not_one_key),
)}
