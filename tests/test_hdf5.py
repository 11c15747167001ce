"""Result files: round trip, atomic writing, failed runs."""
from __future__ import annotations

import h5py
import numpy as np
import pytest
import yaml
from conftest import qr_case

from csim.errors import ResultFileError
from csim.io.hdf5 import atomic_h5, read_result, write_result
from csim.pipeline import run_case


@pytest.fixture(scope="module")
def short_result():
    return run_case(qr_case("simulation.t_end=0.3"))


def test_round_trip(tmp_path, short_result):
    path = tmp_path / "r.h5"
    write_result(path, short_result)
    back = read_result(path)
    for name in ("t", "q", "qd", "qdd", "lam", "phi", "phi_dot", "kinetic", "potential", "work", "loads",
                 "generalized_forces", "observables", "observable_rates", "event_times"):
        np.testing.assert_array_equal(getattr(back, name), getattr(short_result, name), err_msg=name)
    assert back.event_labels == short_result.event_labels
    assert back.status == "success" and back.nfev == short_result.nfev
    assert back.coordinate_names == ["q1", "q2", "q3"]
    assert yaml.safe_load(back.case_yaml)["mechanism"]["name"] == "quick_return"


def test_every_dataset_has_units(tmp_path, short_result):
    path = tmp_path / "r.h5"
    write_result(path, short_result, ["rad", "rad", "rad"])
    with h5py.File(path) as fh:
        missing = []
        fh.visititems(lambda name, obj: missing.append(name)
                      if isinstance(obj, h5py.Dataset) and "units" not in obj.attrs and name != "events/labels"
                      else None)
        assert not missing
        assert list(fh["q"].attrs["units"]) == [b"rad", b"rad", b"rad"] or list(fh["q"].attrs["units"]) == [
            "rad", "rad", "rad"]


def test_result_file_mode_follows_the_umask(tmp_path, short_result):
    import os

    old = os.umask(0o022)
    try:
        write_result(tmp_path / "r.h5", short_result)
    finally:
        os.umask(old)
    assert (tmp_path / "r.h5").stat().st_mode & 0o777 == 0o644


def test_interrupted_write_leaves_no_file(tmp_path):
    path = tmp_path / "r.h5"
    with pytest.raises(RuntimeError), atomic_h5(path) as fh:
        fh.create_dataset("t", data=np.arange(3))
        raise RuntimeError("crash while writing")
    assert list(tmp_path.iterdir()) == []


def test_interrupted_write_keeps_the_previous_file(tmp_path, short_result):
    path = tmp_path / "r.h5"
    write_result(path, short_result)
    with pytest.raises(RuntimeError), atomic_h5(path):
        raise RuntimeError("crash")
    assert read_result(path).status == "success"
    assert [p.name for p in tmp_path.iterdir()] == ["r.h5"]


def test_failed_initial_conditions_still_give_a_valid_marked_file(tmp_path):
    res = run_case(qr_case("mechanism.parameters.h2=100"))
    assert res.status == "failed" and "Newton-Raphson did not converge" in res.message
    path = tmp_path / "failed.h5"
    write_result(path, res)
    back = read_result(path)
    assert back.status == "failed" and back.t.size == 0 and "Phi[" in back.message


def test_reading_a_non_result_is_a_clear_error(tmp_path):
    junk = tmp_path / "junk.h5"
    junk.write_text("not hdf5")
    with pytest.raises(ResultFileError, match="not a readable HDF5 file"):
        read_result(junk)
    with pytest.raises(ResultFileError, match="no such result file"):
        read_result(tmp_path / "missing.h5")
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as fh:
        fh["x"] = 1
    with pytest.raises(ResultFileError, match="not a csim result"):
        read_result(other)
