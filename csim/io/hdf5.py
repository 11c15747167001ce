"""HDF5 result files: atomic writing, reading back into :class:`csim.result.Result`.

Layout of a single run (a comparison file has one such group per method)::

    /t (N,)  /q /qd /qdd (N, m)  /lambda /phi /phi_dot (N, r)
    /energy/kinetic /energy/potential (N,)  /energy/work (N, k)  /energy/balance_error (N,)
    /forces/loads (N, k)  /forces/generalized (N, m)
    /forces/drive (N, d)  /energy/drive_work (N, d)       driven dynamics only
    /reactions/JOINT/force_global, force_joint, torque_global, torque_joint (N, 3)
                                                          link-coupling mechanisms (every joint)
    /observables/NAME (N,)  /observables/NAME_rate (N,)
    /events/times (E,)  /events/labels (E,)
    attributes: csim_version, format_version, mechanism, case (YAML), coordinate_names,
    load_names, observable_names, status, message, failure, run_kind, backend,
    backend_reason, kernel_load_time, wall_time, nfev, njev, nlu, nsteps

The event times and labels are datasets, never attributes: an attribute holds at most 64 kB,
and a run stopped at ``simulation.max_events`` has 100,000 of them. Files written before
that (with a root attribute ``event_times``) are still read.

Every dataset carries a ``units`` attribute (see :mod:`csim.io.units`).

A comparison file (``csim compare``, :func:`write_comparison`) has one such group per
method, named after it, a ``/reference`` group with the reference run, and tables of 1-D
datasets of equal length (one entry per run)::

    /METHOD ...          one run each (the layout above), e.g. /none /baumgarte /projection
    /reference           the tight-tolerance reference run
    /summary/COLUMN      one entry per method: the runs in the method groups
    /work_precision/COLUMN   one entry per (method, tolerance) of a tolerance study
    attributes: kind = "comparison", methods, csim_version, format_version, case (YAML),
    and the comparison settings (see :func:`write_comparison`)

Table columns and their units: :data:`COMPARISON_COLUMNS`.
"""
from __future__ import annotations

import uuid
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np

from csim import __version__
from csim.errors import ResultFileError
from csim.io.atomic import write_atomically
from csim.io.outputs import OUTPUTS
from csim.io.units import (
    DIMENSIONLESS,
    FIXED_UNITS,
    UNITS,
    common_unit,
    per_time,
)
from csim.result import JointReaction, Result
from csim.schema import cut

#: 2: parsable units, dimension scales, a ``description`` attribute on every dataset
FORMAT_VERSION = 2
_STR = h5py.string_dtype()


@contextmanager
def atomic_h5(path: str | Path):
    """Build an HDF5 file in memory; it replaces ``path`` only when complete.

    The file is built with HDF5's in-memory driver and written by
    :func:`csim.io.atomic.write_atomically`, so that HDF5 never meets a failing write (a
    full disk left it in a state that crashed the process at exit): an exception inside
    the block, or a write that fails, leaves ``path`` untouched (or absent) and no
    temporary file. The file's image is held in memory once more while it is written.

    Raises
    ------
    OSError
        When the file cannot be written (``strerror`` says why).
    """
    path = Path(path)
    fh = h5py.File(f"{path.name}.{uuid.uuid4().hex}", "w", driver="core", backing_store=False)
    try:
        yield fh
        fh.flush()
        image = fh.id.get_file_image()
    finally:
        fh.close()
    write_atomically(path, image)


def damage(exc: Exception) -> str:
    """What reading a damaged or crafted file ran into, for a message: the exception's kind
    and the start of its text (h5py's KeyError names the missing attribute or dataset)."""
    text = str(exc.args[0]) if exc.args else ""
    return f"{type(exc).__name__}: {cut(text, 120)}"


def units_attr(unit: str | list[str]):
    """The ``units`` attribute's value: one string, or an array of them (one per column)."""
    return np.array(unit, dtype=_STR) if isinstance(unit, (list, tuple)) else unit


def _dataset(group, name, data, units, description=None, dims=()):
    """A dataset with its ``units`` and ``description``, its axes attached to the dimension
    scales ``dims`` (None: leave an axis without one)."""
    ds = group.create_dataset(name, data=data)
    ds.attrs["units"] = units_attr(units)
    ds.attrs["description"] = description if description is not None else UNITS.get(name, "")
    attach(ds, dims)
    return ds


def attach(ds: h5py.Dataset, dims) -> None:
    """Attach the dimension scales ``dims`` to the axes of ``ds``, in order (a scale whose
    length differs from the axis, or None, is left out)."""
    for axis, scale in enumerate(dims):
        if scale is not None and axis < ds.ndim and scale.shape[0] == ds.shape[axis]:
            ds.dims[axis].attach_scale(scale)


def scale(group, name, data, units=DIMENSIONLESS, description=None) -> h5py.Dataset:
    """A 1-D dataset made a dimension scale of its own name (a netCDF coordinate variable)."""
    ds = _dataset(group, name, data, units, description if description is not None else UNITS.get(name, ""))
    ds.make_scale(name)
    return ds


def _names(values) -> np.ndarray:
    return np.array([str(v) for v in values], dtype=_STR)


def _fill(units: list[str], n: int, default: str = "") -> list[str]:
    """``units`` when it has ``n`` entries, else ``n`` times ``default``."""
    return list(units) if len(units) == n else [default] * n


def run_units(result: Result, coordinate_units: list[str] | None = None) -> dict[str, list[str]]:
    """The unit of each column of ``result``: its own, else ``coordinate_units``, else unknown."""
    m, r, k, o = result.q.shape[1], result.phi.shape[1], result.loads.shape[1], len(result.observable_names)
    coords = result.coordinate_units or coordinate_units or []
    return dict(coordinate=_fill(coords, m, "rad" if not coords else ""),
                constraint=_fill(result.constraint_units, r), load=_fill(result.load_units, k),
                observable=_fill(result.observable_units, o), observable_rate=_fill(result.observable_rate_units, o))


def write_result_group(group: h5py.Group, result: Result, coordinate_units: list[str] | None = None) -> None:
    """Write one run into an open HDF5 group (the file root, or a method's group).

    ``t``, ``coordinate``, ``constraint``, ``load`` (and ``drive``, ``axis`` where there are
    drives or reactions) are dimension scales that every array of the run is attached to,
    so that netCDF readers (xarray with h5netcdf) see named dimensions.
    """
    a = group.attrs
    a["csim_version"] = __version__
    a["format_version"] = FORMAT_VERSION
    a["mechanism"] = result.mechanism
    a["case"] = result.case_yaml
    a["coordinate_names"] = np.array(result.coordinate_names, dtype=_STR)
    a["load_names"] = np.array(result.load_names, dtype=_STR)
    a["observable_names"] = np.array(result.observable_names, dtype=_STR)
    a["status"] = result.status
    a["message"] = result.message
    a["failure"] = result.failure
    a["run_kind"] = result.run_kind
    a["backend"] = result.backend
    a["backend_reason"] = result.backend_reason
    a["kernel_load_time"] = result.kernel_load_time
    a["wall_time"] = result.wall_time
    for name in ("nfev", "njev", "nlu", "nsteps"):
        a[name] = int(getattr(result, name))

    u = run_units(result, coordinate_units)
    t = scale(group, "t", result.t, "s")
    coordinate = scale(group, "coordinate", _names(result.coordinate_names[:result.q.shape[1]]))
    constraint = scale(group, "constraint", np.arange(1, result.phi.shape[1] + 1, dtype=np.int64))
    load = scale(group, "load", _names(result.load_names[:result.loads.shape[1]]))
    along = {"coordinate": (t, coordinate), "constraint": (t, constraint), "load": (t, load), "": (t,)}
    for out in OUTPUTS:  # q, qd, qdd, lambda, phi, phi_dot, energy/..., forces/... (csim.io.outputs)
        folder, _, name = out.dataset.rpartition("/")
        where = group.require_group(folder) if folder else group
        _dataset(where, name, getattr(result, out.name), out.unit(u), out.description, dims=along[out.columns])
    if result.drive_forces is not None:
        _write_drives(group, result, t)
    if result.reactions:
        _write_reactions(group.create_group("reactions"), result.reactions, t)
    obs = group.create_group("observables")
    for j, name in enumerate(result.observable_names):
        _dataset(obs, name, result.observables[:, j], u["observable"][j], UNITS["observables"], dims=(t,))
        _dataset(obs, f"{name}_rate", result.observable_rates[:, j], u["observable_rate"][j],
                 UNITS["observables_rate"], dims=(t,))
    events = group.create_group("events")
    times = scale(events, "times", np.asarray(result.event_times, dtype=float), "s", UNITS["events/times"])
    _dataset(events, "labels", _names(result.event_labels), DIMENSIONLESS, UNITS["events/labels"], dims=(times,))
    _write_integrity(group, result, t)


def _write_integrity(group: h5py.Group, result: Result, t: h5py.Dataset) -> None:
    """``integrity/``: the run's warnings (attribute), its singular crossings and the residuals
    of the equations removed as dependent (:mod:`csim.solver.integrity`)."""
    integrity = group.create_group("integrity")
    integrity.attrs["warnings"] = np.array(result.warnings, dtype=_STR)
    scale(integrity, "singular_times", np.asarray(result.singular_times, dtype=float), "s",
          "instants where Phi_q of every constraint equation fell below its generic rank")
    if result.removed_names and result.removed_phi is not None:
        removed = scale(integrity, "removed", _names(result.removed_names), DIMENSIONLESS,
                        "the constraint equations removed as dependent at the start")
        units = result.removed_units if len(result.removed_units) == len(result.removed_names) else \
            [""] * len(result.removed_names)
        _dataset(integrity, "removed_phi", result.removed_phi, common_unit(units),
                 "residuals of the removed equations at the samples", dims=(t, removed))


def _write_drives(group: h5py.Group, result: Result, t: h5py.Dataset) -> None:
    """``forces/drive`` and ``energy/drive_work`` (N, d), the drives named by an attribute."""
    names = np.array(result.drive_names, dtype=_STR)
    drive = scale(group, "drive", names)
    ds = _dataset(group["forces"], "drive", result.drive_forces, common_unit(list(result.drive_units)),
                  UNITS["forces/drive"], dims=(t, drive))
    ds.attrs["names"] = names
    ds.attrs["drive_units"] = np.array(result.drive_units, dtype=_STR)
    work = _dataset(group["energy"], "drive_work", result.drive_work, FIXED_UNITS["energy/drive_work"],
                    UNITS["energy/drive_work"], dims=(t, drive))
    work.attrs["names"] = names


def _write_reactions(group: h5py.Group, reactions, t: h5py.Dataset) -> None:
    """One group per joint: force and torque, global and in joint frame ik, (N, 3)."""
    group.attrs["joints"] = np.array([r.name for r in reactions], dtype=_STR)  # their order
    axis = scale(group.parent, "axis", _names("xyz"))
    for r in reactions:
        g = group.create_group(r.name)
        g.attrs["label"] = r.label
        g.attrs["convention"] = UNITS["reactions"]
        g.attrs["undetermined"] = np.array(r.undetermined, dtype=_STR)
        for name in ("force_global", "force_joint", "torque_global", "torque_joint"):
            _dataset(g, name, getattr(r, name), FIXED_UNITS[f"reactions/{name}"], UNITS[f"reactions/{name}"],
                     dims=(t, axis))


def unit_list(value, n: int) -> list[str]:
    """A ``units`` attribute as one unit per column (``n`` columns)."""
    if value is None:
        return [""] * n
    if isinstance(value, np.ndarray) and value.ndim == 1:
        return [_text(x) for x in value]
    return [_text(value)] * n


def _read_extras(group: h5py.Group) -> dict:
    """The drives and reactions of a run, where the file has them (as Result fields)."""
    out: dict = {}
    forces = group.get("forces")
    if forces is not None and "drive" in forces:
        ds = forces["drive"]
        names = [_text(x) for x in ds.attrs["names"]]
        units = ds.attrs["drive_units"] if "drive_units" in ds.attrs else ds.attrs["units"]
        out.update(drive_forces=ds[()], drive_names=names, drive_units=unit_list(units, len(names)),
                   drive_work=group["energy/drive_work"][()])
    if "reactions" in group:
        rg = group["reactions"]
        out["reactions"] = [
            JointReaction(name, _text(g.attrs["label"]), g["force_global"][()], g["torque_global"][()],
                          g["force_joint"][()], g["torque_joint"][()], [_text(x) for x in g.attrs["undetermined"]])
            for name, g in ((_text(n), rg[_text(n)]) for n in rg.attrs.get("joints", list(rg)))]
    integrity = group.get("integrity")
    if integrity is not None:
        out.update(warnings=[_text(x) for x in integrity.attrs.get("warnings", [])],
                   singular_times=integrity["singular_times"][()])
        if "removed_phi" in integrity:
            names = [_text(x) for x in integrity["removed"][()]]
            units = [_text(u) for u in np.atleast_1d(integrity["removed_phi"].attrs["units"])]
            out.update(removed_phi=integrity["removed_phi"][()], removed_names=names,
                       removed_units=units * len(names) if len(units) == 1 else units)
    return out


def write_result(path: str | Path, result: Result, coordinate_units: list[str] | None = None) -> None:
    """Write one run to ``path`` atomically."""
    with atomic_h5(path) as fh:
        write_result_group(fh, result, coordinate_units)


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def _read_events(group: h5py.Group) -> tuple[np.ndarray, list[str]]:
    """Event times and labels: the datasets ``events/times`` and ``events/labels``, or in files
    of earlier versions without them, the root attributes ``event_times`` (and ``event_labels``)."""
    a = group.attrs
    ev = group.get("events")
    if ev is not None and "times" in ev:
        times = ev["times"][()]
        labels = [_text(x) for x in ev["labels"][()]] if "labels" in ev else []
    else:
        times = np.asarray(a["event_times"], dtype=float).reshape(-1)
        labels = [_text(x) for x in np.atleast_1d(a["event_labels"])] if "event_labels" in a else []
    return times, labels if len(labels) == len(times) else [""] * len(times)


def unit_text(value) -> str:
    """A ``units`` attribute as one string: the unit, or the units of the columns joined by
    ``", "`` where they differ."""
    if isinstance(value, np.ndarray) and value.ndim == 1:
        return ", ".join(_text(x) for x in value)
    return _text(value)


def _read_units(group: h5py.Group, o: int) -> dict[str, list[str]]:
    """The unit of each column, as Result fields (files before format version 2: the
    coordinates' only; their other ``units`` attributes were descriptions)."""
    q = group["q"]
    out = dict(coordinate_units=unit_list(q.attrs.get("units"), q.shape[1]))
    if int(group.attrs.get("format_version", 1)) < 2:
        return out
    phi = group["phi"]
    out["constraint_units"] = unit_list(phi.attrs.get("units"), phi.shape[1])
    loads = group["forces/loads"]
    out["load_units"] = unit_list(loads.attrs.get("units"), loads.shape[1])
    names = [_text(x) for x in group.attrs["observable_names"]]
    obs = group.get("observables")
    if obs is not None and o:
        out["observable_units"] = [_text(obs[n].attrs.get("units", "")) for n in names]
        out["observable_rate_units"] = [_text(obs[f"{n}_rate"].attrs.get("units", "")) for n in names]
    return out


#: the most a run's datasets may hold beyond the file's own size [bytes]: csim writes them
#: uncompressed, so its files hold every byte they read; a compressed copy (h5repack) may
#: grow EXPANSION_LIMIT times, and a crafted file of a few kilobytes (an unallocated or
#: compressed dataset of billions of values) is refused instead of exhausting memory
EXPANSION_SLACK = 256 * 2**20
EXPANSION_LIMIT = 100


def check_expansion(group: h5py.Group) -> None:
    """Raise :class:`ResultFileError` when the datasets under ``group`` would hold more than
    :data:`EXPANSION_LIMIT` times the file's size plus :data:`EXPANSION_SLACK` once read
    (shapes and types only: nothing is read)."""
    sizes: list[int] = []
    path = Path(group.file.filename)

    def walk(g: h5py.Group, depth: int) -> None:  # soft links followed (visititems skips them)
        for key in g:
            link = g.get(key, getlink=True)
            if isinstance(link, h5py.ExternalLink):
                raise ResultFileError(f"{path}: {g.name}/{key} links to another file; expected the datasets csim "
                                      f"writes, in this file: a crafted or damaged file")
            item = g.get(key)
            if isinstance(item, h5py.Dataset):
                sizes.append(int(item.size or 0) * max(int(item.dtype.itemsize), 1))
            elif isinstance(item, h5py.Group):
                if depth >= 16 or len(sizes) > 100_000:  # csim's runs are a few groups deep: a link cycle
                    raise ResultFileError(f"{path}: {item.name} is nested too deep (or its links loop); expected "
                                          f"the groups csim writes: a crafted or damaged file")
                walk(item, depth + 1)
    walk(group, 0)
    try:
        on_disk = path.stat().st_size
    except OSError:
        return
    total, allowed = sum(sizes), EXPANSION_LIMIT * on_disk + EXPANSION_SLACK
    if total > allowed:
        raise ResultFileError(f"{path}: its datasets would hold {total:.3g} bytes once read, from a file of "
                              f"{on_disk:,} bytes; expected at most {allowed:.3g} ({EXPANSION_LIMIT} times the "
                              f"file's size plus {EXPANSION_SLACK // 2**20} MiB): a crafted or damaged file")


def read_result_group(group: h5py.Group) -> Result:
    """Read one run from an HDF5 group written by :func:`write_result_group` (refusing one
    whose datasets would expand far beyond the file, :func:`check_expansion`)."""
    a = group.attrs
    check_expansion(group)
    try:
        event_times, event_labels = _read_events(group)
        obs_names = [_text(x) for x in a["observable_names"]]
        N = group["t"].shape[0]
        observables, rates = np.zeros((N, 0)), np.zeros((N, 0))
        if obs_names:
            observables = np.column_stack([group["observables"][n][()] for n in obs_names])
            rates = np.column_stack([group["observables"][f"{n}_rate"][()] for n in obs_names])
        result = Result(
            mechanism=_text(a["mechanism"]),
            coordinate_names=[_text(x) for x in a["coordinate_names"]],
            load_names=[_text(x) for x in a["load_names"]],
            observable_names=obs_names,
            case_yaml=_text(a["case"]),
            t=group["t"][()], q=group["q"][()], qd=group["qd"][()], qdd=group["qdd"][()],
            lam=group["lambda"][()], phi=group["phi"][()], phi_dot=group["phi_dot"][()],
            kinetic=group["energy/kinetic"][()], potential=group["energy/potential"][()],
            work=group["energy/work"][()], loads=group["forces/loads"][()],
            generalized_forces=group["forces/generalized"][()],
            observables=observables, observable_rates=rates,
            status=_text(a["status"]), message=_text(a["message"]), wall_time=float(a["wall_time"]),
            nfev=int(a["nfev"]), njev=int(a["njev"]), nlu=int(a["nlu"]), nsteps=int(a["nsteps"]),
            event_times=event_times, event_labels=event_labels,
            run_kind=_text(a.get("run_kind", "simulation")), backend=_text(a.get("backend", "python")),
            kernel_load_time=float(a.get("kernel_load_time", 0.0)), failure=_text(a.get("failure", "")),
            backend_reason=_text(a.get("backend_reason", "")),
            **_read_extras(group), **_read_units(group, len(obs_names)),
        )
        _check_shapes(result)
        return result
    except KeyError as exc:
        raise ResultFileError(f"{group.file.filename}: not a csim result (missing {exc})") from None
    except (ValueError, TypeError, AttributeError, IndexError) as exc:  # a damaged or crafted file
        raise ResultFileError(f"{group.file.filename}: a csim result with a damaged part ({damage(exc)})") \
            from None


def _check_shapes(result: Result) -> None:
    """Raise ValueError unless the signals have the shapes their names give: t (N,), q, qd
    and qdd (N, m), phi and phi_dot (N, r) (a crafted or damaged file, read by plot)."""
    n, m = result.t.shape[0] if result.t.ndim == 1 else -1, len(result.coordinate_names)
    if n < 0:
        raise ValueError(f"t has the shape {result.t.shape}; expected (N,)")
    for name in ("q", "qd", "qdd"):
        shape = getattr(result, name).shape
        if shape != (n, m):
            raise ValueError(f"{name} has the shape {shape}; expected ({n}, {m}): a sample per time, a column per "
                             f"coordinate")
    for name in ("phi", "phi_dot", "kinetic", "potential"):
        shape = getattr(result, name).shape
        if len(shape) not in (1, 2) or shape[0] != n:
            raise ValueError(f"{name} has the shape {shape}; expected {n} samples")


def read_result(path: str | Path, group: str = "/") -> Result:
    """Read a run from ``path`` (``group`` names a method's group in a comparison file)."""
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such result file")
    try:
        with h5py.File(path, "r") as fh:
            if group not in fh:
                raise ResultFileError(f"{path}: no group {group!r}; groups: {', '.join(fh.keys())}")
            if group.strip("/") == "" and _text(fh.attrs.get("kind", "")) == "sweep":
                raise ResultFileError(f"{path}: a sweep file (csim sweep), a table of runs without their motion; "
                                      f"expected a result file of csim run, or a comparison file and --group")
            if group.strip("/") == "" and _text(fh.attrs.get("kind", "")) == COMPARISON_KIND:
                runs = [k for k in fh if isinstance(fh[k], h5py.Group) and "t" in fh[k]]
                raise ResultFileError(f"{path}: a comparison file, with one run per group; read one with "
                                      f"group=NAME, NAME one of {', '.join(runs)}")
            return read_result_group(fh[group])
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None


# --------------------------------------------------------------------------- comparison files

#: value of the root attribute ``kind`` of a comparison file (single-run files have none)
COMPARISON_KIND = "comparison"

#: groups of a comparison file that are not method groups
COMPARISON_RESERVED = ("reference", "summary", "work_precision")

#: column of a comparison table -> what it holds and in which unit (the ``description``
#: attribute of its dataset; the parsable ``units`` come from :func:`comparison_units`). The
#: tolerance's unit depends on the run's integrator: see the column ``tolerance_kind``.
COMPARISON_COLUMNS: dict[str, str] = {
    "method": "",
    "tolerance": "rtol (= atol) [1] for adaptive integrators, simulation.step [s] for fixed-step ones "
                 "(column tolerance_kind)",
    "tolerance_kind": "what tolerance is for the run: rtol=atol, rtol (atol differs: see the run's case) "
                      "or step [s]",
    "status": "",
    "message": "",
    "max_phi": "unit of the constraint functions: max over the run and the constraints of |Phi_i|",
    "final_phi": "unit of the constraint functions: max over the constraints of |Phi_i| at the last sample",
    "max_phi_dot": "unit of the constraint functions per s: max over the run and the constraints of "
                   "|(Phi_q qd)_i|",
    "motion_error": "per coordinate: rad or m; max over the output times and the coordinates of "
                    "|q_i - q_ref_i| (NaN: no reference)",
    "final_error": "per coordinate: rad or m; max over the coordinates of |q_i - q_ref_i| at t_end "
                   "(NaN: a run that did not reach t_end, or no reference)",
    "error_until": "s: last output time that motion_error covers (t_end unless a run stopped early)",
    "wall_time": "s",
    "nfev": "count of right-hand-side evaluations",
    "nsteps": "count of accepted steps",
    "backend": "what integrated the run: python, compiled or interpreted",
}


def _attr_value(value):
    if isinstance(value, (list, tuple)):
        if all(isinstance(v, str) for v in value):
            return np.array(value, dtype=_STR)
        return np.asarray(value, dtype=float)
    if value is None:
        return ""
    return value


def comparison_units(table: dict[str, list], coordinate_units: list[str],
                     constraint_units: list[str]) -> dict[str, str | list[str]]:
    """The parsable unit of each column of a comparison table (see :data:`COMPARISON_COLUMNS`).

    ``coordinate_units`` and ``constraint_units`` are the runs' (the errors are maxima over
    the coordinates, the residuals over the constraints); the tolerance is dimensionless for
    an adaptive integrator's rtol and in s for a fixed step.
    """
    con = common_unit(list(constraint_units)) if constraint_units else ""
    units: dict[str, str | list[str]] = {
        "tolerance": common_unit(["s" if k == "step" else DIMENSIONLESS for k in table.get("tolerance_kind", [])]),
        "max_phi": con, "final_phi": con,
        "max_phi_dot": common_unit([per_time(c) if c else "" for c in constraint_units]) if constraint_units else "",
        "motion_error": common_unit(list(coordinate_units)), "final_error": common_unit(list(coordinate_units)),
        "error_until": "s", "wall_time": "s",
    }
    return {name: units.get(name, DIMENSIONLESS) for name in table}


def _write_table(group: h5py.Group, table: dict[str, np.ndarray | list], units: dict[str, str | list[str]],
                 index: str | None = None) -> None:
    """Columns of equal length, each a dataset attached to the dimension scale ``index``
    (a column made the scale), or to a scale ``row`` (0, 1, ...) when ``index`` is None."""
    lengths = {len(v) for v in table.values()}
    if len(lengths) > 1:
        raise ValueError(f"table columns of different lengths: { {k: len(v) for k, v in table.items()} }")
    n = lengths.pop() if lengths else 0
    row = None if index is not None else scale(group, "row", np.arange(n, dtype=np.int64), DIMENSIONLESS,
                                               "row number (dimension scale of the columns)")
    for name, values in table.items():
        values = list(values)
        if any(isinstance(v, str) for v in values):
            data = np.array([str(v) for v in values], dtype=_STR)
        else:
            data = np.asarray(values, dtype=float if not all(isinstance(v, (int, np.integer)) for v in values)
                              else np.int64)
        ds = group.create_dataset(name, data=data)
        ds.attrs["units"] = units_attr(units.get(name, DIMENSIONLESS))
        ds.attrs["description"] = COMPARISON_COLUMNS.get(name, "")
        if name == index:
            ds.make_scale(name)
            row = ds
    for name in table:
        if name != index:
            attach(group[name], (row,))


def write_comparison(path: str | Path, runs: dict[str, Result], reference: Result | None, attrs: dict,
                     tables: dict[str, dict[str, np.ndarray | list]],
                     coordinate_units: list[str] | None = None) -> None:
    """Write a comparison of methods to ``path`` atomically.

    Parameters
    ----------
    path : str or Path
    runs : dict
        Method name -> its run; each is written as the group ``/NAME`` with the layout of a
        single-run file (:func:`write_result_group`).
    reference : Result or None
        The reference run, written as ``/reference``.
    attrs : dict
        Root attributes besides ``kind``, ``csim_version`` and ``format_version`` (lists of
        strings become string arrays, lists of numbers float arrays, None an empty string).
    tables : dict
        Table name (``summary``, ``work_precision``) -> column name -> 1-D values of equal
        length; each column becomes the dataset ``/TABLE/COLUMN`` with the unit from
        :data:`COMPARISON_COLUMNS` and :func:`comparison_units`. ``summary`` is indexed by
        its column ``method`` (a dimension scale), every other table by a scale ``row``.
    coordinate_units : list of str, optional
        Units of the coordinates (the ``units`` attribute of each group's ``q``), where the
        runs do not carry them.
    """
    clash = [name for name in runs if name in COMPARISON_RESERVED or name in tables]
    if clash:
        raise ValueError(f"method group name(s) {clash} clash with the comparison's own groups")
    with atomic_h5(path) as fh:
        fh.attrs["kind"] = COMPARISON_KIND
        fh.attrs["csim_version"] = __version__
        fh.attrs["format_version"] = FORMAT_VERSION
        fh.attrs["methods"] = np.array(list(runs), dtype=_STR)
        for key, value in attrs.items():
            fh.attrs[key] = _attr_value(value)
        for name, result in runs.items():
            write_result_group(fh.create_group(name), result, coordinate_units)
        if reference is not None:
            write_result_group(fh.create_group("reference"), reference, coordinate_units)
        units = next((run_units(r, coordinate_units) for r in [*runs.values(), reference]
                      if r is not None and r.q.shape[1]), None)
        coords, cons = (units["coordinate"], units["constraint"]) if units else (coordinate_units or [], [])
        for name, table in tables.items():
            _write_table(fh.create_group(name), table, comparison_units(table, coords, cons),
                         index="method" if name == "summary" else None)


@dataclass
class ComparisonFile:
    """What :func:`read_comparison` reads from a comparison file.

    Attributes
    ----------
    path : Path
    methods : list of str
        The method groups, in the order compared.
    attrs : dict
        Root attributes (strings decoded, arrays as lists or numpy arrays).
    summary : dict of str -> ndarray (n_methods,)
        One entry per method: the runs in the method groups (see :data:`COMPARISON_COLUMNS`).
    work_precision : dict of str -> ndarray (n_runs,), or None
        One entry per (method, tolerance) of a tolerance study; None without one.
    has_reference : bool
        Whether the file holds the ``/reference`` group.
    """

    path: Path
    methods: list[str]
    attrs: dict
    summary: dict[str, np.ndarray]
    work_precision: dict[str, np.ndarray] | None = None
    has_reference: bool = False
    units: dict[str, str] = field(default_factory=dict)

    def run(self, method: str) -> Result:
        """The full run of ``method`` (or ``"reference"``), read from its group."""
        return read_result(self.path, group=method)


def _read_table(group: h5py.Group, units: dict[str, str]) -> dict[str, np.ndarray]:
    table = {}
    for name, ds in group.items():
        if name == "row":  # the dimension scale of a table without an index column
            continue
        if ds.dtype.kind in "OS":
            table[name] = np.array(ds.asstr()[()], dtype=object)
        else:
            table[name] = ds[()]
        units[f"{group.name.strip('/')}/{name}"] = unit_text(ds.attrs.get("units", ""))
    return table


def read_comparison(path: str | Path) -> ComparisonFile:
    """Read the tables and settings of a comparison file written by :func:`write_comparison`.

    Raises
    ------
    ResultFileError
        When ``path`` is missing, unreadable, or not a comparison file, or one whose datasets
        would expand far beyond the file (:func:`check_expansion`).
    """
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such comparison file")
    try:
        with h5py.File(path, "r") as fh:
            if _text(fh.attrs.get("kind", "")) != COMPARISON_KIND:
                raise ResultFileError(f"{path}: not a comparison file (no attribute kind = {COMPARISON_KIND!r}); "
                                      f"read a single run with read_result")
            check_expansion(fh)  # its tables and every run in it: shapes only, nothing read
            attrs = {}
            for key, value in fh.attrs.items():
                if isinstance(value, np.ndarray) and value.dtype.kind in "OS":
                    attrs[key] = [_text(v) for v in value]
                elif isinstance(value, (bytes, str)):
                    attrs[key] = _text(value)
                else:
                    attrs[key] = value
            units: dict[str, str] = {}
            if "summary" not in fh:
                raise ResultFileError(f"{path}: a comparison file without its /summary table")
            summary = _read_table(fh["summary"], units)
            work = _read_table(fh["work_precision"], units) if "work_precision" in fh else None
            return ComparisonFile(path=path, methods=list(attrs.get("methods", [])), attrs=attrs, summary=summary,
                                  work_precision=work, has_reference="reference" in fh, units=units)
    except (KeyError, ValueError, TypeError, AttributeError, IndexError) as exc:  # a damaged or crafted file
        raise ResultFileError(f"{path}: a comparison file with a missing or damaged part ({damage(exc)})") \
            from None
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None
