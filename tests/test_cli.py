"""End-to-end tests of ``csim run``: exit codes, messages, and the HDF5 result file."""
from __future__ import annotations

import os
import re
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from csim import __version__
from csim.case import load_case
from csim.cli import app
from csim.mechanisms import MECHANISMS
from csim.solver.integrators import INTEGRATORS

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "quick_return.yaml"
SHORT = ["--set", "simulation.t_end=0.2"]

MINIMAL = "mechanism:\n  name: quick_return\n"

DATASETS = ["t", "q", "qd", "qdd", "lambda", "phi", "phi_dot", "energy/kinetic", "energy/potential",
            "energy/work", "forces/loads"]
ATTRIBUTES = ["csim_version", "case", "coordinate_names", "status", "message", "failure", "backend", "backend_reason",
              "wall_time", "nfev"]


def invoke(*args: str):
    """Run the CLI in-process; stdout and stderr stay apart (and are both in ``output``)."""
    return CliRunner().invoke(app, [str(a) for a in args])


def assert_clean_exit(result, code: int) -> None:
    """Exit ``code`` through csim's own handling: no exception escaped, no traceback printed."""
    assert result.exit_code == code, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exc_info
    assert "Traceback" not in result.output


#: status lines of slow steps, where stderr is no terminal (csim.progress.status)
STATUS_LINES = ("csim: simulating ", "csim: loading the compiled kernels ", "csim: deriving the equations ",
                "csim: generating the compiled module ")


def errors(result) -> str:
    """stderr without the status lines of slow steps ("csim: simulating CASE ..." where stderr is no terminal)."""
    return "".join(line for line in result.stderr.splitlines(keepends=True) if not line.startswith(STATUS_LINES))


def text_attr(fh, name: str) -> str:
    value = fh.attrs[name]
    return value.decode() if isinstance(value, bytes) else str(value)


# --------------------------------------------------------------------------- a good run


@pytest.fixture
def good_run(tmp_path):
    case = tmp_path / "qr.yaml"
    case.write_text(CONFIG.read_text())
    out = tmp_path / "qr.h5"
    result = invoke("run", case, "-o", out, *SHORT)
    return case, out, result


def test_good_run_exits_0_and_prints_the_summary(good_run):
    case, out, result = good_run
    assert_clean_exit(result, 0)
    stdout = result.stdout
    for label in ("case:", "status:            success", "final time:        0.2 s", "final q:", "max |Phi|:",
                  "max |Phi_q qd|:", "energy balance:", "events:", "wall time:", "RHS evaluations:", "result:"):
        assert label in stdout, label
    assert str(case) in stdout and str(out) in stdout
    assert "error" not in result.output


def test_good_run_writes_a_complete_result_file(good_run):
    case, out, result = good_run
    assert_clean_exit(result, 0)
    assert out.is_file()
    assert [p.name for p in out.parent.iterdir() if p.name.endswith(".tmp")] == []  # no temporary left over
    with h5py.File(out, "r") as fh:
        for name in DATASETS:
            assert name in fh, name
            assert isinstance(fh[name], h5py.Dataset)
        for name in ATTRIBUTES:
            assert name in fh.attrs, name
        t = fh["t"][()]
        n = t.size
        assert n > 10 and t[0] == 0.0 and t[-1] == pytest.approx(0.2)
        assert np.all(np.diff(t) > 0)
        assert fh["q"].shape == fh["qd"].shape == fh["qdd"].shape == (n, 3)
        assert fh["lambda"].shape == fh["phi"].shape == fh["phi_dot"].shape == (n, 2)
        assert fh["energy/kinetic"].shape == fh["energy/potential"].shape == (n,)
        assert fh["energy/work"].shape == fh["forces/loads"].shape == (n, 2)
        assert np.all(np.isfinite(fh["q"][()]))
        assert np.max(np.abs(fh["phi"][()])) < 1e-6
        assert text_attr(fh, "csim_version") == __version__
        assert text_attr(fh, "status") == "success"
        assert "t_end" in text_attr(fh, "message")
        assert [x.decode() if isinstance(x, bytes) else x for x in fh.attrs["coordinate_names"]] == ["q1", "q2", "q3"]
        assert float(fh.attrs["wall_time"]) > 0
        assert int(fh.attrs["nfev"]) > 0
        assert "event_times" not in fh.attrs  # a dataset: an attribute cannot hold 100,000 of them
        events = fh["events/times"][()]
        assert fh["events/labels"].shape == events.shape
        assert events.ndim == 1 and np.all((events > 0) & (events < 0.2))
        case_yaml = text_attr(fh, "case")
    expected = load_case(case, ["simulation.t_end=0.2"]).data
    assert yaml.safe_load(case_yaml) == expected
    assert expected["simulation"]["t_end"] == 0.2


def test_quiet_run_prints_nothing(tmp_path):
    out = tmp_path / "qr.h5"
    result = invoke("run", CONFIG, "-o", out, "-q", *SHORT)
    assert_clean_exit(result, 0)
    assert result.output == ""
    assert out.is_file()


def test_default_output_is_results_slash_case_stem_and_the_summary_says_so(tmp_path, monkeypatch):
    case = tmp_path / "my_case.yaml"
    case.write_text(MINIMAL)
    monkeypatch.chdir(tmp_path)
    result = invoke("run", case, *SHORT)
    assert_clean_exit(result, 0)
    assert (tmp_path / "results" / "my_case.h5").is_file()
    line = [x for x in result.stdout.splitlines() if x.startswith("result:")][0]
    default = Path("results") / "my_case.h5"
    assert line == f"result:            {default} (the default for this case file; -o names another)"
    again = invoke("run", case, *SHORT)
    assert "replacing the file there" in again.stdout
    named = invoke("run", case, "-o", tmp_path / "named.h5", *SHORT)
    assert f"result:            {tmp_path / 'named.h5'}\n" in named.stdout


def test_output_in_a_new_nested_directory_is_created(tmp_path):
    out = tmp_path / "new" / "deeper" / "still" / "qr.h5"
    result = invoke("run", CONFIG, "-o", out, *SHORT)
    assert_clean_exit(result, 0)
    assert out.is_file()
    with h5py.File(out, "r") as fh:
        assert text_attr(fh, "status") == "success"


@pytest.mark.parametrize("where", ["parent_is_a_file", "output_is_a_directory"])
def test_unwritable_output_is_a_clean_error(tmp_path, where):
    if where == "parent_is_a_file":
        (tmp_path / "blocker").write_text("not a directory")
        out = tmp_path / "blocker" / "qr.h5"
    else:
        out = tmp_path / "adir"
        out.mkdir()
    result = invoke("run", CONFIG, "-o", out, *SHORT)
    assert_clean_exit(result, 2)
    assert f"--output {out}: cannot write" in result.stderr
    assert "status:" not in result.stdout  # refused before the run, not after it
    assert [p.name for p in tmp_path.rglob("*.tmp")] == []


def test_output_may_not_overwrite_the_case_file(tmp_path):
    case = tmp_path / "case.yaml"
    case.write_text(Path(CONFIG).read_text())
    result = invoke("run", case, "-o", case, *SHORT)
    assert_clean_exit(result, 2)
    assert "that is an input file" in result.stderr
    assert case.read_text() == Path(CONFIG).read_text()


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root may write anywhere")
def test_output_in_a_read_only_directory_is_a_clean_error(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        result = invoke("run", CONFIG, "-o", locked / "sub" / "qr.h5", *SHORT)
    finally:
        locked.chmod(0o700)
    assert_clean_exit(result, 2)
    assert "csim: error: cannot write" in result.stderr


# --------------------------------------------------------------------------- bad input: exit 2


# id, case-file text (None: no file), extra arguments, fragments the message must contain
BAD_CASES = [
    ("missing_file", None, [], ["no such case file"]),
    ("yaml_syntax", MINIMAL + "simulation: {t_end: 1\n", [], ["not valid YAML", "line 4"]),
    ("duplicate_key", MINIMAL + "simulation: {t_end: 1, t_end: 2}\n", [], ["duplicate key 't_end'"]),
    ("impossible_date", MINIMAL + "simulation: {t_end: 2024-02-30}\n", [], ["not valid YAML", "day is out of range"]),
    ("top_level_list", "- mechanism\n- simulation\n", [], ["['mechanism', 'simulation'] (list)", "top level",
                                                            "expected a mapping"]),
    ("unknown_top_level_key", MINIMAL + "simulaton:\n  t_end: 1\n", [],
     ["simulaton: unknown key", "did you mean 'simulation'?"]),
    ("unknown_mechanism", "mechanism:\n  name: slider_crank\n", [],
     ["mechanism.name", "'slider_crank'", f"one of {', '.join(sorted(MECHANISMS))}"]),
    ("missing_mechanism_name", "simulation:\n  t_end: 1\n", [], ["mechanism.name: missing"]),
    ("negative_mass", MINIMAL + "  parameters: {m1: -4}\n", [], ["mechanism.parameters.m1", "-4.0", "> 0"]),
    ("zero_length", MINIMAL + "  parameters: {l1: 0}\n", [], ["mechanism.parameters.l1", "got 0.0", "> 0"]),
    ("unknown_parameter", MINIMAL + "  parameters: {l7: 1.0}\n", [],
     ["mechanism.parameters.l7: unknown key", "l1, l2, l3"]),
    ("t_end_zero", MINIMAL + "simulation: {t_end: 0}\n", [], ["simulation.t_end", "got 0.0", "> 0"]),
    ("t_end_negative", MINIMAL + "simulation: {t_end: -3}\n", [], ["simulation.t_end", "-3.0", "> 0"]),
    ("t_end_string", MINIMAL + 'simulation: {t_end: "ten"}\n', [],
     ["simulation.t_end", "'ten' (string)", "expected a number"]),
    ("unknown_integrator", MINIMAL + "simulation: {integrator: Euler}\n", [],
     ["simulation.integrator", "'Euler'", f"one of {', '.join(INTEGRATORS)}"]),
    ("negative_rtol", MINIMAL + "simulation: {rtol: -1e-6}\n", [], ["simulation.rtol", "-1e-06", "<= 1"]),
    ("unknown_coordinate", MINIMAL + "initial: {q: {theta: 1.0}}\n", [],
     ["initial.q.theta", "not a coordinate of quick_return", "q1, q2, q3"]),
    ("two_coordinates_for_1_dof", MINIMAL + "initial: {q: {q1: 3.0, q2: 2.0}}\n", [],
     ["initial.q", "2 coordinate(s) (q1, q2)", "exactly 1"]),
    ("unknown_load", MINIMAL + "loads: {drive_torque: 5.0}\n", [],
     ["loads.drive_torque: unknown key", "torque, cutting_force"]),
    ("window_lo_ge_hi", MINIMAL + "loads:\n  cutting_force: {magnitude: 1.0, window: [1.2, -4.0]}\n", [],
     ["loads.cutting_force.window", "[1.2, -4.0]", "lo < hi"]),
    ("bad_velocity_condition", MINIMAL + "loads:\n  cutting_force: {magnitude: 1.0, velocity: backwards}\n", [],
     ["loads.cutting_force.velocity", "'backwards'", "one of any, positive, negative"]),
    ("output_dt_zero", MINIMAL + "output: {dt: 0}\n", [], ["output.dt", "got 0.0", "> 0"]),
    ("set_without_equals", MINIMAL, ["--set", "simulation.t_end"], ["--set 'simulation.t_end'", "key=value"]),
    ("set_unknown_key", MINIMAL, ["--set", "simulation.tend=3"],
     ["--set simulation.tend: unknown key", "did you mean 'simulation.t_end'?"]),
    ("set_bad_value", MINIMAL, ["--set", "simulation.integrator=rk4"],
     ["simulation.integrator", "'rk4'", "did you mean 'RK4'?"]),
    ("set_into_a_scalar", MINIMAL + "simulation: 5\n", ["--set", "simulation.t_end=1"],
     ["--set simulation.t_end", "5 (integer)", "expected a mapping"]),
    ("output_dt_too_fine", MINIMAL + "simulation: {t_end: 5}\noutput: {dt: 1.0e-10}\n", [],
     ["output.dt", "1e-10", "at most 1e+07 output samples"]),
    ("rk4_step_too_fine", MINIMAL + "simulation: {t_end: 5, integrator: RK4, step: 1.0e-300}\n", [],
     ["simulation.step", "1e-300", "fixed steps"]),
]


@pytest.mark.parametrize("text, extra, fragments", [c[1:] for c in BAD_CASES], ids=[c[0] for c in BAD_CASES])
def test_bad_input_exits_2_with_a_clear_message(tmp_path, text, extra, fragments):
    case = tmp_path / "case.yaml"
    if text is not None:
        case.write_text(text)
    out = tmp_path / "out.h5"
    short = [] if "t_end" in (text or "") + " ".join(extra) else SHORT  # should a bad case run, keep it short
    result = invoke("run", case, "-o", out, *short, *extra)
    assert_clean_exit(result, 2)
    assert result.stderr.startswith("csim: error:")
    assert result.stdout == ""  # no summary, nothing half-done
    for fragment in fragments:
        assert fragment in result.stderr, (fragment, result.stderr)
    if text is None:
        assert str(case) in result.stderr
    assert not out.exists()


def test_all_problems_are_listed_in_one_go(tmp_path):
    case = tmp_path / "case.yaml"
    case.write_text(MINIMAL + "  parameters: {m1: -4}\nsimulation: {t_end: -1, integrator: Euler}\n")
    result = invoke("run", case, "-o", tmp_path / "out.h5")
    assert_clean_exit(result, 2)
    lines = result.stderr.splitlines()
    assert lines[0] == "csim: error: 3 problem(s):"
    assert len(lines) == 4
    assert {line.split(":")[0].strip().split(" [")[0] for line in lines[1:]} == {
        "mechanism.parameters.m1", "simulation.t_end", "simulation.integrator"}


def test_bad_command_line_usage_exits_2(tmp_path):
    assert_clean_exit(invoke("run"), 2)
    result = invoke("run", CONFIG, "--no-such-option")
    assert_clean_exit(result, 2)
    assert "--no-such-option" in result.output


# --------------------------------------------------------------------------- a failed run: exit 1


def test_mechanism_that_cannot_assemble_exits_2_and_keeps_a_marked_result_file(tmp_path):
    case = tmp_path / "far_guide.yaml"
    case.write_text(CONFIG.read_text())
    out = tmp_path / "far_guide.h5"
    result = invoke("run", case, "-o", out, *SHORT, "--set", "mechanism.parameters.h2=100")
    assert_clean_exit(result, 2)  # bad input, as for a link-coupling mechanism that cannot be assembled
    assert "status:            failed" in result.stdout
    err = errors(result)
    assert err.startswith("csim: error: the mechanism cannot be assembled at its initial values:")
    assert "Newton-Raphson did not converge" in err
    assert "residuals" in err and "Phi[0] =" in err and "Phi[1] =" in err
    assert f"result file with status failed: {out}" in err
    assert out.is_file()
    with h5py.File(out, "r") as fh:
        assert text_attr(fh, "status") == "failed"
        assert text_attr(fh, "failure") == "assembly"
        assert "Newton-Raphson did not converge" in text_attr(fh, "message")
        for name in DATASETS:
            assert name in fh, name
        assert fh["t"].shape == (0,)
        assert yaml.safe_load(text_attr(fh, "case"))["mechanism"]["parameters"]["h2"] == 100.0


def test_link_coupling_mechanism_that_cannot_assemble_exits_2(tmp_path):
    out = tmp_path / "fourbar.h5"
    result = invoke("run", CONFIG.parent / "fourbar.yaml", "-o", out, "--set", "mechanism.parameters.b=10")
    assert_clean_exit(result, 2)
    assert result.stderr.startswith("csim: error:")
    assert "cannot be assembled at the given values" in result.stderr and "residuals" in result.stderr
    assert not out.exists()  # rejected with the case, before a run


def test_a_run_that_fails_exits_1_and_is_not_marked_as_bad_input(tmp_path):
    out = tmp_path / "blow_up.h5"
    result = invoke("run", CONFIG.parent / "pendulum.yaml", "-o", out, "--set", "simulation.t_end=0.5",
                    "--set", "simulation.max_steps=3")
    assert_clean_exit(result, 1)
    assert errors(result).startswith("csim: simulation failed:") and "max_steps" in result.stderr
    with h5py.File(out, "r") as fh:
        assert text_attr(fh, "status") == "failed" and text_attr(fh, "failure") == "max steps"


# --------------------------------------------------------------------------- help and version


def test_help_mentions_an_example():
    result = invoke("--help")
    assert_clean_exit(result, 0)
    assert "run" in result.stdout and "Example" in result.stdout
    result = invoke("run", "--help")
    assert_clean_exit(result, 0)
    assert "Example" in result.stdout and "configs/quick_return.yaml" in result.stdout
    for option in ("--output", "--set", "--quiet"):
        assert option in result.stdout


def test_version():
    result = invoke("--version")
    assert_clean_exit(result, 0)
    assert result.stdout.strip() == f"csim {__version__}"


def test_help_lists_flags_without_a_value_type():
    for command in ([], ["run"], ["compare"], ["batch"], ["plot"], ["animate"], ["describe"]):
        result = invoke(*command, "--help")
        assert_clean_exit(result, 0)
        assert "<bool>" not in result.stdout, command
        assert "--help" in result.stdout
    result = invoke("run", "--help")
    assert "--quiet" in result.stdout and "Print nothing but errors" in result.stdout
    assert "130" in result.stdout  # the exit codes, interruption included


#: text in square brackets in a help string or docstring, escaped (``\\[dask]``) or not
BRACKETED = re.compile(r"\\?\[([^\[\]]*)\]")
#: what the rich help adds around and inside its text: whitespace and the panels' box drawing
LAYOUT = re.compile(r"[\s\u2500-\u257f]+")


def _help_texts(command) -> list[str]:
    """A command's docstring and the help strings of its options and arguments, as written."""
    return [text for text in (command.help, *(getattr(p, "help", None) for p in command.params)) if text]


def test_bracketed_text_in_help_strings_is_shown_not_taken_for_markup():
    """typer's rich help reads [name] as a markup tag and drops it (pip install
    'csim-multibody[dask]' showed as 'csim-multibody'): every bracketed text of a command's
    help strings and docstring must appear in its --help, escaped as \\[ in the source."""
    import typer.main

    group = typer.main.get_command(app)
    commands = [([], group), *(([name], command) for name, command in group.commands.items())]
    assert len(commands) > 5
    checked = []
    for args, command in commands:
        result = CliRunner().invoke(app, [*args, "--help"], env={"COLUMNS": "200"})
        assert_clean_exit(result, 0)
        shown = LAYOUT.sub("", result.stdout)
        assert "\\[" not in shown, (args, result.stdout)  # an escape is shown as the bracket alone
        for text in _help_texts(command):
            for inner in BRACKETED.findall(text):
                expected = LAYOUT.sub("", f"[{inner}]")
                assert expected in shown, (args, f"[{inner}]", result.stdout)
                checked.append(expected)
    assert "[dask]" in checked and "[rad]" in checked  # the two of the issue, at least


# --------------------------------------------------------------------------- output paths


@pytest.mark.parametrize("name", ["qr.txt", "qr", "qr.h5.bak"])
def test_output_without_an_hdf5_suffix_is_rejected_before_the_run(tmp_path, name):
    out = tmp_path / name
    result = invoke("run", CONFIG, "-o", out, *SHORT)
    assert_clean_exit(result, 2)
    assert f"--output {out}: expected an HDF5 file name ending in .h5 or .hdf5" in result.stderr
    assert "status:" not in result.stdout
    assert list(tmp_path.iterdir()) == []


def test_compare_output_without_an_hdf5_suffix_is_rejected(tmp_path):
    result = invoke("compare", CONFIG, "-o", tmp_path / "cmp.txt", "--methods", "none", *SHORT)
    assert_clean_exit(result, 2)
    assert "expected an HDF5 file name ending in .h5 or .hdf5" in result.stderr


@pytest.mark.parametrize("name", ["qr.hdf5", "QR.H5"])
def test_hdf5_suffixes_are_accepted_in_any_case(tmp_path, name):
    result = invoke("run", CONFIG, "-o", tmp_path / name, "-q", *SHORT)
    assert_clean_exit(result, 0)
    assert (tmp_path / name).is_file()


def test_readme_use_examples_each_name_their_own_output():
    """No example of docs/usage.md overwrites another's result, nor make run's results/quick_return.h5."""
    use = (Path(__file__).resolve().parents[1] / "docs" / "usage.md").read_text()
    commands = [line.split() for line in use.splitlines() if line.startswith(".venv/bin/csim ")]
    writers = [c for c in commands if c[1] in ("run", "compare", "plot", "animate") and "--help" not in c]
    assert len(writers) >= 6
    outputs = []
    for c in writers:
        assert "-o" in c, " ".join(c)
        outputs.append(c[c.index("-o") + 1])
    assert len(set(outputs)) == len(outputs), outputs
    assert "results/quick_return.h5" not in outputs
    makefile = (Path(__file__).resolve().parents[1] / "Makefile").read_text()
    assert "csim run configs/quick_return.yaml -o results/quick_return.h5" in makefile


# --------------------------------------------------------------------------- the run summary


def test_a_run_at_rest_reports_its_energy_balance_in_joules(tmp_path):
    out = tmp_path / "rest.h5"
    result = invoke("run", CONFIG.parent / "pendulum.yaml", "-o", out, "--set", "initial.q.x=0",
                    "--set", "initial.q_offset.y=0", "--set", "stabilization.method=none",
                    "--set", "simulation.t_end=0.2")
    assert_clean_exit(result, 0)
    line = [x for x in result.stdout.splitlines() if x.startswith("energy balance:")][0]
    assert line.endswith("J (max |T + V - T0 - V0 - W|, in J: the energy scale is zero, the mechanism stays at rest)")
    assert "e-308" not in result.stdout


def test_a_run_that_moves_with_a_tiny_energy_change_is_not_said_to_be_massless(tmp_path):
    """A 1 kg pendulum swinging by 32 um: its kinetic energy (5e-9 J) is below 1e-9 of |V| (9.8 J), so the
    energy scale counts as zero; it moved, and it has mass."""
    result = invoke("run", CONFIG.parent / "pendulum.yaml", "-o", tmp_path / "tiny.h5", "--set", "initial.q.x=0",
                    "--set", "initial.qd.x=1e-4", "--set", "initial.q_offset.y=0", "--set", "simulation.t_end=0.2")
    assert_clean_exit(result, 0)
    line = [x for x in result.stdout.splitlines() if x.startswith("energy balance:")][0]
    assert line.endswith("the mechanism moves, but its energies change by less than 1e-9 of the largest it records)")


def test_a_python_fallback_says_why_in_the_summary(tmp_path):
    result = invoke("run", CONFIG, "-o", tmp_path / "bdf.h5", *SHORT, "--set", "simulation.integrator=BDF")
    assert_clean_exit(result, 0)
    assert "(python backend)" in result.stdout
    assert ("python backend:    not compiled because simulation.integrator 'BDF': the compiled backend "
            "implements DOP853") in result.stdout
    with h5py.File(tmp_path / "bdf.h5") as fh:
        assert "simulation.integrator 'BDF'" in text_attr(fh, "backend_reason")
    asked = invoke("run", CONFIG, "-o", tmp_path / "py.h5", *SHORT, "--set", "simulation.backend=python")
    assert_clean_exit(asked, 0)
    assert "python backend:" not in asked.stdout  # asked for, not a fallback


def test_a_slow_run_says_what_it_is_doing_in_one_plain_line_off_a_terminal(tmp_path, monkeypatch):
    import time

    import csim.pipeline

    real = csim.pipeline.run_case

    def slow(case, progress=None):
        time.sleep(2.2)  # past the status line's delay of 2 s
        return real(case, progress=progress)

    monkeypatch.setattr(csim.pipeline, "run_case", slow)
    result = invoke("run", CONFIG, "-o", tmp_path / "slow.h5", *SHORT)
    assert_clean_exit(result, 0)
    assert result.stderr == "csim: simulating quick_return.yaml to t = 0.2 s ...\n"
    quiet = invoke("run", CONFIG, "-o", tmp_path / "slow.h5", "-q", *SHORT)
    assert_clean_exit(quiet, 0)
    assert quiet.output == ""


def test_kernels_that_cannot_load_give_the_reason_of_the_fallback(tmp_path, monkeypatch):
    import csim.pipeline

    def broken(system, y0, settings):
        raise RuntimeError("no LLVM here")

    monkeypatch.setattr(csim.pipeline, "prepare_compiled", broken)
    result = invoke("run", CONFIG, "-o", tmp_path / "fallback.h5", *SHORT)
    assert_clean_exit(result, 0)
    assert ("python backend:    not compiled because the compiled kernels could not be loaded, "
            "RuntimeError: no LLVM here") in result.stdout


def test_a_chattering_load_law_fails_fast_with_its_file(tmp_path):
    """Issue 13: with this torque the drive stalls and the cutting force's velocity sign chatters."""
    out = tmp_path / "chatter.h5"
    result = invoke("run", CONFIG, "-o", out, "--set", "loads.torque=160000")
    assert_clean_exit(result, 1)
    assert "chattering load law: cutting_force: ds/dt = 0 (velocity sign)" in result.stderr
    assert f"partial result in {out}" in result.stderr
    with h5py.File(out, "r") as fh:
        assert text_attr(fh, "status") == "failed"
        assert text_attr(fh, "message").startswith("chattering load law: cutting_force")
        assert text_attr(fh, "failure") == "chatter"  # machine-readable, not only in the message
        assert fh["events/times"].shape == (23 + 20,)


@pytest.mark.slow
def test_a_run_stopped_at_max_events_still_writes_its_file(tmp_path):
    """Issue 13: with chatter detection off (chatter_events above max_events) this law chatters on to 100,000."""
    out = tmp_path / "chatter.h5"
    result = invoke("run", CONFIG, "-o", out, "--set", "loads.torque=160000", "--set",
                    "simulation.chatter_events=200000")
    assert_clean_exit(result, 1)
    assert "max_events" in result.stderr and f"partial result in {out}" in result.stderr
    with h5py.File(out, "r") as fh:
        assert text_attr(fh, "status") == "failed"
        assert fh["events/times"].shape[0] > 100_000


def test_a_kinematic_analysis_that_loses_assembly_later_exits_1_not_2(tmp_path):
    """A crank of 0.3 m with coupler 0.35 m and rocker 0.3 m on a 0.4 m ground closes at q_crank = 0
    (|B D| = 0.1 m) but not at q_crank = pi (|B D| = 0.7 m > 0.35 + 0.3): the run fails (exit 1), its
    failure kind is assembly, and it is not reported as bad input at the initial values."""
    out = tmp_path / "k.h5"
    result = invoke("run", CONFIG.parent / "fourbar.yaml", "-o", out, "--set", "mechanism.parameters.a=0.3")
    assert_clean_exit(result, 1)
    assert "cannot be assembled at t = " in result.stderr and "at its initial values" not in result.stderr
    with h5py.File(out, "r") as fh:
        assert (text_attr(fh, "status"), text_attr(fh, "failure")) == ("failed", "assembly")
        assert 0 < fh["t"][-1] < 0.5


def test_plot_output_named_like_a_figure_is_rejected(tmp_path):
    from conftest import assert_bad_input, invoke

    result = invoke("plot", tmp_path / "r.h5", "-o", tmp_path / "plot.png")
    assert_bad_input(result, "--output", "plot.png", "a folder")
    assert not (tmp_path / "plot.png").exists()


def test_an_expected_error_no_command_words_is_still_a_message(monkeypatch, capsys):
    """A csim error that reaches the entry point (a cached linkage that disagrees with its plan, raised while a run
    builds it) is printed as a message, exit 1, not a traceback."""
    import csim.cli as cli
    from csim.errors import CacheError

    def app(prog_name):
        raise CacheError("the symbolic linkage does not match its plan")

    monkeypatch.setattr(cli, "app", app)
    monkeypatch.delenv("CSIM_TRACEBACK", raising=False)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == cli.EXIT_FAILED
    assert capsys.readouterr().err == "csim: error: the symbolic linkage does not match its plan\n"


@pytest.mark.parametrize("traceback", ["", "1"])
def test_bad_input_that_reaches_the_entry_point_exits_2_and_csim_traceback_shows_where(monkeypatch, capsys,
                                                                                      traceback):
    """A CaseError no command turned into its own message is bad input (exit 2, its problems listed);
    CSIM_TRACEBACK=1 adds the traceback, for a bug report."""
    import csim.cli as cli
    from csim.errors import CaseError

    def app(prog_name):
        raise CaseError(["mechanism.drive: 'w*t**1.5' has no finite acceleration at t = 0", "simulation.rtol: -1"])

    monkeypatch.setattr(cli, "app", app)
    monkeypatch.setenv("CSIM_TRACEBACK", traceback)
    with pytest.raises(SystemExit) as info:
        cli.main()
    assert info.value.code == cli.EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.endswith("csim: error: 2 problem(s):\n  mechanism.drive: 'w*t**1.5' has no finite acceleration at "
                        "t = 0\n  simulation.rtol: -1\n")
    assert ("Traceback (most recent call last)" in err) == bool(traceback)
