"""HDF5 result files: atomic writing, reading back into :class:`csim.result.Result`.

Layout of a single run (a comparison file has one such group per method)::

    /t (N,)  /q /qd /qdd (N, m)  /lambda /phi /phi_dot (N, r)
    /energy/kinetic /energy/potential (N,)  /energy/work (N, k)  /energy/balance_error (N,)
    /forces/loads (N, k)  /forces/generalized (N, m)
    /observables/NAME (N,)  /observables/NAME_rate (N,)
    /events/times (E,)  /events/labels (E,)
    attributes: csim_version, format_version, mechanism, case (YAML), coordinate_names,
    load_names, observable_names, status, message, wall_time, nfev, njev, nlu, nsteps,
    event_times

Every dataset carries a ``units`` attribute (see :mod:`csim.io.units`).
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path

import h5py
import numpy as np

from csim import __version__
from csim.errors import ResultFileError
from csim.io.units import UNITS
from csim.result import Result

FORMAT_VERSION = 1
_STR = h5py.string_dtype()


@contextmanager
def atomic_h5(path: str | Path):
    """Open a temporary HDF5 file beside ``path``; it replaces ``path`` only when complete.

    A crash or an exception inside the block leaves ``path`` untouched (or absent) and
    removes the temporary file.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    try:
        with h5py.File(tmp, "w") as fh:
            yield fh
        # durable before it becomes visible; mode as for any new file (mkstemp makes 0600)
        with open(tmp, "rb+") as raw:
            os.fsync(raw.fileno())
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _dataset(group, name, data, units=None):
    ds = group.create_dataset(name, data=data)
    ds.attrs["units"] = units if units is not None else UNITS.get(name, "")
    return ds


def write_result_group(group: h5py.Group, result: Result, coordinate_units: list[str] | None = None) -> None:
    """Write one run into an open HDF5 group (the file root, or a method's group)."""
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
    a["wall_time"] = result.wall_time
    for name in ("nfev", "njev", "nlu", "nsteps"):
        a[name] = int(getattr(result, name))
    a["event_times"] = np.asarray(result.event_times, dtype=float)

    _dataset(group, "t", result.t)
    units = coordinate_units or ["rad"] * len(result.coordinate_names)
    _dataset(group, "q", result.q, np.array(units, dtype=_STR))
    _dataset(group, "qd", result.qd, np.array([u + "/s" for u in units], dtype=_STR))
    _dataset(group, "qdd", result.qdd, np.array([u + "/s^2" for u in units], dtype=_STR))
    _dataset(group, "lambda", result.lam)
    _dataset(group, "phi", result.phi)
    _dataset(group, "phi_dot", result.phi_dot)
    energy = group.create_group("energy")
    for name, data in (("kinetic", result.kinetic), ("potential", result.potential), ("work", result.work),
                       ("balance_error", result.energy_error)):
        _dataset(energy, name, data, UNITS[f"energy/{name}"])
    forces = group.create_group("forces")
    _dataset(forces, "loads", result.loads, UNITS["forces/loads"])
    _dataset(forces, "generalized", result.generalized_forces, UNITS["forces/generalized"])
    obs = group.create_group("observables")
    for j, name in enumerate(result.observable_names):
        _dataset(obs, name, result.observables[:, j], "")
        _dataset(obs, f"{name}_rate", result.observable_rates[:, j], "")
    events = group.create_group("events")
    _dataset(events, "times", np.asarray(result.event_times, dtype=float), UNITS["events/times"])
    events.create_dataset("labels", data=np.array(result.event_labels, dtype=_STR))


def write_result(path: str | Path, result: Result, coordinate_units: list[str] | None = None) -> None:
    """Write one run to ``path`` atomically."""
    with atomic_h5(path) as fh:
        write_result_group(fh, result, coordinate_units)


def _text(value) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def read_result_group(group: h5py.Group) -> Result:
    """Read one run from an HDF5 group written by :func:`write_result_group`."""
    a = group.attrs
    try:
        ev = group["events"]
        obs_names = [_text(x) for x in a["observable_names"]]
        N = group["t"].shape[0]
        observables, rates = np.zeros((N, 0)), np.zeros((N, 0))
        if obs_names:
            observables = np.column_stack([group["observables"][n][()] for n in obs_names])
            rates = np.column_stack([group["observables"][f"{n}_rate"][()] for n in obs_names])
        return Result(
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
            event_times=ev["times"][()], event_labels=[_text(x) for x in ev["labels"][()]],
        )
    except KeyError as exc:
        raise ResultFileError(f"{group.file.filename}: not a csim result (missing {exc})") from None


def read_result(path: str | Path, group: str = "/") -> Result:
    """Read a run from ``path`` (``group`` names a method's group in a comparison file)."""
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such result file")
    try:
        with h5py.File(path, "r") as fh:
            if group not in fh:
                raise ResultFileError(f"{path}: no group {group!r}; groups: {', '.join(fh.keys())}")
            return read_result_group(fh[group])
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None
