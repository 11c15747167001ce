"""The registry of per-sample output quantities (csim.io.outputs): each record is a Result
field, an evaluation's field where it says so, a dataset of the result file with the
record's unit and description, and a figure or series of csim plot."""
from __future__ import annotations

import dataclasses

import h5py
import numpy as np
import pytest
from conftest import qr_case

from csim.io.hdf5 import run_units, write_result
from csim.io.outputs import EVALUATED, OUTPUTS
from csim.pipeline import run_case
from csim.plot.registry import RUN_FIGURES
from csim.result import Result
from csim.solver.system import Evaluation


def test_every_output_is_a_result_field_and_every_evaluated_one_an_evaluation_field():
    result_fields = {f.name for f in dataclasses.fields(Result)}
    evaluation_fields = {f.name for f in dataclasses.fields(Evaluation)}
    computed = {name for name in dir(Result) if isinstance(getattr(Result, name), property)}  # energy_error
    assert {o.name for o in OUTPUTS} <= result_fields | computed
    assert all(o.evaluation is None for o in OUTPUTS if o.name in computed)
    assert {o.evaluation for o in EVALUATED.values()} <= evaluation_fields
    assert len({o.dataset for o in OUTPUTS}) == len(OUTPUTS)


def test_every_figure_named_is_one_csim_plot_draws():
    for out in OUTPUTS:
        if out.figure is None:
            continue
        if out.figure.startswith("--series "):
            assert out.figure.split()[1].split(":")[0] in ("q", "qd", "qdd", "phi", "phi_dot", "lambda", "load")
        else:
            assert out.figure in RUN_FIGURES, out


@pytest.mark.parametrize("backend", ["python", "compiled"])
def test_a_run_fills_every_output_and_the_file_carries_each_with_its_unit(tmp_path, backend):
    result = run_case(qr_case("simulation.t_end=0.05", f"simulation.backend={backend}"))
    assert result.ok and result.backend == backend
    path = tmp_path / "r.h5"
    write_result(path, result)
    units = run_units(result)
    with h5py.File(path, "r") as fh:
        for out in OUTPUTS:
            values = getattr(result, out.name)
            assert values.shape[0] == result.t.size and np.all(np.isfinite(values)), out.name
            ds = fh[out.dataset]
            np.testing.assert_array_equal(ds[()], values)
            expected = out.unit(units)
            written = ds.attrs["units"]
            assert (list(written) if isinstance(expected, list) else written) == expected, out.name
            assert ds.attrs["description"] == out.description
            assert ds.dims[0][0].name.endswith("/t")
    # the quick-return's units spelled out: its accelerations, and the multipliers of its loop closures in m
    assert OUTPUTS[2].unit(units) == "rad/s^2" and EVALUATED["lam"].unit(units) == "N"
