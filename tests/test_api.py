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


# --- the units of the constraints of link-coupling mechanisms -----------------------------

#: the unit of each constraint row of a link-coupling case: m for a position equation (a
#: component of r_jm - r_ik), 1 for an orientation equation (a product of two unit axes)
LINKAGE_ROWS = {
    "slider_crank.yaml": ["m", "m"],  # the cut revolute joint C: x, y
    "quick_return_tables.yaml": ["m", "1", "m", "1"],  # two cut slides: x_ik . d, x_ik . z_jm each
    "bricard.yaml": ["m", "m", "m", "1"],  # the cut revolute joint 6: d = 0 and one of z_ik = z_jm
}


def _unit(value):
    """A ``units`` attribute as a str, or a list of str (one per column)."""
    if isinstance(value, (np.ndarray, list, tuple)):
        return [v.decode() if isinstance(v, bytes) else str(v) for v in value]
    return value.decode() if isinstance(value, bytes) else str(value)


@pytest.fixture(scope="module")
def linkage_runs(tmp_path_factory):
    """A short run of each link-coupling case of LINKAGE_ROWS, with its case and result file."""
    from csim.case import load_case
    from csim.io.hdf5 import write_result
    from csim.pipeline import run_case

    d = tmp_path_factory.mktemp("linkage-units")
    out = {}
    for name in LINKAGE_ROWS:
        case = load_case(CONFIGS / name, ["simulation.t_end=0.1", "simulation.backend=python"])
        result = run_case(case)
        assert result.status == "success", result.message
        path = d / name.replace(".yaml", ".h5")
        write_result(path, result)
        out[name] = (case, result, path)
    return out


@pytest.mark.parametrize("name", list(LINKAGE_ROWS))
def test_link_coupling_constraints_get_the_units_of_their_equations(linkage_runs, name):
    from csim.io.hdf5 import read_result

    case, result, path = linkage_runs[name]
    rows = LINKAGE_ROWS[name]
    # the kind of each kept cut-joint equation, as csim describe labels it
    assert ["m" if "(r_jm - r_ik)" in label else "1" for label in case.linkage.equation_labels] == rows
    assert result.constraint_units == rows
    same = len(set(rows)) == 1
    phi = rows[0] if same else rows
    phi_dot = [f"{u}/s" for u in rows]
    lam = [{"m": "N", "1": "N m"}[u] for u in rows]
    expected = {"phi": phi, "phi_dot": phi_dot[0] if same else phi_dot, "lambda": lam[0] if same else lam}
    with h5py.File(path, "r") as fh:
        assert {k: _unit(fh[k].attrs["units"]) for k in expected} == expected
    assert read_result(path).constraint_units == rows
    run = csim.load(path)
    assert {k: _unit(run[k].attrs["units"]) for k in expected} == expected
    ureg = pint.UnitRegistry()
    for units in expected.values():
        for unit in units if isinstance(units, list) else [units]:
            ureg.parse_units(unit)


@pytest.mark.parametrize("name, rows", [("quick_return.yaml", ["m", "m"]), ("pendulum.yaml", ["m"]),
                                        ("andrews.yaml", ["m"] * 6)])
def test_registered_mechanisms_keep_the_units_dimensional_analysis_finds(name, rows):
    from csim.case import load_case
    from csim.io.units import declared_constraint_units, mechanism_units
    from csim.pipeline import numeric_model

    case = load_case(CONFIGS / name)
    assert declared_constraint_units(case.mechanism) is None  # not the linkage's rows
    model = numeric_model(case)
    units = mechanism_units(case.mechanism, model, model.parameter_vector(case.parameters))
    assert units["constraint_units"] == rows


def test_a_unit_that_cannot_be_determined_is_not_written_as_dimensionless():
    from csim.io.units import UNKNOWN, common_unit, constraint_units, multiplier_unit, per_time

    assert UNKNOWN == "" and common_unit(["", ""]) == "" and common_unit(["m", ""]) == ["m", ""]
    assert per_time("") == "" and multiplier_unit("") == ""
    assert (multiplier_unit("m"), multiplier_unit("1"), multiplier_unit("m^2")) == ("N", "N m", "J/m^2")

    def phi(q, par):  # a length (par 0, declared in m), and one in a parameter of unknown unit (par 1)
        return np.array([q[0] - par[0], q[0] - par[1]])

    par = np.array([0.5, 0.2])
    assert constraint_units(phi, np.zeros(1), par, np.array([True]), np.array([True, False]),
                            np.array([False, True])) == ["m", UNKNOWN]
