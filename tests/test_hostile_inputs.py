"""Issue 24's hostile inputs and faults, through the command line: each ends within a bound
with exit 2 and a message naming the key, option or file, never a hang, a traceback or a
crash.

Every case runs ``python -m csim`` in its own process under a timeout: a hang inside sympy
or the YAML reader is one C call that no in-process alarm interrupts. :data:`LIMIT_S` is
the issue's 5 s plus the start of a Python process that imports csim (about 2 s) on a
shared, loaded machine; a hang runs far past it.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"
FOURBAR = CONFIGS / "fourbar_gravity.yaml"
PENDULUM = CONFIGS / "pendulum.yaml"
#: a hang shows as a timeout; a bounded input returns far sooner
LIMIT_S = 20
#: Python path only: no kernel compilation in a case that is (wrongly) accepted
PYTHON = ("--set", "simulation.backend=python")


def csim(*args, cwd: Path | None = None, limit: float = LIMIT_S, env: dict | None = None,
         preexec=None) -> subprocess.CompletedProcess:
    """``python -m csim ARGS`` in a new process, killed after ``limit`` seconds (a failed test)."""
    environment = {**os.environ, "PYTHONPATH": str(ROOT), **(env or {})}
    return subprocess.run([sys.executable, "-m", "csim", *map(str, args)], capture_output=True, text=True,
                          timeout=limit, cwd=cwd, env=environment, preexec_fn=preexec)


class _InProcess:
    """A command run in this process (:func:`conftest.invoke`), read like a CompletedProcess."""

    def __init__(self, result):
        self.returncode, self.stderr, self.stdout = result.exit_code, result.stderr, result.stdout
        if result.exception is not None and not isinstance(result.exception, SystemExit):
            import traceback

            self.stderr += "Traceback\n" + "".join(traceback.format_exception(result.exception))


def quick(*args) -> _InProcess:
    """``csim ARGS`` in this process: for inputs whose handling runs only Python code (a hang
    there would still show, as the test run's own time-out), without a process start."""
    from conftest import invoke

    return _InProcess(invoke(*args))


def assert_clear(proc: subprocess.CompletedProcess, *fragments: str, code: int = 2) -> None:
    """Exit ``code`` through csim's own message, no traceback, naming each fragment."""
    assert proc.returncode == code, (proc.returncode, proc.stderr[-2000:])
    assert "Traceback" not in proc.stderr, proc.stderr[-2000:]
    for fragment in fragments:
        assert fragment in proc.stderr, proc.stderr[-2000:]


def fourbar(folder: Path, name: str, forces: list | None = None, **links) -> Path:
    """The four-bar of configs/fourbar_gravity.yaml with force elements and link-1 entries changed."""
    doc = yaml.safe_load(FOURBAR.read_text())
    doc["simulation"]["t_end"] = 0.01
    doc["mechanism"]["links"][1].update(links)
    if forces is not None:
        doc["mechanism"]["forces"] = forces
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def alias_bomb(levels: int = 9) -> str:
    """A YAML flow list whose aliases expand to 9**levels strings (a few hundred bytes)."""
    parts = ["&a [x, x, x, x, x, x, x, x, x]"]
    for n in range(1, levels):
        name, previous = chr(97 + n), chr(96 + n)
        parts.append(f"&{name} [" + ", ".join([f"*{previous}"] * 9) + "]")
    return "[" + ", ".join(parts) + "]"


# --------------------------------------------------------------------------- bounded work


@pytest.mark.parametrize("mass, fragment", [
    ("((((9^99)^99)^99)^99)^99", "beyond the float range"),
    ("9^999999999", "beyond the float range"),
    ("(1/3)^999999999", "a power of constants"),
    ("0.5^999999999*m1", "a power of constants"),
    ("(m1+a)^100000", "expected an exponent of at most 64"),
    ("exp(exp(exp(1000)))", "beyond the float range"),
    ("(" * 60 + "m1" + ")" * 60, "nested 60 parentheses deep"),
    ("m1" + "+m1" * 400, "characters long"),
])
def test_an_expression_too_large_for_sympy_is_refused_at_once(tmp_path, mass, fragment):
    proc = csim("run", fourbar(tmp_path, "big", mass=mass), "-o", tmp_path / "o.h5", *PYTHON)
    assert_clear(proc, "mechanism.links[1].mass", fragment)


def test_describe_refuses_a_tower_of_powers_at_once(tmp_path):
    proc = csim("describe", fourbar(tmp_path, "tower", mass="((((9^99)^99)^99)^99)^99"))
    assert_clear(proc, "mechanism.links[1].mass", "beyond the float range")


def test_an_alias_bomb_as_a_value_is_measured_not_built(tmp_path):
    case = tmp_path / "bomb.yaml"
    case.write_text(PENDULUM.read_text().replace("dt: 0.01", f"dt: {alias_bomb()}"))
    proc = csim("run", case, "-o", tmp_path / "o.h5", *PYTHON)
    assert_clear(proc, str(case), "once its aliases (*name) are expanded", "expected at most 200,000")


def test_an_alias_bomb_in_a_sweep_values_file_is_measured_not_built(tmp_path):
    (tmp_path / "bomb.yaml").write_text(alias_bomb() + "\n")
    proc = csim("sweep", PENDULUM, "-v", "stabilization.w=@bomb.yaml", "-o", tmp_path / "s.h5", *PYTHON,
                cwd=tmp_path)
    assert_clear(proc, "--vary", "bomb.yaml", "once its aliases (*name) are expanded")


def test_an_alias_bomb_in_set_is_measured_not_built(tmp_path):
    proc = csim("run", PENDULUM, "-o", tmp_path / "o.h5", "--set", f"output.dt={alias_bomb()}", *PYTHON)
    assert_clear(proc, "--set output.dt", "once its aliases (*name) are expanded")


def test_twenty_thousand_nested_lists_are_refused_without_recursion(tmp_path):
    case = tmp_path / "nested.yaml"
    case.write_text("mechanism: " + "[" * 20_000 + "]" * 20_000 + "\n")
    proc = csim("run", case, "-o", tmp_path / "o.h5")
    assert_clear(proc, str(case), "nested more than 32 lists or mappings deep")


def _chain(n: int) -> str:
    """A planar chain of ``n`` links hanging from the ground, as a case file."""
    lines = ["mechanism:", "  label: chain", "  parameters: {l: 0.1, m: 0.2}", "  gravity: [0, -9.81, 0]",
             "  links:", "    - {link: 0, name: ground, joints: [[R, 0, A0]]}"]
    for i in range(1, n + 1):
        joints = f"[[R, 0, A{i - 1}]" + (f", [R, [l, 0, 0], A{i}]]" if i < n else "]")
        lines.append(f"    - {{link: {i}, joints: {joints}, mass: m, com: [l/2, 0, 0], inertia: m*l^2/12}}")
    lines.append("  couplings:")
    lines += [f"    - {{couple: [{i - 1}, A{i - 1}, {i}, A{i - 1}]}}" for i in range(1, n + 1)]
    return "\n".join(lines + ["simulation:", "  t_end: 0.1"]) + "\n"


def test_a_table_of_5000_links_is_refused_at_once(tmp_path):
    case = tmp_path / "chain.yaml"
    case.write_text(_chain(5000))
    assert_clear(csim("run", case, "-o", tmp_path / "o.h5"), str(case), "characters long; expected at most 100,000")


def test_a_table_over_the_link_limit_is_refused_at_once(tmp_path):
    case = tmp_path / "chain.yaml"
    case.write_text(_chain(101))
    assert_clear(csim("run", case, "-o", tmp_path / "o.h5"), "mechanism.links: got 102 rows; expected at most 100")


def test_a_chain_longer_than_the_chain_limit_is_refused_before_it_is_derived(tmp_path):
    """99 links pass the table limit, but a chain that long would take over ten minutes of
    symbolic work: refused at once, naming the chain."""
    case = tmp_path / "chain.yaml"
    case.write_text(_chain(99))
    assert_clear(csim("run", case, "-o", tmp_path / "o.h5"),
                 "mechanism.links: a chain of 99 moving links from the ground", "expected at most 40")


def test_describe_of_a_30_link_chain_ends_within_the_bound_with_progress(tmp_path):
    """The issue's 10 s, plus the process start (describe derives no dynamics model)."""
    case = tmp_path / "chain.yaml"
    case.write_text(_chain(30))
    start = time.monotonic()
    proc = csim("describe", case, limit=10 + LIMIT_S)
    assert proc.returncode == 0, proc.stderr
    assert "31 links, 30 joints" in proc.stdout and "q30" in proc.stdout
    if time.monotonic() - start > 5:  # the derivation took seconds (not only the process start): it says so
        assert "csim: deriving the kinematics of chain.yaml ..." in proc.stderr


@pytest.mark.parametrize("mass", ["((((9^99)^99)^99)^99)^99", "(1/3)^999999999"])
def test_plot_of_a_crafted_result_file_does_not_hang(tmp_path, mass):
    """A result file whose stored case holds a tower of powers, or a power of constants
    with a billion-digit exact value: plotted from its samples, at once."""
    out = tmp_path / "r.h5"
    assert csim("run", PENDULUM, "-o", out, "-q", "--set", "simulation.t_end=0.05", *PYTHON).returncode == 0
    tower = yaml.safe_dump({"mechanism": yaml.safe_load(FOURBAR.read_text())["mechanism"]})
    with h5py.File(out, "r+") as fh:
        fh.attrs["case"] = tower.replace("mass: m1", f"mass: {mass}")
    start = time.monotonic()
    proc = csim("plot", out, "-o", tmp_path / "plots", "--only", "coordinates")
    assert proc.returncode == 0, proc.stderr
    assert time.monotonic() - start < 15  # the process start and the figure; the stored case is refused at once
    assert (tmp_path / "plots" / "coordinates.png").is_file()


@pytest.fixture(scope="module")
def short_run(tmp_path_factory) -> Path:
    """A pendulum result file of 0.5 s, 51 samples (its stored case replaced by the tests, on copies)."""
    out = tmp_path_factory.mktemp("short") / "r.h5"
    assert quick("run", PENDULUM, "-o", out, "-q", "--set", "simulation.t_end=0.5", *PYTHON).returncode == 0
    return out


def _crafted(short_run: Path, folder: Path, case: str) -> Path:
    """A copy of ``short_run`` whose stored case is ``case``."""
    out = folder / "crafted.h5"
    out.write_bytes(short_run.read_bytes())
    with h5py.File(out, "r+") as fh:
        fh.attrs["case"] = case
    return out


def test_animate_of_a_crafted_result_file_does_not_hang(tmp_path, short_run):
    """The stored case holds a tower of powers: refused by the expression checks, so the
    file's own mechanism (the pendulum) is drawn with its defaults."""
    tower = yaml.safe_dump({"mechanism": yaml.safe_load(FOURBAR.read_text())["mechanism"]})
    out = _crafted(short_run, tmp_path, tower.replace("mass: m1", "mass: ((((9^99)^99)^99)^99)^99"))
    proc = csim("animate", out, "-o", tmp_path / "a.gif", "--dpi", "30")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "a.gif").is_file()


@pytest.mark.parametrize("command", ["plot", "animate"])
def test_a_stored_case_that_is_an_alias_bomb_is_measured_not_built(tmp_path, short_run, command):
    out = _crafted(short_run, tmp_path, f"mechanism: {{name: pendulum}}\noutput: {{dt: {alias_bomb()}}}\n")
    args = ["-o", tmp_path / "plots", "--only", "coordinates"] if command == "plot" else \
        ["-o", tmp_path / "a.gif", "--dpi", "30"]
    proc = csim(command, out, *args)
    assert proc.returncode == 0, proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_stored_case_too_large_to_rebuild_in_time_is_shown_from_its_samples(tmp_path, short_run, monkeypatch):
    """A stored chain of 40 links (the longest csim takes) needs about 30 s to rebuild: after
    REBUILD_LIMIT_S (here 1 s) plot draws the samples and says why the mechanism is left out;
    animate exits 2 saying so."""
    import csim.plot.source as source

    monkeypatch.setattr(source, "REBUILD_LIMIT_S", 1.0)
    out = _crafted(short_run, tmp_path, _chain(40))
    start = time.monotonic()
    proc = quick("plot", out, "-o", tmp_path / "plots")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "plots" / "coordinates.png").is_file()
    assert "skipped mechanism: rebuilding the mechanism from the case stored in the file took over 1 s" \
        in proc.stdout + proc.stderr
    assert_clear(quick("animate", out, "-o", tmp_path / "a.gif"), str(out), "took over 1 s", "cannot draw it")
    assert time.monotonic() - start < LIMIT_S  # two rebuilds of 1 s each, not minutes


def test_runs_of_one_mechanism_in_a_file_share_one_rebuild(short_run):
    from csim.io.hdf5 import read_result
    from csim.plot.source import Rebuilds, run_data

    rebuilds, result = Rebuilds(), read_result(short_run)
    first, second = run_data(result, short_run, "", rebuilds), run_data(result, short_run, "", rebuilds)
    assert len(rebuilds.done) == 1 and first.definition is second.definition is not None
    assert second.method == first.method == "baumgarte"


def test_a_result_file_whose_datasets_expand_beyond_it_is_refused(tmp_path, short_run):
    """A few kilobytes that would read as 160 GB (an unallocated, compressed dataset)."""
    out = _crafted(short_run, tmp_path, read_case(short_run))
    with h5py.File(out, "r+") as fh:
        del fh["qdd"]
        fh.create_dataset("qdd", shape=(10**10, 2), dtype="f8", chunks=(10**6, 2), compression="gzip")
    for command in ("plot", "animate"):
        assert_clear(quick(command, out), str(out), "would hold 1.6e+11 bytes once read", "a crafted or damaged file")


def test_the_expansion_check_follows_soft_links_and_refuses_external_ones(tmp_path):
    """A run group whose dataset is a soft link to a huge one outside it (h5py's visititems
    does not follow soft links), and one that links into another file."""
    from csim.io.hdf5 import ResultFileError, check_expansion

    path = tmp_path / "links.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("big", shape=(10**10, 2), dtype="f8", chunks=(10**6, 2), compression="gzip")
        fh.create_group("run")["qdd"] = h5py.SoftLink("/big")
        fh.create_group("other")["q"] = h5py.ExternalLink("elsewhere.h5", "/q")
    with h5py.File(path, "r") as fh:
        with pytest.raises(ResultFileError, match="would hold 1.6e.11 bytes"):
            check_expansion(fh["run"])
        with pytest.raises(ResultFileError, match="links to another file"):
            check_expansion(fh["other"])


def read_case(path: Path) -> str:
    with h5py.File(path, "r") as fh:
        return fh.attrs["case"]


@pytest.mark.parametrize("args, fragments", [
    (["--max-frames", "1000000000"], ["--max-frames: got 1000000000", "from 2 to 1,000"]),
    (["--dpi", "1200"], ["--max-frames / --dpi: 11 frames of 7680 x 9216 pixels", "expected at most 4.92e+08",
                         "--max-frames 6 or fewer"]),
    (["--speed", "inf"], ["--speed: got inf"]),
])
def test_animate_frames_are_bounded_naming_the_option(tmp_path, short_run, args, fragments):
    proc = quick("animate", short_run, "-o", tmp_path / "a.gif", *args)
    assert_clear(proc, *fragments)
    assert not (tmp_path / "a.gif").exists()


def test_animate_of_a_file_with_a_time_of_infinity_does_not_fail(tmp_path, short_run):
    out = tmp_path / "inf.h5"
    out.write_bytes(short_run.read_bytes())
    with h5py.File(out, "r+") as fh:
        fh["t"][-1] = np.inf
    proc = quick("animate", out, "-o", tmp_path / "a.gif", "--dpi", "30")
    assert proc.returncode == 0, proc.stderr


# --------------------------------------------------------------------------- tracebacks and messages


def test_a_force_type_given_as_a_list_names_the_key(tmp_path):
    case = fourbar(tmp_path, "t", [{"name": "act", "type": ["actuator"], "joint": "crank", "torque": 1}])
    assert_clear(quick("run", case, "-o", tmp_path / "o.h5", *PYTHON), "mechanism.forces[0] (act).type",
                 "expected one of spring")


@pytest.mark.parametrize("word", ["on", "yes", "no", "off"])
def test_yaml_1_1_booleans_as_keys_are_the_words(word):
    from csim.case import parse_yaml

    assert parse_yaml(f"{word}: C_x\nflag: {word}\n", "x") == {word: "C_x", "flag": word in ("on", "yes")}


def test_on_written_as_the_readme_shows_is_the_switching_coordinate(tmp_path):
    case = fourbar(tmp_path, "on", PLACEHOLDER_FORCES)
    case.write_text(case.read_text().replace("'on'", "on"))  # as written by hand, unquoted
    proc = quick("run", case, "-o", tmp_path / "o.h5", *PYTHON)
    assert proc.returncode == 0, proc.stderr


#: an actuator switching on a point's coordinate (``on`` is quoted by safe_dump)
PLACEHOLDER_FORCES = [{"name": "act", "type": "actuator", "joint": "crank", "torque": 0.1, "window": [-1, 1],
                       "on": "C_x"}]


def test_an_unknown_name_in_a_force_law_says_to_define_the_parameter(tmp_path):
    case = fourbar(tmp_path, "u", [{"name": "act", "type": "actuator", "joint": "crank", "torque": "k*x"}])
    assert_clear(quick("run", case, "-o", tmp_path / "o.h5", *PYTHON), "(act).torque",
                 "unknown name 'k', not a parameter of mechanism.parameters (define it there)")


def test_a_force_without_a_link_names_the_key_link(tmp_path):
    case = fourbar(tmp_path, "l", [{"name": "f1", "type": "force", "point": "B", "direction": [1, 0, 0],
                                    "value": 1}])
    proc = quick("run", case, "-o", tmp_path / "o.h5", *PYTHON)
    assert_clear(proc, "mechanism.forces[0] (f1).link: got null")
    assert "point[0]" not in proc.stderr


def test_an_unknown_integrator_with_the_compiled_backend_names_the_integrator(tmp_path):
    proc = quick("run", PENDULUM, "-o", tmp_path / "o.h5", "--set", "simulation.backend=compiled",
                "--set", "simulation.integrator=FOO")
    assert_clear(proc, "simulation.integrator: got 'FOO'")
    assert "None" not in proc.stderr


def _sweep_kind_only(path: Path) -> Path:
    with h5py.File(path, "w") as fh:
        fh.attrs["kind"] = "sweep"
    return path


def test_plot_of_a_file_with_only_kind_sweep_is_a_clear_error(tmp_path):
    path = _sweep_kind_only(tmp_path / "s.h5")
    assert_clear(quick("plot", path, "-o", tmp_path / "p"), str(path), "missing or damaged part", "'keys'")


def test_sweep_resume_of_a_file_with_only_kind_sweep_is_a_clear_error(tmp_path):
    path = _sweep_kind_only(tmp_path / "s.h5")
    proc = quick("sweep", PENDULUM, "-v", "stabilization.w=1,2", "--resume", "-o", path, *PYTHON)
    assert_clear(proc, str(path), "missing or damaged part")


def test_animate_of_a_sweep_file_says_it_is_a_sweep_file(tmp_path):
    path = _sweep_kind_only(tmp_path / "s.h5")
    assert_clear(quick("animate", path), str(path), "a sweep file")


@pytest.mark.parametrize("command", ["plot", "animate"])
def test_a_huge_dpi_names_the_option(tmp_path, command):
    out = tmp_path / "r.h5"
    assert quick("run", PENDULUM, "-o", out, "-q", "--set", "simulation.t_end=0.05", *PYTHON).returncode == 0
    assert_clear(quick(command, out, "--dpi", "1e9"), "--dpi: got 1e+09", "at most 1200")


def test_an_output_name_too_long_names_the_option(tmp_path):
    proc = quick("run", PENDULUM, "-o", tmp_path / ("x" * 300 + ".h5"), *PYTHON)
    assert_clear(proc, "--output", "bytes long; expected at most 200")


def test_an_output_under_a_file_says_the_file_is_not_a_folder(tmp_path):
    (tmp_path / "afile").write_text("")
    proc = quick("run", PENDULUM, "-o", tmp_path / "afile" / "out.h5", *PYTHON)
    assert_clear(proc, "--output", f"{tmp_path / 'afile'} is a file, not a folder")


def test_schema_replaces_a_symbolic_link_instead_of_writing_through_it(tmp_path):
    target = tmp_path / "target.json"
    target.write_text("kept")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    proc = csim("schema", "-o", link)
    assert proc.returncode == 0, proc.stderr
    assert target.read_text() == "kept"
    assert not link.is_symlink() and link.read_text().startswith("{")
    assert link.stat().st_mode & 0o777 == 0o666 & ~_umask()


#: a file or folder name over MAX_NAME_BYTES (200)
LONG = "x" * 300


@pytest.mark.parametrize("command, output, fragments", [
    ("plot", ["-o", LONG], ["--output", "is 300 bytes long; expected at most 200"]),
    ("animate", ["-o", LONG + ".gif"], ["--output", "is 304 bytes long; expected at most 200"]),
    ("export", ["-o", LONG], ["--output", "is 300 bytes long; expected at most 200"]),
    ("examples", [LONG], ["is 300 bytes long; expected at most 200"]),
])
def test_a_folder_or_file_name_too_long_names_the_output(tmp_path, short_run, command, output, fragments):
    args = [tmp_path / output[0]] if command == "examples" else [short_run, output[0], tmp_path / output[1]]
    assert_clear(quick(command, *args), *fragments)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["plot", "animate", "export", "examples"])
def test_an_output_under_a_file_says_the_file_is_not_a_folder_for_every_writer(tmp_path, short_run, command):
    (tmp_path / "afile").write_text("")
    out = tmp_path / "afile" / ("a.gif" if command == "animate" else "sub")
    proc = quick(command, out) if command == "examples" else quick(command, short_run, "-o", out)
    assert_clear(proc, str(out), f"{tmp_path / 'afile'} is a file, not a folder")
    assert "File exists" not in proc.stderr
    if command != "animate":  # the output folder itself a file
        proc = quick(command, tmp_path / "afile") if command == "examples" else \
            quick(command, short_run, "-o", tmp_path / "afile")
        assert_clear(proc, f"{tmp_path / 'afile'} is a file, not a folder")


@pytest.mark.parametrize("command, name, dangling", [
    ("plot", "coordinates.png", False),
    ("plot", "coordinates.png", True),
    ("export", "run.csv", False),
    ("export", "run.csv", True),
    ("examples", "pendulum.yaml", True),
])
def test_a_writer_replaces_a_symbolic_link_instead_of_writing_through_it(tmp_path, short_run, command, name,
                                                                         dangling):
    """plot, export and examples write each file through a temporary file renamed over it:
    the link gives way to the file; its target is left as it was, or not created. (A link to
    an existing file is an existing file to examples, which refuses to replace it.)"""
    target = tmp_path / "target"
    if not dangling:
        target.write_text("kept")
    out = tmp_path / "out"
    out.mkdir()
    (out / name).symlink_to(target)
    args = [out] if command == "examples" else [short_run, "-o", out] + (
        ["--only", "coordinates"] if command == "plot" else [])
    proc = quick(command, *args, "-q")
    assert proc.returncode == 0, proc.stderr
    assert not (out / name).is_symlink() and (out / name).is_file() and (out / name).stat().st_size > 0
    assert (out / name).stat().st_mode & 0o777 == 0o666 & ~_umask()
    if dangling:
        assert not target.exists()
    else:
        assert target.read_text() == "kept"
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []  # no temporary file left


@pytest.mark.parametrize("kind, fragment", [
    ("sweep", "a sweep file with a missing or damaged part"),
    ("comparison", "a comparison file without its /summary table"),
])
def test_export_of_a_file_with_only_its_kind_is_a_clear_error(tmp_path, kind, fragment):
    path = tmp_path / "k.h5"
    with h5py.File(path, "w") as fh:
        fh.attrs["kind"] = kind
    assert_clear(quick("export", path, "-o", tmp_path / "e"), str(path), fragment)
    assert not (tmp_path / "e").exists()


def test_export_to_a_full_disk_is_a_clear_error_leaving_no_partial_file(tmp_path, short_run):
    """``ulimit -f 1``: run.csv (about 10 kB) cannot be written whole; nothing of it is left."""
    out = tmp_path / "e"
    command = f"ulimit -f 1 && exec {sys.executable} -m csim export {short_run} -o {out}"
    proc = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=LIMIT_S,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert_clear(proc, "--output", str(out), "File too large")
    assert sorted(p.name for p in out.iterdir()) == []


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# --------------------------------------------------------------------------- meaningless force elements


@pytest.mark.parametrize("element, key, fragment", [
    ({"type": "spring", "between": [["crank", "B"], ["coupler", "B"]], "stiffness": 100}, "(e).between",
     "one point in every position"),
    ({"type": "spring", "between": [["ground", "A"], ["ground", "D"]], "stiffness": 100}, "(e).between",
     "never changes"),
    ({"type": "force", "link": "ground", "point": "A", "direction": [1, 0, 0], "value": 1}, "(e).link",
     "does not move"),
    ({"type": "torque", "link": "ground", "axis": [0, 0, 1], "value": 1}, "(e).link", "never turns"),
    ({"type": "torque", "link": "crank", "axis": [1, 0, 0], "value": 1}, "(e).axis", "does no work"),
    ({"type": "force", "link": "crank", "point": "B", "direction": [0, 0, 1], "value": 1}, "(e).direction",
     "does no work"),
    ({"type": "force", "link": "crank", "point": "B", "direction": [0, 0, 1], "frame": "link", "value": 1},
     "(e).direction", "does no work"),
])
def test_a_force_element_that_does_nothing_is_refused_naming_it(tmp_path, element, key, fragment):
    case = fourbar(tmp_path, "f", [{"name": "e", **element}])
    assert_clear(quick("run", case, "-o", tmp_path / "o.h5", *PYTHON), f"mechanism.forces[0] {key}", fragment)


# --------------------------------------------------------------------------- batch


def test_batch_expectations_no_run_could_meet_are_refused_before_any_run(tmp_path):
    manifest = tmp_path / "m.yaml"
    manifest.write_text(yaml.safe_dump({"cases": [{"name": "a", "case": str(PENDULUM), "expect": {
        "wall_time": -1, "max_phi": -1, "final_time": -5, "energy_error": {"min": 0, "max": -2}}}]}))
    start = time.monotonic()
    proc = csim("batch", manifest)
    assert_clear(proc, "4 problem(s)", "cases[0].expect.wall_time", "cases[0].expect.max_phi",
                 "cases[0].expect.final_time", "cases[0].expect.energy_error", "so no run could pass")
    assert time.monotonic() - start < LIMIT_S


def test_batch_expectations_above_t_end_are_refused(tmp_path):
    manifest = tmp_path / "m.yaml"
    manifest.write_text(yaml.safe_dump({"cases": [{"name": "a", "case": str(PENDULUM),
                                                   "expect": {"final_time": {"min": 5}}}]}))
    assert_clear(quick("batch", manifest), "cases[0].expect.final_time", "never above 2 s")


def test_the_junit_report_is_0644_under_umask_022(tmp_path):
    manifest = tmp_path / "m.yaml"
    manifest.write_text(yaml.safe_dump({"cases": [{"name": "a", "case": str(PENDULUM),
                                                   "set": ["simulation.t_end=0.01", "simulation.backend=python"],
                                                   "expect": {"status": "success"}}]}))
    report = tmp_path / "junit.xml"
    proc = csim("batch", manifest, "--junit", report, "-j", "1", preexec=lambda: os.umask(0o022))
    assert proc.returncode == 0, proc.stderr
    assert report.stat().st_mode & 0o777 == 0o644


# --------------------------------------------------------------------------- faults


def _file_size_limit(blocks: int):
    """``ulimit -f BLOCKS`` in the child (RLIMIT_FSIZE, bytes); Python ignores SIGXFSZ, so a
    write past it fails with EFBIG."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (blocks * 1024, blocks * 1024))
    return limit


#: about 0.5 MB of samples: past a limit of 100 blocks (100 kB)
BIG = ("--set", "output.dt=0.0005", "--set", "simulation.t_end=3", *PYTHON)


@pytest.mark.parametrize("command", [
    ("run", PENDULUM, *BIG),
    pytest.param(("compare", PENDULUM, "-m", "none,baumgarte", "-j", "1", *BIG), marks=pytest.mark.slow),
    pytest.param(("sweep", PENDULUM, "-v", "stabilization.w=1,2", "--keep", "-j", "1", *BIG), marks=pytest.mark.slow),
])
def test_a_full_disk_is_a_clear_error_leaving_no_file(tmp_path, command):
    out = tmp_path / "o.h5"
    proc = csim(*command, "-o", out, "-q", preexec=_file_size_limit(100), limit=120)
    assert proc.returncode in (1, 2), (proc.returncode, proc.stderr[-2000:])
    assert "Traceback" not in proc.stderr and "File too large" in proc.stderr and str(out) in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def _children(pid: int) -> list[int]:
    """The processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid:
                found.append(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_kill_9_of_a_sweep_leaves_no_process_behind(tmp_path):
    environment = {**os.environ, "PYTHONPATH": str(ROOT)}
    sweep = subprocess.Popen([sys.executable, "-m", "csim", "sweep", str(PENDULUM), "-v",
                              "stabilization.w=lin:1:40:40", "-j", "2", "-o", str(tmp_path / "s.h5"), "-q",
                              "--set", "simulation.t_end=30", *PYTHON], env=environment,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while len(children := _children(sweep.pid)) < 3 and time.monotonic() < deadline:  # 2 workers, the tracker
            time.sleep(0.2)
        assert len(children) >= 2, children
        time.sleep(1.0)  # the workers are running their chunks
        sweep.send_signal(signal.SIGKILL)
        sweep.wait()
        time.sleep(2.0)
        assert [pid for pid in children if _alive(pid)] == []
    finally:
        if sweep.poll() is None:
            sweep.kill()


def test_the_rebuild_deadline_gives_back_a_callers_own_timer():
    import signal

    from csim.plot.source import _deadline

    fired = []
    previous = signal.signal(signal.SIGALRM, lambda *_: fired.append(1))
    try:
        signal.setitimer(signal.ITIMER_REAL, 100.0)
        with _deadline(5.0):
            pass
        left = signal.getitimer(signal.ITIMER_REAL)[0]
        assert 90.0 < left <= 100.0 and not fired
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


@pytest.mark.parametrize("kind", ["comparison", "sweep"])
def test_comparison_and_sweep_files_whose_tables_expand_beyond_them_are_refused(tmp_path, kind):
    """A comparison's /summary or a sweep's /runs with a dataset that would read as 160 GB."""
    from csim.io.hdf5 import COMPARISON_KIND, ResultFileError, read_comparison
    from csim.study.sweep_file import SWEEP_KIND, read_sweep

    path = tmp_path / f"{kind}.h5"
    with h5py.File(path, "w") as fh:
        fh.attrs["kind"] = COMPARISON_KIND if kind == "comparison" else SWEEP_KIND
        fh.attrs["keys"] = "[]"
        table = fh.create_group("summary" if kind == "comparison" else "runs")
        table.create_dataset("wall_time", shape=(10**10, 2), dtype="f8", chunks=(10**6, 2), compression="gzip")
    with pytest.raises(ResultFileError, match="would hold 1.6e.11 bytes once read"):
        (read_comparison if kind == "comparison" else read_sweep)(path)


def test_a_deadline_swallowed_in_a_weakref_callback_is_quiet_and_the_next_one_ends_the_block(monkeypatch):
    """A rebuild's deadline that fires inside a weakref callback cannot be raised there: Python printed it as
    "Exception ignored in ..." with a traceback. It is swallowed quietly, and the next one (0.5 s later)
    ends the block."""
    import gc
    import weakref

    from csim.plot.source import _Deadline, _deadline

    class Thing:
        pass

    def linger(_):
        end = time.monotonic() + 0.3
        while time.monotonic() < end:  # the deadline fires in here
            pass

    reported = []  # what reaches Python's hook for exceptions it cannot raise (it prints them)
    monkeypatch.setattr(sys, "unraisablehook", reported.append)
    start = time.monotonic()
    with pytest.raises(_Deadline), _deadline(0.1):
        thing = Thing()
        ref = weakref.ref(thing, linger)  # noqa: F841 (the callback runs when thing goes)
        del thing
        gc.collect()
        while time.monotonic() - start < 5:
            pass
    assert time.monotonic() - start < 2
    assert reported == [] and sys.unraisablehook == reported.append


def test_a_deadline_that_fires_on_the_way_out_leaves_nothing_behind(monkeypatch):
    """The timer's tick landing in the block's cleanup raised _Deadline there, which skipped the rest of it:
    the handler, a 0.5 s repeating timer and the hook stayed for the rest of the process (helper-24's
    stress loop leaked within 11 to 330 deadlines). The tick is sent here as the cleanup restores the handler."""
    import contextlib

    from csim.plot.source import _Deadline, _deadline

    real, state = signal.signal, {"leaving": False, "fired": False}

    def racing(signum, handler):
        if state["leaving"] and not state["fired"]:
            state["fired"] = True
            signal.raise_signal(signal.SIGALRM)  # the timer fires as the block ends
        return real(signum, handler)

    previous = signal.getsignal(signal.SIGALRM)
    reported = []
    monkeypatch.setattr(sys, "unraisablehook", reported.append)
    monkeypatch.setattr(signal, "signal", racing)
    try:
        with contextlib.suppress(_Deadline), _deadline(10.0):
            state["leaving"] = True
        assert state["fired"]
        assert signal.getsignal(signal.SIGALRM) is previous
        assert sys.unraisablehook == reported.append and reported == []
        assert signal.getitimer(signal.ITIMER_REAL)[0] == 0
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        real(signal.SIGALRM, previous)
