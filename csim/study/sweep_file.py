"""The sweep file (``csim sweep``): the plan, one row per run, and optionally each run's signals.

Layout::

    /values/KEY (n,)        each varied key's value in each run: numbers as float64, any
                            other value (a name, a list) as its JSON text
    /runs/status (n,)       success | failed | pending (not run yet: an interrupted sweep)
    /runs/reason (n,)       why a run failed (csim.study.metrics.REASONS), "" otherwise;
                            "interrupted" for a pending run that Ctrl-C stopped while it ran
    /runs/message (n,)
    /runs/COLUMN (n,)       each number of csim.study.metrics.COLUMNS, with its units
    /signals/I/NAME         run I's t, q, qd, phi, phi_dot, energy_error (``--keep`` only)
    /reference/t, /reference/q    the reference run's samples (with ``--reference`` only)
    attributes: kind = "sweep", csim_version, format_version, case (the base case, YAML),
    keys, variations (JSON), sampling, seed, reference (its --set overrides, JSON),
    complete (every run done), coordinate_names

The file is always written whole (:func:`csim.io.hdf5.atomic_h5`): a sweep's checkpoint
replaces the previous one, copying the signals it already holds.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from csim import __version__
from csim.errors import ResultFileError
from csim.io.hdf5 import FORMAT_VERSION, _dataset, _names, atomic_h5, check_expansion, damage, scale, unit_text
from csim.io.outputs import OUTPUTS
from csim.io.units import DIMENSIONLESS
from csim.study.metrics import COLUMNS

SWEEP_KIND = "sweep"
_STR = h5py.string_dtype()
PENDING = "pending"


@dataclass
class SweepTable:
    """A sweep's plan and rows as stored (what ``--resume`` and ``csim plot`` read).

    Attributes
    ----------
    keys : list of str
    values : dict of str -> list
        Each key's value in each run (numbers as floats; other values decoded from JSON).
    numeric : dict of str -> bool
        Whether a key's values are numbers.
    status, reason, message : list of str (n,)
    columns : dict of str -> ndarray (n,)
        The numbers of :data:`csim.study.metrics.COLUMNS`.
    units : dict of str -> str
    attrs : dict
        ``case``, ``variations``, ``sampling``, ``seed``, ``reference``, ``complete``, ...
    reference : tuple of ndarray or None
        (t, q) of the reference run.
    value_units : dict of str -> str
        The unit of each varied key's value (:func:`csim.study.plan.key_unit`).
    coordinate_units, constraint_units : list of str
        The units of the coordinates and of the constraint functions, for the signals.
    """

    keys: list[str]
    values: dict[str, list]
    numeric: dict[str, bool]
    status: list[str]
    reason: list[str]
    message: list[str]
    columns: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    attrs: dict = field(default_factory=dict)
    reference: tuple[np.ndarray, np.ndarray] | None = None
    value_units: dict[str, str] = field(default_factory=dict)
    coordinate_units: list[str] = field(default_factory=list)
    constraint_units: list[str] = field(default_factory=list)

    @property
    def n(self) -> int:
        return len(self.status)

    @property
    def done(self) -> np.ndarray:
        return np.array([s != PENDING for s in self.status], dtype=bool)


def _value_dataset(values: list) -> tuple[np.ndarray, bool]:
    numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    if numeric:
        return np.asarray(values, dtype=float), True
    return np.array([json.dumps(v) for v in values], dtype=_STR), False


def write_sweep(path: str | Path, table: SweepTable, signals: dict[int, dict[str, np.ndarray]],
                keep_from: str | Path | None = None, n_runs: int | None = None) -> None:
    """Write ``table`` (and the runs' ``signals``) to ``path`` atomically.

    ``run`` (0, 1, ...), ``coordinate`` and ``constraint`` are dimension scales at the root;
    the columns of ``/values`` and ``/runs`` are attached to ``run``, and each group of
    signals (and ``/reference``) has its own ``t``.

    Parameters
    ----------
    signals : dict
        Run index -> name -> array, for the runs whose signals are not in ``keep_from`` yet.
    keep_from : path, optional
        A previous version of this file whose ``/signals`` groups are copied over (those of
        runs below ``n_runs``).
    """
    with atomic_h5(path) as fh:
        fh.attrs["kind"] = SWEEP_KIND
        fh.attrs["csim_version"] = __version__
        fh.attrs["format_version"] = FORMAT_VERSION
        fh.attrs["keys"] = json.dumps(table.keys)
        for key, value in table.attrs.items():
            fh.attrs[key] = value if not isinstance(value, (list, dict, tuple)) else json.dumps(value)
        run = scale(fh, "run", np.arange(table.n, dtype=np.int64), DIMENSIONLESS, "run number (dimension scale)")
        names = json.loads(fh.attrs.get("coordinate_names", "[]")) if "coordinate_names" in fh.attrs else []
        m = len(names)
        scales = dict(coordinate=scale(fh, "coordinate", _names(names)),
                      constraint=scale(fh, "constraint", np.arange(1, len(table.constraint_units) + 1,
                                                                      dtype=np.int64)))
        values = fh.create_group("values")
        for key in table.keys:
            data, numeric = _value_dataset(table.values[key])
            unit = table.value_units.get(key, "") if numeric else DIMENSIONLESS
            ds = _dataset(values, key, data, unit, f"the value of {key} in each run"
                          + ("" if numeric else " (JSON text)"), dims=(run,))
            ds.attrs["numeric"] = np.bool_(numeric)
        runs = fh.create_group("runs")
        for name in ("status", "reason", "message"):
            _dataset(runs, name, _names(getattr(table, name)), DIMENSIONLESS, RUN_TEXT[name], dims=(run,))
        docs = {c.name: c.doc for c in COLUMNS}
        for name, data in table.columns.items():
            _dataset(runs, name, data, table.units.get(name, ""), docs.get(name, ""), dims=(run,))
        units = _signal_units(table, m)
        if table.reference is not None:
            ref = fh.create_group("reference")
            _write_signal_group(ref, {"t": table.reference[0], "q": table.reference[1]}, units, scales)
        _write_signals(fh, signals, keep_from, table.n if n_runs is None else n_runs, units, scales)


#: descriptions of a sweep's text columns
RUN_TEXT = {"status": "success | failed | pending (not run yet: an interrupted sweep)",
            "reason": "why a run failed (the failure kinds of a result file), empty for a success; "
                      "interrupted for a pending run that Ctrl-C stopped while it ran",
            "message": "the run's message"}


def _signal_units(table: SweepTable, m: int) -> dict[str, str | list[str]]:
    """The units of the kept signals (:data:`csim.study.execute.SIGNALS`)."""
    columns = {"coordinate": table.coordinate_units if len(table.coordinate_units) == m else [""] * m,
               "constraint": table.constraint_units}
    # each signal's unit by the rule of the per-sample output it is (csim.io.outputs)
    return {"t": "s", **{out.name: out.unit(columns) for out in OUTPUTS if out.name in SIGNAL_TEXT}}


#: what each kept signal holds
SIGNAL_TEXT = {"t": "s: output time", "q": "generalized coordinates", "qd": "generalized velocities",
               "phi": "constraint residuals Phi(q)", "phi_dot": "velocity-level residuals Phi_q qd",
               "energy_error": "energy-balance error T + V - (T0 + V0) - sum of load work"}


def _write_signal_group(group: h5py.Group, arrays: dict[str, np.ndarray], units: dict, scales: dict) -> None:
    """One run's signals, attached to its own ``t`` and the root's ``coordinate``, ``constraint``."""
    t = scale(group, "t", arrays["t"], "s", SIGNAL_TEXT["t"])
    second = {"q": "coordinate", "qd": "coordinate", "phi": "constraint", "phi_dot": "constraint"}
    for name, data in arrays.items():
        if name == "t":
            continue
        _dataset(group, name, data, units.get(name, ""), SIGNAL_TEXT.get(name, ""),
                 dims=(t, scales.get(second.get(name, ""))))


def _write_signals(fh: h5py.File, signals: dict, keep_from, n_runs: int, units: dict, scales: dict) -> None:
    if not signals and keep_from is None:
        return
    group = fh.require_group("signals")
    kept: dict[int, dict[str, np.ndarray]] = {}
    if keep_from is not None and Path(keep_from).is_file():
        with h5py.File(keep_from, "r") as old:  # the arrays, not the objects: their scales are the old file's
            for name, run in old.get("signals", {}).items():
                if name.isdigit() and int(name) < n_runs and int(name) not in signals:
                    kept[int(name)] = {k: run[k][()] for k in run}
    for i, arrays in sorted({**kept, **signals}.items()):
        _write_signal_group(group.create_group(str(i)), arrays, units, scales)


def read_sweep(path: str | Path) -> SweepTable:
    """The table of a sweep file.

    Raises
    ------
    ResultFileError
        When ``path`` is missing, unreadable or not a sweep file, or one whose datasets would
        expand far beyond the file (:func:`csim.io.hdf5.check_expansion`).
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as fh:
            kind = fh.attrs.get("kind", "")
            if (kind.decode() if isinstance(kind, bytes) else str(kind)) != SWEEP_KIND:
                raise ResultFileError(f"{path}: not a csim sweep file")
            check_expansion(fh)  # the table and the kept signals: shapes only, nothing read
            try:
                return _read(fh)
            except (KeyError, ValueError, TypeError, AttributeError, IndexError) as exc:  # json errors included
                raise ResultFileError(f"{path}: a sweep file with a missing or damaged part ({damage(exc)}); "
                                      f"expected a file written by csim sweep") from None
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _read(fh: h5py.File) -> SweepTable:
    keys = json.loads(_text(fh.attrs["keys"]))
    values, numeric = {}, {}
    for key in keys:
        ds = fh["values"][key]
        numeric[key] = bool(ds.attrs["numeric"])
        values[key] = [float(x) for x in ds[()]] if numeric[key] else [json.loads(_text(x)) for x in ds[()]]
    runs = fh["runs"]
    text = {name: [_text(x) for x in runs[name][()]] for name in ("status", "reason", "message")}
    columns = {name: runs[name][()] for name in runs if name not in text}
    units = {name: unit_text(runs[name].attrs.get("units", "")) for name in columns}
    value_units = {key: unit_text(fh["values"][key].attrs.get("units", "")) for key in keys}
    attrs = {name: _text(value) if isinstance(value, (bytes, str)) else value for name, value in fh.attrs.items()}
    reference = (fh["reference"]["t"][()], fh["reference"]["q"][()]) if "reference" in fh else None
    return SweepTable(keys=keys, values=values, numeric=numeric, columns=columns, units=units, attrs=attrs,
                      reference=reference, value_units=value_units, **text)


def read_signals(path: str | Path, i: int) -> dict[str, np.ndarray]:
    """The kept signals of run ``i`` (empty when the sweep did not keep them)."""
    with h5py.File(path, "r") as fh:
        group = fh.get(f"signals/{i}")
        return {} if group is None else {name: group[name][()] for name in group}
