"""The sweep file (``csim sweep``): the plan, one row per run, and optionally each run's signals.

Layout::

    /values/KEY (n,)        each varied key's value in each run: numbers as float64, any
                            other value (a name, a list) as its JSON text
    /runs/status (n,)       success | failed | pending (not run yet: an interrupted sweep)
    /runs/reason (n,)       why a run failed (csim.study.metrics.REASONS), "" otherwise
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
from csim.io.hdf5 import FORMAT_VERSION, atomic_h5, damage

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
        values = fh.create_group("values")
        for key in table.keys:
            data, numeric = _value_dataset(table.values[key])
            ds = values.create_dataset(key, data=data)
            ds.attrs["numeric"] = numeric
        runs = fh.create_group("runs")
        for name in ("status", "reason", "message"):
            runs.create_dataset(name, data=np.array(getattr(table, name), dtype=_STR))
        for name, data in table.columns.items():
            ds = runs.create_dataset(name, data=data)
            ds.attrs["units"] = table.units.get(name, "")
        if table.reference is not None:
            ref = fh.create_group("reference")
            ref.create_dataset("t", data=table.reference[0]).attrs["units"] = "s"
            ref.create_dataset("q", data=table.reference[1])
        _write_signals(fh, signals, keep_from, table.n if n_runs is None else n_runs)


def _write_signals(fh: h5py.File, signals: dict, keep_from, n_runs: int) -> None:
    if not signals and keep_from is None:
        return
    group = fh.require_group("signals")
    if keep_from is not None and Path(keep_from).is_file():
        with h5py.File(keep_from, "r") as old:
            for name in old.get("signals", {}):
                if name.isdigit() and int(name) < n_runs and int(name) not in signals:
                    old.copy(old["signals"][name], group, name=name)
    for i, arrays in signals.items():
        run = group.create_group(str(i))
        for name, data in arrays.items():
            run.create_dataset(name, data=data)


def read_sweep(path: str | Path) -> SweepTable:
    """The table of a sweep file.

    Raises
    ------
    ResultFileError
        When ``path`` is missing, unreadable or not a sweep file.
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as fh:
            kind = fh.attrs.get("kind", "")
            if (kind.decode() if isinstance(kind, bytes) else str(kind)) != SWEEP_KIND:
                raise ResultFileError(f"{path}: not a csim sweep file")
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
    units = {name: _text(runs[name].attrs.get("units", "")) for name in columns}
    attrs = {name: _text(value) if isinstance(value, (bytes, str)) else value for name, value in fh.attrs.items()}
    reference = (fh["reference"]["t"][()], fh["reference"]["q"][()]) if "reference" in fh else None
    return SweepTable(keys=keys, values=values, numeric=numeric, columns=columns, units=units, attrs=attrs,
                      reference=reference, **text)


def read_signals(path: str | Path, i: int) -> dict[str, np.ndarray]:
    """The kept signals of run ``i`` (empty when the sweep did not keep them)."""
    with h5py.File(path, "r") as fh:
        group = fh.get(f"signals/{i}")
        return {} if group is None else {name: group[name][()] for name in group}
