"""csim.load, csim export and the self-describing layout: every kind of file opened with
xarray (h5netcdf) and pandas, a parsable unit on every dataset, round trips through CSV and
Parquet."""
from __future__ import annotations

import h5py
import numpy as np
import pytest
from conftest import CONFIGS, invoke

import csim
from csim.api import export, frames, read_export
from csim.errors import ResultFileError

xr = pytest.importorskip("xarray")
pd = pytest.importorskip("pandas")
pint = pytest.importorskip("pint")
pytest.importorskip("h5netcdf")

SHORT = ("--set", "simulation.t_end=0.3", "--set", "simulation.backend=python", "--quiet")


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A run, a comparison with a tolerance study, and a sweep with kept signals and a reference."""
    d = tmp_path_factory.mktemp("api")
    case = CONFIGS / "quick_return.yaml"
    out = {"run": d / "run.h5", "comparison": d / "cmp.h5", "sweep": d / "sweep.h5"}
    r = invoke("run", case, *SHORT, "-o", out["run"])
    assert r.exit_code == 0, r.output
    r = invoke("compare", case, "-m", "none,projection", "--tolerances", "1e-4,1e-6", *SHORT, "-o",
               out["comparison"])
    assert r.exit_code == 0, r.output
    r = invoke("sweep", case, "-v", "stabilization.method=none,baumgarte", "-v", "mechanism.parameters.l1=1.4,1.5",
               "--keep", "-r", "simulation.rtol=1e-10", "-j", "1", *SHORT, "-o", out["sweep"])
    assert r.exit_code == 0, r.output
    return out


def _datasets(path):
    found = {}
    with h5py.File(path, "r") as fh:
        fh.visititems(lambda name, obj: found.setdefault(name, dict(obj.attrs))
                      if isinstance(obj, h5py.Dataset) else None)
    return found


@pytest.mark.parametrize("kind", ["run", "comparison", "sweep"])
def test_every_dataset_has_a_parsable_unit_and_a_description(files, kind):
    ureg = pint.UnitRegistry()
    for name, attrs in _datasets(files[kind]).items():
        assert "units" in attrs, name
        units = attrs["units"]
        for unit in (units if isinstance(units, np.ndarray) else [units]):
            unit = unit.decode() if isinstance(unit, bytes) else unit
            assert unit, f"{name}: empty units"
            ureg.parse_units(unit)  # raises on a unit pint cannot read
        assert "description" in attrs, name


def test_units_are_the_quantities_own(files):
    with h5py.File(files["run"], "r") as fh:
        units = {name: fh[name].attrs["units"] for name in
                 ("t", "q", "qd", "qdd", "phi", "phi_dot", "lambda", "energy/kinetic", "observables/ram_x",
                  "observables/ram_x_rate", "events/times", "events/labels", "forces/generalized")}
        assert list(fh["forces/loads"].attrs["units"]) == ["N m", "N"]  # torque, cutting force: one per column
    assert units == {"t": "s", "q": "rad", "qd": "rad/s", "qdd": "rad/s^2", "phi": "m", "phi_dot": "m/s",
                     "lambda": "N", "energy/kinetic": "J", "observables/ram_x": "m", "observables/ram_x_rate": "m/s",
                     "events/times": "s", "events/labels": "1", "forces/generalized": "N m"}
    with h5py.File(files["sweep"], "r") as fh:
        assert fh["runs/max_phi"].attrs["units"] == "m" and fh["runs/error"].attrs["units"] == "rad"
        assert fh["values/mechanism.parameters.l1"].attrs["units"] == "m"
        assert fh["values/stabilization.method"].attrs["numeric"].dtype == np.bool_
        assert isinstance(fh.attrs["complete"], np.bool_)


def test_run_opens_with_xarray_h5netcdf_with_named_dimensions(files):
    with xr.open_dataset(files["run"], engine="h5netcdf") as ds:
        assert "t" in ds.coords and ds["t"].attrs["units"] == "s"
        assert ds["q"].dims == ("t", "coordinate") and list(ds["coordinate"].values) == ["q1", "q2", "q3"]
        assert ds["phi"].dims == ("t", "constraint")
        assert not [d for d in ds.dims if str(d).startswith("phony_dim")]
    with xr.open_dataset(files["run"], engine="h5netcdf", group="energy") as energy:
        assert energy["work"].dims == ("t", "load")
    with xr.open_dataset(files["run"], engine="h5netcdf", group="events") as events:
        assert events["labels"].dims == ("times",) and "times" in events.coords


def test_comparison_and_sweep_open_with_xarray_h5netcdf(files):
    with xr.open_dataset(files["comparison"], engine="h5netcdf", group="projection") as run:
        assert "t" in run.coords and run["q"].dims == ("t", "coordinate")
    with xr.open_dataset(files["comparison"], engine="h5netcdf", group="summary") as summary:
        assert list(summary["method"].values) == ["none", "projection"]
        assert summary["max_phi"].dims == ("method",)
    with xr.open_dataset(files["sweep"], engine="h5netcdf", group="signals/0") as signals:
        assert "t" in signals.coords and signals["phi"].dims == ("t", "constraint")
    with xr.open_dataset(files["sweep"], engine="h5netcdf", group="runs") as runs:
        assert runs["max_phi"].dims == ("run",)


def test_load_gives_a_dataset_for_a_run_and_frames_for_tables(files):
    run = csim.load(files["run"])
    assert isinstance(run, xr.Dataset) and "t" in run.coords
    assert run["energy/kinetic"].attrs["units"] == "J" and run["q"].dims == ("t", "coordinate")
    np.testing.assert_array_equal(run["q"].sel(coordinate="q1").values, h5py.File(files["run"])["q"][:, 0])

    comparison = csim.load(files["comparison"])
    assert set(comparison) == {"summary", "work_precision"}
    assert list(comparison["summary"].index) == ["none", "projection"]
    assert comparison["summary"].attrs["units"]["max_phi"] == "m"
    assert len(comparison["work_precision"]) == 4
    method = csim.load(files["comparison"], "projection")
    assert "t" in method.coords and method.attrs["status"] == "success"

    sweep = csim.load(files["sweep"])["runs"]
    assert len(sweep) == 4 and set(sweep["stabilization.method"]) == {"none", "baumgarte"}
    assert sweep.attrs["units"]["mechanism.parameters.l1"] == "m"
    kept = csim.load(files["sweep"], "signals/2")
    assert "t" in kept.coords and kept["q"].attrs["units"] == "rad"


def test_load_names_what_a_file_holds_when_the_group_is_wrong(files):
    with pytest.raises(ResultFileError, match="runs: none, projection, reference"):
        csim.load(files["comparison"], "baumgarte")


def test_pandas_reads_a_run_as_a_frame_indexed_by_time(files):
    frame = frames(files["run"])["run"]
    assert frame.index.name == "t" and frame.attrs["units"]["q:q1"] == "rad"
    assert frame.attrs["units"]["forces/loads:cutting_force"] == "N"


@pytest.mark.parametrize("fmt", ["csv", "parquet"])
@pytest.mark.parametrize("kind", ["run", "comparison", "sweep"])
def test_export_round_trips(files, tmp_path, kind, fmt):
    if fmt == "parquet":
        pytest.importorskip("pyarrow")
    r = invoke("export", files[kind], "--format", fmt, "-o", tmp_path / "out")
    assert r.exit_code == 0, r.output
    original = frames(files[kind])
    written = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert written == sorted(f"{name}.{fmt}" for name in original)
    for name, frame in original.items():
        back = read_export(tmp_path / "out" / f"{name}.{fmt}")
        assert back.attrs["units"] == {k: v for k, v in frame.attrs["units"].items() if v}, name
        assert list(back.columns) == list(frame.columns), name
        for column in frame.columns:
            a, b = frame[column].to_numpy(), back[column].to_numpy()
            if a.dtype.kind == "f":
                np.testing.assert_array_equal(a, b.astype(float), err_msg=f"{name} {column}")
            else:
                assert [str(x) for x in a] == [str(x) for x in b], (name, column)
        np.testing.assert_array_equal(frame.index.to_numpy(), back.index.to_numpy())


def test_export_rejects_an_unknown_format_and_a_file_as_folder(files, tmp_path):
    r = invoke("export", files["run"], "--format", "xlsx", "-o", tmp_path / "x")
    assert r.exit_code == 2 and "--format 'xlsx'" in r.output and not (tmp_path / "x").exists()
    (tmp_path / "f").write_text("")
    r = invoke("export", files["run"], "-o", tmp_path / "f")
    assert r.exit_code == 2 and "not a folder" in r.output


def test_export_of_a_file_that_is_not_csim_is_bad_input(tmp_path):
    with h5py.File(tmp_path / "other.h5", "w") as fh:
        fh["x"] = np.arange(3)
    r = invoke("export", tmp_path / "other.h5", "-o", tmp_path / "out")
    assert r.exit_code == 2 and "not a csim result" in r.output
    with pytest.raises(ResultFileError):
        export(tmp_path / "missing.h5", tmp_path / "out")
