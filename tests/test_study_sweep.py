"""Sweeps end to end: rows against single runs, failure reasons, interruption and --resume,
Dask equality with the local run, the command line, and the stability-map figures' data."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import CONFIGS, qr_case
from typer.testing import CliRunner

from csim.cli import app
from csim.physics import status as st
from csim.pipeline import run_case
from csim.solver.failures import failure_message
from csim.study import execute, failure_reason, make_plan, parse_variation, run_sweep
from csim.study.sweep_file import PENDING, read_sweep

#: Baumgarte under RK4 on the quick-return: w h = 400 * 2e-2 = 8 lies far outside RK4's stability interval
BASE = ("simulation.t_end=0.5", "stabilization.method=baumgarte", "simulation.integrator=RK4")
VARY = ("stabilization.w=20,400", "simulation.step=2e-3,2e-2")


def _plan(*vary, base=BASE):
    return make_plan(qr_case(*base), [parse_variation(v) for v in vary or VARY])


def _same_rows(a, b):
    assert a.status == b.status and a.reason == b.reason and a.message == b.message
    for name, column in a.columns.items():
        if name != "wall_time":
            np.testing.assert_array_equal(column, b.columns[name], err_msg=name)


@pytest.fixture(scope="module")
def grid_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("sweep") / "grid.h5"
    run_sweep(_plan(), path, jobs=1, reference=["simulation.step=1e-4"], keep=True)
    return path


def test_rows_equal_the_runs_made_one_at_a_time(grid_file):
    table = read_sweep(grid_file)
    assert table.n == 4 and table.attrs["complete"]
    for i, (w, h) in enumerate([(20, 2e-3), (20, 2e-2), (400, 2e-3), (400, 2e-2)]):
        assert (table.values["stabilization.w"][i], table.values["simulation.step"][i]) == (w, h)
        single = run_case(qr_case(*BASE, f"stabilization.w={w}", f"simulation.step={h}"))
        assert table.status[i] == single.status and table.message[i] == single.message
        assert table.columns["nfev"][i] == single.nfev
        np.testing.assert_allclose(table.columns["max_phi"][i], single.max_phi, rtol=1e-12)
    assert table.status[3] == "failed" and table.reason[3] in ("drift", "blow-up")  # w h = 8
    assert table.status[0] == "success" and table.columns["error"][0] < 1e-3  # w h = 0.04 against h = 1e-4


def test_kept_signals_are_the_runs_samples(grid_file):
    from csim.study.sweep_file import read_signals

    sig = read_signals(grid_file, 0)
    single = run_case(qr_case(*BASE, "stabilization.w=20", "simulation.step=2e-3"))
    np.testing.assert_array_equal(sig["t"], single.t)
    np.testing.assert_allclose(sig["q"], single.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(sig["energy_error"], single.energy_error, rtol=0, atol=1e-9)


@pytest.mark.parametrize("code, reason", [
    (st.NONFINITE_RHS, "blow-up"), (st.MAX_PHI, "drift"), (st.STEP_COLLAPSE, "step collapse"),
    (st.MAX_STEPS, "max steps"), (st.MAX_EVENTS, "chatter"), (st.SINGULAR_KKT, "singular"),
    (st.PROJ_SINGULAR, "singular"), (st.RK4_RESOLUTION, "step"), (st.STEP_TOO_SMALL, "step collapse"),
    (st.CHATTER, "chatter"),
])
def test_every_status_message_has_its_reason(code, reason):
    settings = qr_case().integration_settings()
    assert failure_reason("failed", failure_message(code, 1.0, 2.0, settings)) == reason
    assert failure_reason("success", "reached t_end = 5 s") == ""


def test_an_interrupted_sweep_keeps_its_finished_runs_and_resumes(tmp_path, monkeypatch, grid_file):
    path = tmp_path / "s.h5"
    real, calls = execute.run_chunk, []

    def interrupted_after_one(work, chunk):
        calls.append(len(chunk))
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(work, chunk)

    monkeypatch.setattr(execute, "run_chunk", interrupted_after_one)
    plan = _plan()
    sweep = run_sweep(plan, path, jobs=1, reference=["simulation.step=1e-4"])
    assert sweep.interrupted and 0 < sweep.done < 4
    stored = read_sweep(path)
    assert not stored.attrs["complete"] and stored.status.count(PENDING) == 4 - sweep.done
    monkeypatch.setattr(execute, "run_chunk", real)
    done = run_sweep(plan, path, jobs=1, resume=True)
    assert done.complete and not done.interrupted
    _same_rows(read_sweep(path), read_sweep(grid_file))


def test_resume_refuses_another_plan(tmp_path, grid_file):
    from csim.errors import CaseError

    with pytest.raises(CaseError, match="values differ"):
        run_sweep(_plan("stabilization.w=20,300", "simulation.step=2e-3,2e-2"), grid_file, jobs=1, resume=True)


def test_worker_processes_give_the_rows_of_this_process(tmp_path, grid_file):
    run_sweep(_plan(), tmp_path / "p.h5", jobs=2, reference=["simulation.step=1e-4"])
    _same_rows(read_sweep(tmp_path / "p.h5"), read_sweep(grid_file))


def test_a_dask_cluster_gives_the_rows_of_the_local_run(tmp_path, grid_file):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cl:
        run_sweep(_plan(), tmp_path / "d.h5", scheduler=cl.scheduler_address, reference=["simulation.step=1e-4"])
    _same_rows(read_sweep(tmp_path / "d.h5"), read_sweep(grid_file))


def test_the_command_line_runs_a_sweep_and_rejects_bad_options(tmp_path):
    out = tmp_path / "cli.h5"
    args = ["sweep", str(CONFIGS / "quick_return.yaml"), *sum((["--set", b] for b in BASE), []),
            "-v", "stabilization.w=20,400", "-v", "simulation.step=2e-3", "-j", "1", "-o", str(out)]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    assert "2 runs" in res.output and read_sweep(out).n == 2
    bad = CliRunner().invoke(app, [*args[:-2], "-v", "stabilization.dd=1", "-o", str(tmp_path / "x.h5")])
    assert bad.exit_code == 2 and "stabilization.dd" in bad.output and not (tmp_path / "x.h5").exists()


def test_map_figures_draw_the_files_data(grid_file):
    from csim.plot.sweep_figures import OUTCOMES, metric_figure, outcome, outcome_figure

    table = read_sweep(grid_file)
    fig = outcome_figure(table)
    mesh = next(c for c in fig.axes[0].collections if c.get_gid() == "outcome")
    present = [k for k in OUTCOMES if any(outcome(table, i) == k for i in range(table.n))]
    codes = np.array([present.index(outcome(table, i)) for i in range(table.n)], float).reshape(2, 2).T  # (step, w)
    np.testing.assert_array_equal(np.asarray(mesh.get_array()).reshape(2, 2), codes)
    fig = metric_figure(table, "max_phi")
    mesh = next(c for c in fig.axes[0].collections if c.get_gid() == "max_phi")
    ok = np.array([s == "success" for s in table.status])
    expected = np.where(ok, table.columns["max_phi"], np.nan).reshape(2, 2).T
    drawn = np.ma.filled(np.ma.asarray(mesh.get_array(), dtype=float), np.nan).reshape(2, 2)
    np.testing.assert_array_equal(drawn, expected)


def test_curves_of_one_key_draw_the_files_data(tmp_path):
    from csim.plot.sweep_figures import curves_figure

    path = tmp_path / "one.h5"
    run_sweep(_plan("stabilization.w=5,20,80", base=(*BASE, "simulation.step=2e-3")), path, jobs=1)
    table = read_sweep(path)
    fig = curves_figure(table)
    line = next(ln for ln in fig.axes[0].lines if ln.get_gid() == "max_phi|")
    np.testing.assert_array_equal(line.get_xdata(), [5, 20, 80])
    np.testing.assert_array_equal(line.get_ydata(), table.columns["max_phi"])


def test_a_new_sweep_does_not_inherit_the_signals_of_a_file_it_replaces(tmp_path):
    from csim.study.sweep_file import read_signals

    path = tmp_path / "s.h5"
    run_sweep(_plan("stabilization.w=10,20,30", base=(*BASE, "simulation.step=2e-3")), path, jobs=1, keep=True)
    assert read_signals(path, 2)
    run_sweep(_plan("stabilization.w=10,20", base=(*BASE, "simulation.step=2e-3")), path, jobs=1)
    assert read_signals(path, 0) == {} and read_signals(path, 2) == {}


def test_runs_of_a_dead_worker_stay_pending_and_the_command_says_so(tmp_path, monkeypatch):
    import concurrent.futures as cf
    from concurrent.futures.process import BrokenProcessPool

    future = cf.Future()
    future.set_exception(BrokenProcessPool("a child process terminated abruptly"))
    assert execute._chunk_result(future)[0] == [] and "BrokenProcessPool" in execute._chunk_result(future)[1]

    real = execute.run_local

    def one_worker_dies(work, parts, jobs, deliver):  # the first chunk comes back, the rest is lost
        flat = [run for part in parts for run in part]
        deliver(execute.run_chunk(work, flat[:1]))
        return execute.Outcome(lost="a worker failed (BrokenProcessPool: a child process terminated abruptly)")

    out = tmp_path / "lost.h5"
    args = ["sweep", str(CONFIGS / "quick_return.yaml"), *sum((["--set", b] for b in BASE), []),
            "-v", "stabilization.w=20,40,80", "--set", "simulation.step=2e-3", "-o", str(out)]
    monkeypatch.setattr(execute, "run_local", one_worker_dies)
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 1 and "pending" in res.stderr and "BrokenProcessPool" in res.stderr
    assert read_sweep(out).status.count(PENDING) == 2 and not read_sweep(out).attrs["complete"]
    monkeypatch.setattr(execute, "run_local", real)
    res = CliRunner().invoke(app, [*args, "--resume", "-j", "1"])
    assert res.exit_code == 0, res.output
    assert PENDING not in read_sweep(out).status


def test_a_random_design_resumes_with_the_seed_in_its_file(tmp_path, monkeypatch):
    out = tmp_path / "r.h5"
    args = ["sweep", str(CONFIGS / "quick_return.yaml"), *sum((["--set", b] for b in BASE), []),
            "--set", "simulation.step=2e-3", "-v", "stabilization.w=log:5:50", "--sample", "lhs", "-n", "3",
            "-j", "1", "-o", str(out)]
    real, calls = execute.run_chunk, []

    def interrupted_after_one(work, chunk):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(work, chunk)

    monkeypatch.setattr(execute, "run_chunk", interrupted_after_one)
    assert CliRunner().invoke(app, args).exit_code == 130
    monkeypatch.setattr(execute, "run_chunk", real)
    res = CliRunner().invoke(app, [*args, "--resume"])
    assert res.exit_code == 0, res.output
    table = read_sweep(out)
    assert PENDING not in table.status and len(set(table.values["stabilization.w"])) == 3


def test_a_sweep_may_vary_the_mechanism(tmp_path):
    case = tmp_path / "min.yaml"
    case.write_text("mechanism: {name: pendulum}\nsimulation: {t_end: 0.2}\n")
    out = tmp_path / "m.h5"
    res = CliRunner().invoke(app, ["sweep", str(case), "-v", "mechanism.name=pendulum,quick_return", "-j", "1",
                                   "-o", str(out)])
    assert res.exit_code == 0, res.output
    table = read_sweep(out)
    assert table.status == ["success", "success"] and table.values["mechanism.name"] == ["pendulum", "quick_return"]


@pytest.mark.parametrize("extra, words", [
    (["-r", "output.dt=0.01"], "--reference output.dt=0.01: the reference run keeps the sweep's output times"),
    (["--seed", "3"], "--seed: only with --sample random"),
    (["--sample", "random", "-n", "2", "--seed", "-5"], "--seed: got -5"),
    (["-j", "2", "--scheduler", "tcp://127.0.0.1:1"], "--jobs: the Dask cluster"),
])
def test_contradictory_options_exit_2_naming_the_option(tmp_path, extra, words):
    args = ["sweep", str(CONFIGS / "quick_return.yaml"), "-v", "stabilization.w=lin:1:2:2", *extra,
            "-o", str(tmp_path / "x.h5")]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 2 and words in res.stderr, res.output


def test_an_unreachable_scheduler_is_bad_input(tmp_path):
    pytest.importorskip("distributed")
    res = CliRunner().invoke(app, ["sweep", str(CONFIGS / "quick_return.yaml"), "-v", "stabilization.w=1,2",
                                   "--scheduler", "tcp://127.0.0.1:9", "-o", str(tmp_path / "x.h5")])
    assert res.exit_code == 2 and "--scheduler tcp://127.0.0.1:9: cannot reach" in res.stderr


def test_maps_put_each_run_in_its_cell_on_a_grid_that_is_not_square(tmp_path):
    from csim.plot.sweep_figures import metric_figure

    path = tmp_path / "g.h5"
    run_sweep(_plan("stabilization.w=10,20,40", "simulation.step=1e-3,2e-3"), path, jobs=1)
    table = read_sweep(path)
    fig = metric_figure(table, "max_phi")
    mesh = next(c for c in fig.axes[0].collections if c.get_gid() == "max_phi")
    corners = mesh.get_coordinates()  # (ny + 1, nx + 1, 2): x along the columns, y along the rows
    assert corners.shape == (3, 4, 2)
    centres_x = np.sqrt(corners[0, :-1, 0] * corners[0, 1:, 0])  # log-spaced w: geometric centres
    np.testing.assert_allclose(centres_x, [10, 20, 40])
    drawn = np.ma.filled(np.ma.asarray(mesh.get_array(), dtype=float), np.nan).reshape(2, 3)
    for i in range(table.n):
        col = [10, 20, 40].index(table.values["stabilization.w"][i])
        row = [1e-3, 2e-3].index(table.values["simulation.step"][i])
        assert drawn[row, col] == table.columns["max_phi"][i]


def test_curves_draw_one_line_per_value_of_the_other_key(tmp_path):
    from csim.plot.sweep_figures import curves_figure

    path = tmp_path / "c.h5"
    run_sweep(_plan("stabilization.w=5,20,80", "stabilization.method=baumgarte,none",
                    base=(*BASE, "simulation.step=2e-3")), path, jobs=1)
    table = read_sweep(path)
    lines = {ln.get_gid(): ln for ln in curve_lines(curves_figure(table))}
    for method in ("baumgarte", "none"):
        line = lines[f"max_phi|stabilization.method = {method}"]
        rows = [i for i in range(table.n) if table.values["stabilization.method"][i] == method]
        np.testing.assert_array_equal(line.get_xdata(), [table.values["stabilization.w"][i] for i in rows])
        np.testing.assert_array_equal(line.get_ydata(), table.columns["max_phi"][rows])


def curve_lines(fig):
    return [ln for ln in fig.axes[0].lines if ln.get_gid()]


def _synthetic_table(keys_values: dict, case: str, statuses=None, value_units=None):
    """A grid sweep table built by hand (no runs): every combination of the keys' values."""
    import itertools

    from csim.study.metrics import COLUMNS
    from csim.study.sweep_file import SweepTable

    combos = list(itertools.product(*keys_values.values()))
    n = len(combos)
    values = {k: [c[j] for c in combos] for j, k in enumerate(keys_values)}
    status = statuses or ["success"] * n
    rng = np.random.default_rng(1)
    columns = {c.name: rng.uniform(1e-6, 1e-3, n) for c in COLUMNS}
    return SweepTable(keys=list(keys_values), values=values, numeric={k: True for k in keys_values},
                      status=status, reason=["" if s == "success" else "drift" for s in status], message=[""] * n,
                      columns=columns, units={c.name: "m" for c in COLUMNS}, attrs={"case": case},
                      value_units=value_units or {})


def test_the_baumgarte_map_under_rk4_draws_the_bound_and_legend_swatches():
    from matplotlib.lines import Line2D

    from csim.plot.sweep_figures import RK4_BOUND, outcome_figure

    w, h = [10.0, 100.0, 400.0], [1e-3, 5e-3, 2e-2]
    status = ["drift" if wi * hi > RK4_BOUND else "success" for wi in w for hi in h]
    case = "stabilization: {method: baumgarte}\nsimulation: {integrator: RK4}\n"
    table = _synthetic_table({"stabilization.w": w, "simulation.step": h}, case, status,
                             {"stabilization.w": "1/s", "simulation.step": "s"})
    ax = outcome_figure(table).axes[0]
    bound = [ln for ln in ax.get_lines() if ln.get_label().startswith("RK4 bound")]
    assert len(bound) == 1
    x, y = bound[0].get_data()
    np.testing.assert_allclose(x * y, RK4_BOUND)
    legend = ax.get_legend()
    swatches = [h for h in legend.legend_handles if isinstance(h, Line2D) and h.get_marker() not in ("None", "")]
    assert {t.get_text().split(" (")[0] for t in legend.get_texts()} >= {"success", "drift"}
    assert all(h.get_markerfacecolor() not in ("none", "None") for h in swatches) and len(swatches) == 2
    assert ax.get_xlabel() == "stabilization.w [1/s]" and ax.get_ylabel() == "simulation.step [s]"
    # the same map under DOP853 has no RK4 bound
    other = _synthetic_table({"stabilization.w": w, "simulation.step": h},
                             "stabilization: {method: baumgarte}\nsimulation: {integrator: DOP853}\n")
    assert not [ln for ln in outcome_figure(other).axes[0].get_lines() if ln.get_label().startswith("RK4")]


def test_many_curves_are_a_colour_scale_with_a_colour_bar():
    from csim.plot.sweep_figures import MAX_LEGEND, curves_figure

    torques = list(np.linspace(1e5, 2e5, MAX_LEGEND + 4))
    table = _synthetic_table({"simulation.rtol": [1e-8, 1e-6, 1e-4], "loads.torque": torques}, "",
                             value_units={"simulation.rtol": "1", "loads.torque": "N m"})
    fig = curves_figure(table)
    bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(bars) == 1 and bars[0].get_ylabel() == "loads.torque [N m]"
    panels = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert all(ax.get_legend() is None for ax in panels) and not fig.legends
    assert panels[-1].get_xlabel() == "simulation.rtol [-]"
    assert all(ax.get_ylabel().endswith("[m]") or ax.get_ylabel().endswith("[-]") for ax in panels)


def test_ctrl_c_inside_a_run_marks_that_run_interrupted_and_the_command_names_it(tmp_path, monkeypatch,
                                                                                 python_sigint):
    """Ctrl-C while the second run is under way: the first is kept, the second is pending with
    the reason ``interrupted`` (named on stderr), the third pending; --resume runs both."""
    import signal

    import csim.pipeline as pipeline

    real, calls = pipeline.run_case, []

    def ctrl_c_in_the_second(case):
        calls.append(1)
        if len(calls) == 2:
            signal.raise_signal(signal.SIGINT)  # what the terminal does on Ctrl-C
        return real(case)

    out = tmp_path / "i.h5"
    args = ["sweep", str(CONFIGS / "pendulum.yaml"), "--set", "simulation.backend=python", "--set",
            "simulation.t_end=0.2", "-v", "stabilization.w=5,10,20", "-j", "1", "-o", str(out)]
    monkeypatch.setattr(pipeline, "run_case", ctrl_c_in_the_second)
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 130, res.output
    assert "1 of 3 runs finished" in res.stderr and "1 stopped while running (run 1: status pending, reason " \
        "interrupted), 1 not started" in res.stderr, res.stderr
    table = read_sweep(out)
    assert table.status == ["success", PENDING, PENDING] and table.reason == ["", "interrupted", ""]
    assert "stopped by Ctrl-C while it ran" in table.message[1] and not table.attrs["complete"]
    monkeypatch.setattr(pipeline, "run_case", real)
    res = CliRunner().invoke(app, [*args, "--resume"])
    assert res.exit_code == 0, res.output
    assert read_sweep(out).status == ["success"] * 3 and read_sweep(out).reason == [""] * 3


def test_ctrl_c_of_worker_processes_keeps_the_runs_each_chunk_finished(tmp_path):
    """Two workers: one runs a 30 s pendulum, the other two short runs, then a long one, then
    another short one. Ctrl-C when the first chunk comes back: the other worker's chunk
    returns its two finished runs and its long run stopped (not the fourth), within the grace."""
    import time

    from csim.case import load_case, read_case_file
    from csim.pipeline import numeric_model

    path = CONFIGS / "pendulum.yaml"
    numeric_model(load_case(path))  # derived once here; the workers load it from the cache
    work = execute.Work(data=read_case_file(path, ["simulation.backend=python"]), source=str(path),
                        keys=("simulation.t_end",))
    parts = [[(0, (30.0,))], [(1, (0.01,)), (2, (0.01,)), (3, (1000.0,)), (4, (0.01,))]]
    delivered: dict[int, dict] = {}
    stopped_at = []

    def deliver(done):
        delivered.update({i: row for i, row, _ in done})
        if 0 in delivered and not stopped_at:
            stopped_at.append(time.monotonic())
            raise KeyboardInterrupt  # Ctrl-C in the parent, as the first chunk comes back

    outcome = execute.run_local(work, parts, 2, deliver)
    assert outcome.interrupted and time.monotonic() - stopped_at[0] < 30  # the 1000 s run did not go on
    assert delivered[0]["status"] == delivered[1]["status"] == delivered[2]["status"] == "success"
    assert delivered[3]["status"] == PENDING and delivered[3]["reason"] == execute.INTERRUPTED
    assert "interrupted by the user after t = " in delivered[3]["message"]
    assert 4 not in delivered


def test_a_run_asked_to_stop_before_it_begins_ends_at_once(monkeypatch):
    """The stop signal may come while a worker validates its next case, after it checked for
    one: the run then ends on entry instead of running to its end (whose chunk the parent
    would terminate after the grace, losing the runs it had finished)."""
    from csim import parallel

    monkeypatch.setitem(parallel._IN_RUN, "stop", True)
    ran = []
    with pytest.raises(KeyboardInterrupt), parallel.stoppable_run():
        ran.append(1)
    assert not ran and parallel._IN_RUN["active"] is False


def test_ctrl_c_on_a_dask_cluster_keeps_the_runs_the_chunks_under_way_finished():
    """Ctrl-C (here: raised as the first chunk is delivered) sets the sweep's stop Event: the
    long chunk running beside it stops between two runs and brings back those it finished,
    far before its last run."""
    distributed = pytest.importorskip("distributed")
    plan = _plan("stabilization.w=lin:10:20:400", "simulation.step=2e-3")
    work = execute.Work(data=plan.data, source="test", keys=tuple(plan.keys))
    short, long = [(0, plan.rows[0])], [(i, plan.rows[i]) for i in range(1, len(plan.rows))]
    delivered: list[int] = []

    def deliver(done):
        delivered.extend(i for i, _, _ in done)
        if delivered == [0]:
            raise KeyboardInterrupt

    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cl, \
            distributed.Client(cl) as client:
        outcome = execute.run_dask(work, [short, long], client, deliver, grace=30.0)
    assert outcome.interrupted and delivered[0] == 0
    rest = delivered[1:]
    assert rest == list(range(1, 1 + len(rest))) and 1 <= len(rest) < len(long) // 2, len(rest)
