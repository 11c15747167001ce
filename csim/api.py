"""Reading csim's result files into xarray and pandas: :func:`load`, :func:`frames`, :func:`export`.

A run (a single-run file, a method's group of a comparison file, the reference or a kept
run of a sweep file) becomes an :class:`xarray.Dataset`: every array of the group and its
subgroups is a variable named by its path in the file (``q``, ``energy/kinetic``,
``reactions/A/force_global``), on the dimensions the file's dimension scales name (``t``,
``coordinate``, ``constraint``, ``load``, ...), which are its coordinates. Each variable's
``units`` attribute is a UDUNITS/pint unit (:mod:`csim.io.units`). A table (a comparison's
``summary`` and ``work_precision``, a sweep's runs) becomes a :class:`pandas.DataFrame`
with ``df.attrs["units"]``, column -> unit.

xarray, pandas and (for Parquet) pyarrow are an optional extra: ``pip install
'csim-multibody[data]'``.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import h5py
import numpy as np

from csim.errors import ResultFileError

#: the distribution's extra that installs what this module needs
EXTRA_HINT = "pip install 'csim-multibody[data]'"

#: what :func:`export` writes
FORMATS = ("csv", "parquet")

_COLUMN = re.compile(r"^(?P<name>.*?)(?: \[(?P<unit>[^\]]*)\])?$")


def _need(module: str):
    """Import an optional dependency, or say how to install it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise ResultFileError(f"reading csim files into tables needs {module}, which is not installed "
                              f"({EXTRA_HINT})") from None


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _attr(value):
    """An HDF5 attribute as a plain Python value (strings decoded, string arrays as lists)."""
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.ndarray):
        return [_text(v) for v in value] if value.dtype.kind in "OS" else value
    if isinstance(value, np.generic):
        return value.item()
    return value


def _read(ds: h5py.Dataset) -> np.ndarray:
    return ds.asstr()[()] if ds.dtype.kind in "OS" else ds[()]


def _is_scale(ds: h5py.Dataset) -> bool:
    return _text(ds.attrs.get("CLASS", b"")) == "DIMENSION_SCALE"


def kind(path: str | Path) -> str:
    """What a csim HDF5 file holds: ``"run"``, ``"comparison"`` or ``"sweep"``.

    Raises
    ------
    ResultFileError
        When ``path`` is missing, not HDF5, or not a csim file.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such result file")
    try:
        with h5py.File(path, "r") as fh:
            k = _text(fh.attrs.get("kind", ""))
            if k in ("comparison", "sweep"):
                return k
            if "t" in fh and "q" in fh:
                return "run"
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None
    raise ResultFileError(f"{path}: not a csim result, comparison or sweep file")


def _dims(ds: h5py.Dataset, name: str) -> tuple[str, ...]:
    """The dimension names of ``ds``: its scales' names, or ``NAME_dimI`` for an axis without one."""
    out = []
    for axis in range(ds.ndim):
        scales = ds.dims[axis]
        out.append(scales[len(scales) - 1].name.rsplit("/", 1)[-1] if len(scales) else f"{name}_dim{axis}")
    return tuple(out)


def dataset(path: str | Path, group: str = "/"):
    """The run in ``group`` of ``path`` as an :class:`xarray.Dataset` (see the module's doc).

    Raises
    ------
    ResultFileError
        When the file or the group is missing, or xarray is not installed.
    """
    xr = _need("xarray")
    path = Path(path)
    try:
        with h5py.File(path, "r") as fh:
            if group not in fh:
                raise ResultFileError(f"{path}: no group {group!r}; groups: {', '.join(fh.keys())}")
            root = fh[group]
            data_vars, coords = {}, {}

            def visit(name: str, obj) -> None:
                if not isinstance(obj, h5py.Dataset):
                    return
                attrs = {k: _attr(v) for k, v in obj.attrs.items()
                         if k not in ("CLASS", "NAME", "DIMENSION_LIST", "REFERENCE_LIST")}
                if _is_scale(obj):
                    coords[name.rsplit("/", 1)[-1]] = (name.rsplit("/", 1)[-1], _read(obj), attrs)
                elif "/" not in name or not name.split("/", 1)[0].isdigit():
                    data_vars[name] = (_dims(obj, name), _read(obj), attrs)

            root.visititems(visit)
            attrs = {k: _attr(v) for k, v in root.attrs.items()}
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)


def _frame_units(ds, names) -> dict[str, str]:
    out = {}
    for name in names:
        unit = ds[name].attrs.get("units", "")
        out[name] = unit if isinstance(unit, str) else ", ".join(unit)
    return out


def to_frame(ds):
    """A run's time series as a :class:`pandas.DataFrame`, one row per output time.

    The index is ``t``; a 1-D variable is a column of its own name, a 2-D one a column
    per entry of its second dimension, named ``NAME:ENTRY`` (``q:q1``, ``phi:2``,
    ``forces/loads:torque``, as ``csim plot`` names series). ``df.attrs["units"]`` maps
    each column (and ``t``) to its unit.
    """
    pd = _need("pandas")
    columns, units = {}, {"t": ds["t"].attrs.get("units", "s")}
    for name, var in ds.data_vars.items():
        if not var.dims or var.dims[0] != "t":
            continue
        unit = var.attrs.get("units", "")
        if var.ndim == 1:
            columns[name], units[name] = var.values, unit
        elif var.ndim == 2:
            labels = ds[var.dims[1]].values if var.dims[1] in ds.coords else range(var.shape[1])
            for j, label in enumerate(labels):
                column = f"{name}:{label}"
                columns[column] = var.values[:, j]
                units[column] = unit if isinstance(unit, str) else unit[j]
    frame = pd.DataFrame(columns, index=pd.Index(ds["t"].values, name="t"))
    frame.attrs["units"] = units
    return frame


def _table(group: h5py.Group, index: str | None = None, extra: h5py.Group | None = None):
    """The columns of ``group`` (and of ``extra``, first) as a DataFrame, units in ``attrs``."""
    pd = _need("pandas")
    columns, units = {}, {}
    for g in (extra, group):
        if g is None:
            continue
        for name, ds in g.items():
            if isinstance(ds, h5py.Dataset) and not (_is_scale(ds) and name != index):
                columns[name] = _read(ds)
                if "numeric" in ds.attrs and not bool(ds.attrs["numeric"]):  # a sweep's value, as JSON
                    columns[name] = np.array([json.loads(x) for x in columns[name]], dtype=object)
                unit = _attr(ds.attrs.get("units", ""))
                units[name] = unit if isinstance(unit, str) else ", ".join(unit)
    frame = pd.DataFrame(columns)
    if index is not None and index in frame:
        frame = frame.set_index(index)
    else:
        frame.index.name = "run" if extra is not None else "row"
    frame.attrs["units"] = units
    return frame


def tables(path: str | Path) -> dict:
    """The tables of a comparison or sweep file as DataFrames (empty for a run file).

    A comparison file: ``summary`` (indexed by method) and, after a tolerance study,
    ``work_precision``. A sweep file: ``runs``, each run's varied values, status and
    numbers, indexed by run number.
    """
    k = kind(path)
    with h5py.File(path, "r") as fh:
        if k == "comparison":
            out = {"summary": _table(fh["summary"], index="method")}
            if "work_precision" in fh:
                out["work_precision"] = _table(fh["work_precision"])
            return out
        if k == "sweep":
            return {"runs": _table(fh["runs"], extra=fh["values"])}
    return {}


def run_groups(path: str | Path) -> list[str]:
    """The groups of ``path`` that hold a run: ``/`` for a run file; a comparison's methods
    and ``reference``; a sweep's ``reference`` and kept ``signals/I``."""
    k = kind(path)
    with h5py.File(path, "r") as fh:
        if k == "run":
            return ["/"]
        if k == "comparison":
            return [name for name in fh if isinstance(fh[name], h5py.Group) and "t" in fh[name]]
        groups = ["reference"] if "reference" in fh else []
        signals = fh.get("signals", {})
        return groups + [f"signals/{i}" for i in sorted((int(n) for n in signals), key=int)]


def load(path: str | Path, group: str | None = None):
    """Read a csim file: a run as an :class:`xarray.Dataset`, tables as DataFrames.

    Parameters
    ----------
    path : str or Path
        A result file (``csim run``), a comparison file (``csim compare``) or a sweep file
        (``csim sweep``).
    group : str, optional
        A run's group in a comparison or sweep file (``"projection"``, ``"reference"``,
        ``"signals/3"``): that run as a Dataset; or a table's name (``"summary"``,
        ``"work_precision"``, ``"runs"``): that table as a DataFrame.

    Returns
    -------
    xarray.Dataset or pandas.DataFrame or dict
        A run file: its Dataset. A comparison or sweep file without ``group``: a dict of its
        tables (:func:`tables`).

    Examples
    --------
    >>> import csim
    >>> run = csim.load("results/qr.h5")                   # doctest: +SKIP
    >>> run["q"].sel(coordinate="q1")                       # doctest: +SKIP
    >>> csim.load("results/qr_compare.h5")["summary"]       # doctest: +SKIP
    """
    k = kind(path)
    if group is None:
        return dataset(path) if k == "run" else tables(path)
    found = tables(path)
    if group in found:
        return found[group]
    if group.strip("/") in [g.strip("/") for g in run_groups(path)]:
        return dataset(path, group)
    raise ResultFileError(f"{path}: no run or table {group!r}; runs: {', '.join(run_groups(path))}; "
                          f"tables: {', '.join(found) or 'none'}")


def frames(path: str | Path) -> dict:
    """Every table and every run of ``path`` as DataFrames, by name (what :func:`export` writes).

    A run's time series are named after its group (``run`` for a run file, the method for a
    comparison, ``reference``, ``signals.3``), its events ``NAME.events``.
    """
    pd = _need("pandas")
    out = dict(tables(path))
    for group in run_groups(path):
        ds = dataset(path, group)
        name = "run" if group == "/" else group.strip("/").replace("/", ".")
        out[name] = to_frame(ds)
        if "events/labels" in ds:
            events = pd.DataFrame({"labels": ds["events/labels"].values},
                                  index=pd.Index(ds["times"].values, name="times"))
            events.attrs["units"] = {"times": "s", "labels": "1"}
            out[f"{name}.events"] = events
    return out


def export(path: str | Path, out_dir: str | Path, fmt: str = "csv") -> list[Path]:
    """Write every table and run of ``path`` (:func:`frames`) to ``out_dir``, one file each.

    A CSV file's header names each column with its unit, ``q:q1 [rad]``; a Parquet file
    keeps the units in each field's metadata (``units``) and in the schema's
    ``csim_units`` (JSON). :func:`read_export` reads either back.

    The file is read whole before ``out_dir`` is created. Each file goes through a temporary
    file beside it (:func:`csim.io.atomic.atomic_path`): a failure (a full disk, ``ulimit
    -f``) leaves no partial file, and a symbolic link at a file's name is replaced by the
    file, never written through.

    Returns
    -------
    list of Path
        The files written.

    Raises
    ------
    ResultFileError
        When ``path`` is missing, not a csim file, or one with a missing or damaged part (a
        comparison or sweep file is read as ``csim plot`` reads it first), or pandas
        (pyarrow) is not installed.
    OSError
        When a file cannot be written; the files before it are kept.
    """
    from csim.io.atomic import atomic_path
    from csim.io.hdf5 import check_expansion, damage, read_comparison
    from csim.study.sweep_file import read_sweep

    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: expected one of {', '.join(FORMATS)}")
    if fmt == "parquet":
        _need("pyarrow")
    k = kind(path)
    if k == "comparison":  # its tables, settings and sizes checked, as for csim plot
        read_comparison(path)
    elif k == "sweep":
        read_sweep(path)
    else:
        try:
            with h5py.File(path, "r") as fh:
                check_expansion(fh)  # shapes only, nothing read
        except OSError as exc:
            raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None
    try:
        found = frames(path)
    except (KeyError, ValueError, TypeError, AttributeError, IndexError) as exc:  # a damaged or crafted file
        writer = {"run": "csim run", "comparison": "csim compare", "sweep": "csim sweep"}[k]
        raise ResultFileError(f"{path}: a {k} file with a missing or damaged part ({damage(exc)}); expected a "
                              f"file written by {writer}") from None
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for name, frame in found.items():
        target = out_dir / f"{name}.{fmt}"
        units = frame.attrs.get("units", {})
        with atomic_path(target) as tmp:
            if fmt == "csv":
                renamed = frame.rename(columns={c: _with_unit(c, units.get(c, "")) for c in frame.columns})
                renamed.index.name = _with_unit(frame.index.name, units.get(frame.index.name, ""))
                renamed.to_csv(tmp, na_rep="nan")
            else:
                _write_parquet(frame, units, tmp)
        written.append(target)
    return written


def _with_unit(name, unit: str) -> str:
    return f"{name} [{unit}]" if unit else str(name)


def _write_parquet(frame, units: dict, target: Path) -> None:
    pa = _need("pyarrow")
    pq = _need("pyarrow.parquet")
    table = pa.Table.from_pandas(frame)
    fields = [f.with_metadata({"units": units.get(f.name, "")}) if units.get(f.name) else f for f in table.schema]
    metadata = dict(table.schema.metadata or {})
    metadata[b"csim_units"] = json.dumps(units).encode()
    pq.write_table(table.cast(pa.schema(fields, metadata=metadata)), target)


def read_export(path: str | Path):
    """A file written by :func:`export`, as the DataFrame it came from (units in ``attrs``)."""
    pd = _need("pandas")
    path = Path(path)
    if path.suffix == ".parquet":
        pq = _need("pyarrow.parquet")
        table = pq.read_table(path)
        frame = table.to_pandas()
        frame.attrs["units"] = json.loads((table.schema.metadata or {}).get(b"csim_units", b"{}"))
        return frame
    frame = pd.read_csv(path, index_col=0, keep_default_na=False, na_values=["nan"])
    units, names = {}, {}
    for column in [frame.index.name, *frame.columns]:
        match = _COLUMN.match(str(column))
        names[column] = match["name"]
        if match["unit"]:
            units[match["name"]] = match["unit"]
    frame = frame.rename(columns=names)
    frame.index.name = names[frame.index.name]
    frame.attrs["units"] = units
    return frame
