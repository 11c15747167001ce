"""Result files: round trip, atomic writing, failed runs."""
from __future__ import annotations

from types import SimpleNamespace

import h5py
import numpy as np
import pytest
import yaml
from conftest import qr_case

from csim.errors import ResultFileError
from csim.io.hdf5 import atomic_h5, read_result, write_result
from csim.pipeline import run_case
from csim.result import failure_kind


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
                      if isinstance(obj, h5py.Dataset) and not ("units" in obj.attrs and "description" in obj.attrs)
                      else None)
        assert not missing
        assert fh["q"].attrs["units"] == "rad" and fh["events/labels"].attrs["units"] == "1"
    back = read_result(path)
    assert (back.coordinate_units, back.constraint_units, back.load_units) == (["rad"] * 3, ["m", "m"], ["N m", "N"])
    assert (back.observable_units, back.observable_rate_units) == (["m"], ["m/s"])


def test_columns_of_different_units_get_one_unit_each(tmp_path, short_result):
    from dataclasses import replace

    path = tmp_path / "r.h5"
    write_result(path, replace(short_result, coordinate_units=["rad", "m", "rad"]))
    with h5py.File(path) as fh:
        assert [u.decode() if isinstance(u, bytes) else u for u in fh["qdd"].attrs["units"]] == [
            "rad/s^2", "m/s^2", "rad/s^2"]
        assert list(fh["forces/generalized"].attrs["units"]) in ([b"N m", b"N", b"N m"], ["N m", "N", "N m"])
    assert read_result(path).coordinate_units == ["rad", "m", "rad"]


def test_arrays_are_attached_to_dimension_scales(tmp_path, short_result):
    path = tmp_path / "r.h5"
    write_result(path, short_result)
    with h5py.File(path) as fh:
        assert fh["q"].dims[0][0].name == "/t" and fh["q"].dims[1][0].name == "/coordinate"
        assert fh["energy/work"].dims[1][0].name == "/load" and fh["lambda"].dims[1][0].name == "/constraint"
        assert fh["observables/ram_x"].dims[0][0].name == "/t"
        assert [x.decode() for x in fh["coordinate"][()]] == ["q1", "q2", "q3"]


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


def test_a_hundred_thousand_events_are_written_and_read_back(tmp_path, short_result):
    """A run stopped at simulation.max_events (100,000) still gets its file: events are datasets."""
    import dataclasses

    n = 100_000
    many = dataclasses.replace(short_result, status="failed", message="more than simulation.max_events",
                               event_times=np.linspace(0.0, 0.3, n),
                               event_labels=[f"cutting_force: switch {i}" for i in range(n)])
    path = tmp_path / "chatter.h5"
    write_result(path, many)
    back = read_result(path)
    np.testing.assert_array_equal(back.event_times, many.event_times)
    assert back.event_labels == many.event_labels
    assert back.status == "failed"
    with h5py.File(path) as fh:
        assert "event_times" not in fh.attrs and fh["events/times"].shape == (n,)


def test_files_with_event_times_as_attributes_are_still_read(tmp_path, short_result):
    path = tmp_path / "old.h5"
    write_result(path, short_result)
    with h5py.File(path, "r+") as fh:  # the layout of earlier versions: attributes, no events group
        del fh["events"]
        for name in ("failure", "backend_reason"):
            del fh.attrs[name]
        fh.attrs["event_times"] = np.asarray(short_result.event_times)
        fh.attrs["event_labels"] = np.array(short_result.event_labels, dtype=h5py.string_dtype())
    back = read_result(path)
    np.testing.assert_array_equal(back.event_times, short_result.event_times)
    assert back.event_labels == short_result.event_labels and len(back.event_labels) > 0
    assert back.failure == "" and back.backend_reason == ""


def test_failure_and_backend_reason_round_trip(tmp_path, short_result):
    import dataclasses

    marked = dataclasses.replace(short_result, status="failed", failure="interrupted",
                                 backend_reason="numba is not installed")
    write_result(tmp_path / "m.h5", marked)
    back = read_result(tmp_path / "m.h5")
    assert (back.failure, back.backend_reason) == ("interrupted", "numba is not installed")


def test_an_empty_result_is_a_valid_file(tmp_path):
    from csim.result import Result

    empty = Result.empty("quick_return", ["q1", "q2", "q3"], ["torque", "cutting_force"], ["ram_x"], 2,
                         "mechanism: {name: quick_return}\n", message="interrupted", failure="interrupted")
    write_result(tmp_path / "e.h5", empty)
    back = read_result(tmp_path / "e.h5")
    assert back.t.shape == (0,) and back.q.shape == (0, 3) and back.phi.shape == (0, 2)
    assert back.work.shape == (0, 2) and back.observables.shape == (0, 1)
    assert back.failure == "interrupted" and "status:            failed (interrupted)" in back.summary()


def test_failed_initial_conditions_are_marked_as_an_assembly_failure(tmp_path):
    res = run_case(qr_case("mechanism.parameters.h2=100"))
    assert res.failure == "assembly"
    write_result(tmp_path / "a.h5", res)
    assert read_result(tmp_path / "a.h5").failure == "assembly"
    assert run_case(qr_case("simulation.t_end=0.05")).failure == ""


def _status_codes() -> dict[str, int]:
    """Every failure code of csim.physics.status, by name (OK left out)."""
    from csim.physics import status as st

    return {name: code for name, code in vars(st).items()
            if name.isupper() and isinstance(code, int) and code != st.OK}


#: the kind each status code's message is filed under (a new code must be added here)
CODE_KINDS = {"NONFINITE_RHS": "blow-up", "NONFINITE_STATE": "blow-up", "MAX_PHI": "drift",
              "STEP_COLLAPSE": "step collapse", "MAX_STEPS": "max steps", "STEP_TOO_SMALL": "step collapse",
              "SINGULAR_KKT": "singular", "PROJ_SINGULAR": "singular", "PROJ_NO_CONVERGENCE": "projection",
              "MAX_EVENTS": "chatter", "RK4_RESOLUTION": "step", "SINGULAR_MASS": "singular",
              "NO_SIGN_CHANGE": "event location", "CHATTER": "chatter",
              "DEPENDENT_NONFINITE": "blow-up", "DEPENDENT_SINGULAR": "singular", "DEPENDENT_NO_CONVERGENCE": "newton",
              "BRANCH_LEFT": "branch", "NO_BETTER_PARTITION": "branch", "BRANCH_LOST": "branch",
              "INTERRUPTED": "interrupted", "ELIMINATION_FIXED_SINGULAR": "singular",
              "ELIMINATION_NO_BLOCK": "singular", "ELIMINATION_SINGULAR": "singular",
              "TANGENT_MASS_SINGULAR": "singular", "GGL_SINGULAR_MASS": "singular"}


def test_every_status_code_is_listed():
    assert set(_status_codes()) == set(CODE_KINDS)


def test_each_status_code_carries_the_kind_its_message_is_filed_under():
    # a run's failure kind comes from its code (csim.physics.status.KINDS); the message
    # classifier (for messages without a code) must file every code's message the same way
    from csim.physics import status as st
    from csim.physics.partition import D_CODE, new_partition
    from csim.solver.failures import failure

    assert {name: st.code_kind(code) for name, code in _status_codes().items()} == CODE_KINDS
    # NO_BETTER_PARTITION is the kind of the breakdown it could not get past, as its message reads
    detail = new_partition(3, 2, 0).detail
    detail[:] = 0.5
    for inner, kind in ((st.DEPENDENT_SINGULAR, "singular"), (st.DEPENDENT_NO_CONVERGENCE, "newton"),
                        (st.BRANCH_LEFT, "branch")):
        detail[D_CODE] = inner
        exc = failure(st.NO_BETTER_PARTITION, 0.0, 0.0, None, SimpleNamespace(tol=1e-13, max_iter=20),
                      detail=detail, coordinates=["q1", "q2", "q3"])
        assert exc.kind == kind == failure_kind(str(exc))


@pytest.mark.parametrize("name", sorted(CODE_KINDS))
def test_every_failure_code_writes_its_kind_as_the_failure_attribute(tmp_path, name):
    from types import SimpleNamespace

    from csim.physics.partition import new_partition
    from csim.result import FAILURES, Result
    from csim.solver.failures import failure_message

    case = qr_case()  # an adaptive integrator (an RK4 step failure is its own kind)
    method = SimpleNamespace(tol=1e-13, max_iter=20)  # the projection's and minimal's settings quoted
    detail = new_partition(3, 2, 0).detail  # the minimal-coordinate codes' details (csim.physics.partition)
    detail[:] = 0.5
    message = failure_message(_status_codes()[name], 1.0, 2.0, case.integration_settings(), method,
                              ["cutting_force"], detail=detail, coordinates=["q1", "q2", "q3"])
    failed = Result.empty("quick_return", ["q1", "q2", "q3"], [], [], 2, "", message=message)
    assert failed.failure == CODE_KINDS[name] and failed.failure in FAILURES
    path = tmp_path / "f.h5"
    write_result(path, failed)
    with h5py.File(path) as fh:
        assert fh.attrs["failure"] == CODE_KINDS[name]
    assert read_result(path).failure == CODE_KINDS[name]


def test_a_success_has_no_failure_and_a_given_kind_is_kept(short_result):
    from csim.result import Result

    assert short_result.failure == ""
    kept = Result.empty("quick_return", ["q1"], [], [], 0, "", message="blow-up: x", failure="interrupted")
    assert kept.failure == "interrupted"
    assert Result.empty("quick_return", ["q1"], [], [], 0, "", message="something new").failure == "other"
