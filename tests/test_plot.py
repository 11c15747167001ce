"""``csim plot``: every figure kind from short runs, the plotted data against the HDF5 data,
and clear errors (exit code 2) for bad files and options."""
from __future__ import annotations

import math
from pathlib import Path

import h5py
import numpy as np
import pytest
from conftest import assert_bad_input, invoke, simulated_file

from csim.case import load_case
from csim.compare import compare
from csim.io.hdf5 import write_result
from csim.mechanisms import MECHANISMS, get_mechanism
from csim.pipeline import numeric_model, run_case
from csim.plot import COMPARISON_FIGURES, RUN_FIGURES, PlotError, figures, plot_file
from csim.plot.drawing import geometry, snapshot_indices
from csim.plot.series import resolve, series_names
from csim.plot.source import constraint_units, load_comparison, load_run

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
QR_FIGURES = ["crank_velocity", "ram_displacement", "ram_position_velocity", "rocker_rod_angles", "constraint_error",
              "configurations", "coordinates", "velocities", "constraints", "energy", "multipliers", "loads"]


@pytest.fixture(scope="module")
def qr_file(tmp_path_factory):
    """A 0.2 s quick-return run (the cutting force switches on within it)."""
    return simulated_file(tmp_path_factory, "quick_return.yaml", "qr.h5", "simulation.t_end=0.2")


@pytest.fixture(scope="module")
def pendulum_file(tmp_path_factory):
    return simulated_file(tmp_path_factory, "pendulum.yaml", "pendulum.h5", "simulation.t_end=0.3")


@pytest.fixture(scope="module")
def comparison_file(tmp_path_factory):
    """A real comparison with a tolerance study: none, Baumgarte and sliding mode, 0.2 s."""
    c = compare(CONFIGS / "quick_return.yaml", methods=["none", "baumgarte", "sliding_mode"],
                tolerances=[1e-5, 1e-7], overrides=["simulation.t_end=0.2", "simulation.integrator=RK45"], jobs=1)
    path = tmp_path_factory.mktemp("plot") / "cmp.h5"
    c.write(path)
    return path


@pytest.fixture(scope="module")
def plain_comparison_file(tmp_path_factory):
    """A comparison without a tolerance study, and without a sliding-mode run."""
    c = compare(CONFIGS / "pendulum.yaml", methods=["none", "projection"], overrides=["simulation.t_end=0.2"],
                jobs=1)
    path = tmp_path_factory.mktemp("plot") / "pend_cmp.h5"
    c.write(path)
    return path


def read(path, name, group="/"):
    with h5py.File(path, "r") as fh:
        return fh[group][name][()]


def build(path, name, group=None):
    names, _, built = figures(path, only=[name], group=group)
    assert names == [name]
    ((got, fig),) = list(built)
    assert got == name
    return fig


def data_lines(ax):
    """The plotted curves of an axes (not grid or helper lines)."""
    return [line for line in ax.get_lines() if len(line.get_xdata()) > 1]


# --------------------------------------------------------------------------- single run: the paper's figures


def test_quick_return_run_gives_the_paper_figures_and_the_generic_ones(qr_file, tmp_path):
    report = plot_file(qr_file, tmp_path / "figs", dpi=40)
    assert [p.name for p in report.written] == [f"{n}.png" for n in QR_FIGURES]
    for path in report.written:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert set(report.skipped) == {"drive", "reactions"}  # a registered mechanism: no drives, no cut joints


def test_crank_velocity_H2_plots_qd1(qr_file):
    fig = build(qr_file, "crank_velocity")
    (ax,) = fig.axes
    (line,) = data_lines(ax)
    np.testing.assert_array_equal(line.get_xdata(), read(qr_file, "t"))
    np.testing.assert_array_equal(line.get_ydata(), read(qr_file, "qd")[:, 0])
    assert ax.get_ylabel().endswith("[rad/s]") and ax.get_xlabel() == "time t [s]"
    assert "H.2" in fig.get_suptitle()


def test_ram_displacement_H3_is_the_change_of_x_D(qr_file):
    (ax,) = build(qr_file, "ram_displacement").axes
    (line,) = data_lines(ax)
    x = read(qr_file, "observables/ram_x")
    np.testing.assert_array_equal(line.get_ydata(), x - x[0])
    assert ax.get_ylabel().endswith("[m]")


def test_ram_position_and_velocity_H4(qr_file):
    top, bottom = build(qr_file, "ram_position_velocity").axes
    np.testing.assert_array_equal(data_lines(top)[0].get_ydata(), read(qr_file, "observables/ram_x"))
    np.testing.assert_array_equal(data_lines(bottom)[0].get_ydata(), read(qr_file, "observables/ram_x_rate"))
    assert top.get_ylabel().endswith("[m]") and bottom.get_ylabel().endswith("[m/s]")
    assert bottom.get_xlabel() == "time t [s]"


def test_rocker_and_rod_angles_H5(qr_file):
    (ax,) = build(qr_file, "rocker_rod_angles").axes
    rocker, rod = data_lines(ax)
    q = read(qr_file, "q")
    np.testing.assert_array_equal(rocker.get_ydata(), q[:, 1])
    np.testing.assert_array_equal(rod.get_ydata(), q[:, 2])
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [r"rocker $q_2$", r"rod $q_3$"]


def test_constraint_error_H6_on_a_log_scale(qr_file):
    (ax,) = build(qr_file, "constraint_error").axes
    assert ax.get_yscale() == "log"
    phi = read(qr_file, "phi")
    for i, line in enumerate(data_lines(ax)):
        np.testing.assert_array_equal(line.get_ydata(), np.abs(phi[:, i]))
    assert ax.get_ylabel().endswith("[m]")


def test_configurations_H7_draw_the_links_at_the_sampled_instants(qr_file):
    fig = build(qr_file, "configurations")
    t, q = read(qr_file, "t"), read(qr_file, "q")
    par = get_mechanism("quick_return")
    l1 = par.parameter("l1").default
    h1 = par.parameter("h1").default
    axes = [ax for ax in fig.axes if ax.get_visible()]
    # 0.2 s is less than one crank turn: six instants over the whole run, both ends included
    assert len(axes) == 6
    assert axes[0].get_title() == "t = 0.000 s" and axes[-1].get_title() == f"t = {t[-1]:.3f} s"
    for ax in axes:
        k = int(np.argmin(np.abs(t - float(ax.get_title().split()[2]))))
        (crank,) = ax.findobj(lambda a: a.get_gid() == "link:O-A")
        xy = np.column_stack((crank.get_xdata(), crank.get_ydata()))
        expected = [[0.0, h1], [l1 * math.cos(q[k, 0]), h1 + l1 * math.sin(q[k, 0])]]
        np.testing.assert_allclose(xy, expected, atol=1e-12)
        assert ax.get_aspect() == 1.0
        (ram,) = ax.findobj(lambda a: a.get_gid() == "link:ram_1-ram_2-ram_3-ram_4")
        x_d = read(qr_file, "observables/ram_x")[k]
        np.testing.assert_allclose(ram.get_xy()[:4, 0], [x_d - 0.5, x_d + 0.5, x_d + 0.5, x_d - 0.5], atol=1e-12)


def test_drawing_points_equal_the_generated_model_points(qr_file):
    run = load_run(qr_file)
    geom = geometry(run.definition, run.parameters)
    model = numeric_model(load_case(CONFIGS / "quick_return.yaml"))
    q = read(qr_file, "q")
    par = model.parameter_vector(run.parameters)
    for k in (0, len(q) // 2, len(q) - 1):
        np.testing.assert_allclose(geom.points(q[k]), model.points(q[k], par), atol=1e-12)
    np.testing.assert_allclose(geom.points(q)[3], geom.points(q[3]))


def test_snapshot_instants_split_one_cycle_when_the_crank_turns():
    t = np.linspace(0.0, 2.0, 201)
    q = np.column_stack((2 * math.pi * t, np.zeros_like(t)))  # one turn per second
    idx = snapshot_indices(t, q, 4, cycle=0)
    np.testing.assert_allclose(t[idx], [0.0, 0.25, 0.5, 0.75])
    idx = snapshot_indices(t, q, 3)
    np.testing.assert_allclose(t[idx], [0.0, 1.0, 2.0])
    q[150:] = np.nan  # a blown-up end is not drawn
    assert snapshot_indices(t, q, 3).max() < 150


# --------------------------------------------------------------------------- single run: generic figures


def test_coordinates_and_velocities_plot_every_column(qr_file):
    for name, dataset, unit in (("coordinates", "q", "[rad]"), ("velocities", "qd", "[rad/s]")):
        (ax,) = build(qr_file, name).axes
        data = read(qr_file, dataset)
        lines = data_lines(ax)
        assert len(lines) == data.shape[1]
        for j, line in enumerate(lines):
            np.testing.assert_array_equal(line.get_ydata(), data[:, j])
        assert ax.get_ylabel().endswith(unit)


def test_constraints_figure_plots_phi_and_phi_dot_magnitudes(qr_file):
    top, bottom = build(qr_file, "constraints").axes
    for ax, dataset, unit in ((top, "phi", "[m]"), (bottom, "phi_dot", "[m/s]")):
        data = read(qr_file, dataset)
        for j, line in enumerate(data_lines(ax)):
            np.testing.assert_array_equal(line.get_ydata(), np.abs(data[:, j]))
        assert ax.get_yscale() == "log" and ax.get_ylabel().endswith(unit)


def test_energy_figure_plots_the_balance(qr_file):
    top, bottom = build(qr_file, "energy").axes
    kinetic, potential = read(qr_file, "energy/kinetic"), read(qr_file, "energy/potential")
    work = read(qr_file, "energy/work")
    t_line, v_line, *w_lines = data_lines(top)
    np.testing.assert_array_equal(t_line.get_ydata(), kinetic)
    np.testing.assert_array_equal(v_line.get_ydata(), potential - potential[0])
    for j, line in enumerate(w_lines):
        np.testing.assert_array_equal(line.get_ydata(), work[:, j])
    np.testing.assert_allclose(data_lines(bottom)[0].get_ydata(), read(qr_file, "energy/balance_error"),
                               rtol=0, atol=1e-9)
    assert top.get_ylabel() == "energy [J]" and bottom.get_ylabel().endswith("[J]")


def test_multipliers_and_loads_figures(qr_file):
    (ax,) = build(qr_file, "multipliers").axes
    lam = read(qr_file, "lambda")
    for j, line in enumerate(data_lines(ax)):
        np.testing.assert_array_equal(line.get_ydata(), lam[:, j])
    assert ax.get_ylabel().endswith("[N]")  # J per m of constraint
    torque, force = build(qr_file, "loads").axes
    loads = read(qr_file, "forces/loads")
    np.testing.assert_array_equal(data_lines(torque)[0].get_ydata(), loads[:, 0])
    np.testing.assert_array_equal(data_lines(force)[0].get_ydata(), loads[:, 1])
    assert torque.get_ylabel() == "torque [N m]" and force.get_ylabel() == "cutting force [N]"


def test_pendulum_declares_its_own_figures_and_is_drawn(pendulum_file, tmp_path):
    names, skipped, _ = figures(pendulum_file)
    assert names[:2] == ["angle", "configurations"] and "mechanism" not in names
    assert "loads" in skipped  # the pendulum has no loads
    top, bottom = build(pendulum_file, "angle").axes
    np.testing.assert_array_equal(data_lines(top)[0].get_ydata(), read(pendulum_file, "observables/angle"))
    assert top.get_ylabel().endswith("[rad]") and bottom.get_ylabel().endswith("[rad/s]")
    fig = build(pendulum_file, "configurations")
    t, q = read(pendulum_file, "t"), read(pendulum_file, "q")
    for ax in (a for a in fig.axes if a.get_visible()):
        k = int(np.argmin(np.abs(t - float(ax.get_title().split()[2]))))
        (rod,) = ax.findobj(lambda a: a.get_gid() == "link:pivot-bob")
        np.testing.assert_allclose(rod.get_xydata(), [[0.0, 0.0], q[k]], atol=1e-15)


@pytest.mark.parametrize("fmt, magic", [("pdf", b"%PDF"), ("svg", b"<?xml")])
def test_other_formats(qr_file, tmp_path, fmt, magic):
    report = plot_file(qr_file, tmp_path, fmt=fmt, only=["crank_velocity"])
    assert [p.name for p in report.written] == [f"crank_velocity.{fmt}"]
    assert report.written[0].read_bytes().startswith(magic)


def test_group_of_a_comparison_is_plotted_as_a_run(comparison_file):
    fig = build(comparison_file, "crank_velocity", group="baumgarte")
    np.testing.assert_array_equal(data_lines(fig.axes[0])[0].get_ydata(),
                                  read(comparison_file, "qd", "baumgarte")[:, 0])
    assert "baumgarte" in fig.get_suptitle()


# --------------------------------------------------------------------------- declared figures and series


@pytest.mark.parametrize("mechanism", sorted(MECHANISMS))
def test_every_declared_series_exists(mechanism, qr_file, pendulum_file):
    path = {"quick_return": qr_file, "pendulum": pendulum_file}.get(mechanism)
    if path is None:
        pytest.skip(f"no short run of {mechanism} in this test module")
    run = load_run(path)
    valid = set(series_names(run))
    for figure in run.definition.figures:
        assert figure.snapshots > 0 or figure.panels, figure.name
        for panel in figure.panels:
            for name in panel.series:
                assert name.removeprefix("change:") in valid, (figure.name, name)
    names = [f.name for f in run.definition.figures]
    assert len(set(names)) == len(names) and all(n.isidentifier() for n in names)  # unique file stems
    assert not set(names) & set(RUN_FIGURES)  # none hides a generic figure


def test_unknown_series_lists_the_valid_ones(qr_file):
    run = load_run(qr_file)
    with pytest.raises(PlotError, match=r"no coordinate 'q9'.*valid series.*q:q1"):
        resolve("q:q9", run)
    with pytest.raises(PlotError, match=r"unknown kind 'speed'"):
        resolve("speed:q1", run)
    with pytest.raises(PlotError, match=r"constraint number '3' is not in 1\.\.2"):
        resolve("phi:3", run)
    assert resolve("phi:max", run).unit == "m"
    assert resolve("lambda:1", run).unit == "N"


def test_constraint_units_by_dimensional_analysis():
    for name, expected in (("quick_return", ["m", "m"]), ("pendulum", ["m"])):
        d = get_mechanism(name)
        assert constraint_units(d, {p.name: p.default for p in d.parameters}) == expected


# --------------------------------------------------------------------------- comparison files: H.8, H.9, work-precision


def test_comparison_gives_its_figures(comparison_file, tmp_path):
    report = plot_file(comparison_file, tmp_path, dpi=40)
    assert [p.stem for p in report.written] == list(COMPARISON_FIGURES)
    assert report.skipped == {}


def test_constraint_errors_H8_one_line_per_method(comparison_file):
    fig = build(comparison_file, "constraint_errors")
    (ax,) = fig.axes
    assert ax.get_yscale() == "log" and "H.8" in fig.get_suptitle()
    lines = data_lines(ax)
    assert [line.get_label() for line in lines] == ["none", "baumgarte", "sliding_mode"]
    for line in lines:
        method = line.get_label()
        np.testing.assert_array_equal(line.get_xdata(), read(comparison_file, "t", method))
        np.testing.assert_array_equal(line.get_ydata(), np.max(np.abs(read(comparison_file, "phi", method)), axis=1))
    assert lines[0].get_color() == "black"


def test_baumgarte_against_sliding_mode_H9(comparison_file):
    fig = build(comparison_file, "baumgarte_vs_sliding_mode")
    (ax,) = fig.axes
    lines = data_lines(ax)
    assert [line.get_label() for line in lines] == ["baumgarte", "sliding_mode"]
    for line in lines:
        np.testing.assert_array_equal(line.get_ydata(),
                                      np.max(np.abs(read(comparison_file, "phi", line.get_label())), axis=1))
    assert "H.9" in fig.get_suptitle() and ax.get_yscale() == "log"


def test_motion_errors_against_the_reference(comparison_file):
    (ax,) = build(comparison_file, "motion_errors").axes
    q_ref = read(comparison_file, "q", "reference")
    for line in data_lines(ax):
        q = read(comparison_file, "q", line.get_label())
        np.testing.assert_array_equal(line.get_ydata(), np.max(np.abs(q - q_ref), axis=1))
    assert ax.get_ylabel().endswith("[rad]")


@pytest.mark.parametrize("name, cost", [("work_precision_time", "wall_time"), ("work_precision_nfev", "nfev")])
def test_work_precision_lines_are_the_table(comparison_file, name, cost):
    fig = build(comparison_file, name)
    error_ax, phi_ax = fig.axes
    assert all(ax.get_xscale() == "log" and ax.get_yscale() == "log" for ax in (error_ax, phi_ax))
    with h5py.File(comparison_file, "r") as fh:
        table = {k: fh["work_precision"][k][()] for k in fh["work_precision"]}
    methods = np.array([m.decode() for m in table["method"]])
    for error_line, phi_line in zip(data_lines(error_ax), data_lines(phi_ax)):
        rows = np.flatnonzero(methods == error_line.get_label())
        rows = rows[np.argsort(-table["tolerance"][rows])]  # loosest first
        assert rows.size == 2
        np.testing.assert_array_equal(error_line.get_xdata(), table[cost][rows])
        np.testing.assert_array_equal(error_line.get_ydata(), table["motion_error"][rows])
        np.testing.assert_array_equal(phi_line.get_xdata(), table[cost][rows])
        np.testing.assert_array_equal(phi_line.get_ydata(), table["max_phi"][rows])
    assert len(data_lines(error_ax)) == 3
    assert phi_ax.get_xlabel() in ("wall time [s]", "right-hand-side evaluations")


def test_comparison_without_a_study_skips_the_charts(plain_comparison_file):
    names, skipped, built = figures(plain_comparison_file)
    assert names == ["constraint_errors", "velocity_constraint_errors", "motion_errors"]
    assert "tolerance study" in skipped["work_precision_time"]
    assert "sliding_mode" in skipped["baumgarte_vs_sliding_mode"]
    with pytest.raises(PlotError, match="not available.*no tolerance study"):
        figures(plain_comparison_file, only=["work_precision_nfev"])
    data = load_comparison(plain_comparison_file)
    assert data.runs["none"].constraint_units == ["m"]


# --------------------------------------------------------------------------- the command line


def test_cli_plot_writes_the_figures(qr_file, tmp_path):
    result = invoke("plot", qr_file, "-o", tmp_path / "out", "--only", "crank_velocity", "--dpi", "40")
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["crank_velocity.png"]
    assert "wrote" in result.output


def test_cli_plot_missing_file(tmp_path):
    assert_bad_input(invoke("plot", tmp_path / "nope.h5", "-o", tmp_path), "no such result file")


def test_cli_plot_not_hdf5(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_text("not hdf5")
    assert_bad_input(invoke("plot", bad, "-o", tmp_path / "o"), "not a readable HDF5 file")


def test_cli_plot_not_a_csim_result(tmp_path):
    other = tmp_path / "other.h5"
    with h5py.File(other, "w") as fh:
        fh["x"] = [1.0]
    assert_bad_input(invoke("plot", other, "-o", tmp_path / "o"), "not a csim result")


def test_cli_plot_bad_options(qr_file, comparison_file, tmp_path):
    assert_bad_input(invoke("plot", qr_file, "-o", tmp_path, "--only", "crank,energy"),
                     "unknown figure(s) 'crank'", "valid names: crank_velocity")
    assert_bad_input(invoke("plot", qr_file, "-o", tmp_path, "--format", "jpg"), "valid formats: png, pdf, svg")
    assert_bad_input(invoke("plot", comparison_file, "-o", tmp_path, "--group", "ggl"), "no group 'ggl'")
    assert_bad_input(invoke("plot", qr_file, "-o", tmp_path, "--only", "work_precision_time"),
                     "valid names")
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert_bad_input(invoke("plot", qr_file, "-o", blocker, "--only", "energy"), "not a folder")


def test_cli_plot_run_without_samples(tmp_path):
    case = load_case(CONFIGS / "quick_return.yaml", ["initial.max_iter=1", "initial.tol=1e-300",
                                                       "simulation.t_end=0.1"])
    result = run_case(case)
    assert result.t.size == 0 and not result.ok
    path = tmp_path / "failed.h5"
    write_result(path, result, case.mechanism.coordinate_units)
    assert_bad_input(invoke("plot", path, "-o", tmp_path / "o"), "no samples to plot")


# --------------------------------------------------------------------------- drives and joint reactions


@pytest.fixture(scope="module")
def driven_file(tmp_path_factory):
    """Driven dynamics of the slider-crank (configs/slider_crank_dynamic.yaml), 0.3 s."""
    return simulated_file(tmp_path_factory, "slider_crank_dynamic.yaml", "driven.h5", "simulation.t_end=0.3")


def test_drive_and_reactions_figures_plot_the_recorded_values(driven_file):
    (ax,) = build(driven_file, "drive").axes
    np.testing.assert_array_equal(data_lines(ax)[0].get_ydata(), read(driven_file, "forces/drive")[:, 0])
    assert ax.get_ylabel() == "drive torque on q_crank [N m]"
    axes = build(driven_file, "reactions").axes
    assert len(axes) == 2 * 4  # the cut pin C, then the tree joints crank, B, slide
    force, torque = axes[:2]
    f = read(driven_file, "reactions/C/force_global")
    lines = data_lines(force)
    assert len(lines) == 2  # F_z is zero throughout in the plane: left out
    np.testing.assert_array_equal(lines[0].get_ydata(), f[:, 0])
    np.testing.assert_array_equal(lines[1].get_ydata(), f[:, 1])
    assert force.get_ylabel() == "joint C force [N]" and torque.get_ylabel() == "joint C torque [N m]"


def test_drive_and_reactions_figures_are_skipped_with_the_reason(qr_file):
    _, skipped, _ = figures(qr_file)
    assert "no drives" in skipped["drive"] and "no joint reactions" in skipped["reactions"]


def test_series_of_one_method_under_several_integrators_look_different():
    from csim.plot.style import METHOD_COLORS, method_styles

    methods = ["none", "projection", "projection:Tsit5", "projection:Vern7", "ggl:Radau"]
    styles = method_styles(methods)
    assert len(set(styles.values())) == len(methods)
    assert styles["projection"] == (METHOD_COLORS["projection"], "D") and styles["projection:Vern7"][1] == "*"
    assert styles["ggl:Radau"][0] == METHOD_COLORS["ggl"]  # alone of its method: the method's colour
