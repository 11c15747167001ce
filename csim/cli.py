"""Command-line interface: a thin layer over :mod:`csim.pipeline` and :mod:`csim.io`.

Exit codes: 0 success; 1 the simulation ran but failed (the result file says why); 2 bad
input (case file, option, result file, or a mechanism that cannot be assembled at its
initial values), reported without a traceback; 130 interrupted (Ctrl-C): an existing
result file is left as it was, and the partial result goes beside it (``OUT.interrupted.h5``).
"""
from __future__ import annotations

import copy
import functools
import inspect
import os
import signal
import sys
import tempfile
import threading
import traceback
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, NoReturn

import typer
from typer.core import TyperCommand, TyperGroup

from csim import __version__
from csim.errors import CaseError, CsimError, ResultFileError
from csim.schema import short_repr


class _FlagsWithoutType:
    """Help that lists a flag as ``--quiet``, not ``--quiet <bool>``, and flows each paragraph.

    typer's rich help prints the value type of every option, flags (``--help`` included)
    too; an empty metavar leaves the type column of a flag blank. It also keeps the line
    breaks of a docstring's later paragraphs, which then break again where the terminal
    wraps them; the paragraphs are joined into one line each (the help wraps them).
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        if self.help:
            paragraphs = inspect.cleandoc(self.help).split("\n\n")
            self.help = "\n\n".join(" ".join(p.split("\n")) for p in paragraphs)

    def get_params(self, ctx):
        params = super().get_params(ctx)
        for param in params:
            if getattr(param, "is_flag", False) and param.metavar is None:
                param.metavar = ""
        return params


class _Command(_FlagsWithoutType, TyperCommand):
    """A csim command (see :class:`_FlagsWithoutType`)."""


class _Group(_FlagsWithoutType, TyperGroup):
    """The csim command group (see :class:`_FlagsWithoutType`)."""


app = typer.Typer(
    cls=_Group,
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="csim: simulate constrained multibody mechanisms from YAML case files.\n\n"
         "Example: csim run configs/quick_return.yaml -o results/quick_return.h5",
)

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2
#: 128 + SIGINT, as a shell reports a process that Ctrl-C stopped
EXIT_INTERRUPTED = 130

#: the longest file or folder name of an output path, in bytes (255 on most file systems,
#: less what ``.NAME.XXXXXXXX.tmp`` and ``NAME.interrupted.h5`` add)
MAX_NAME_BYTES = 200

#: file name endings accepted for an HDF5 result or comparison file (``--output``)
RESULT_SUFFIXES = (".h5", ".hdf5")


def _fail_input(exc: CsimError) -> NoReturn:
    for line in _input_lines(exc):
        typer.echo(line, err=True)
    raise typer.Exit(EXIT_BAD_INPUT)


def _input_lines(exc: CsimError) -> list[str]:
    """The lines of bad input's message: a header, then each problem (a CaseError's, or the error itself)."""
    problems = exc.problems if isinstance(exc, CaseError) else [str(exc)]
    header = f"csim: error: {len(problems)} problem(s):" if len(problems) > 1 else "csim: error:"
    return [header, *(f"  {line}" for line in problems)]


def check_writable(out: Path, protect: list[Path] = (), suffixes: tuple[str, ...] = (), option: str = "--output",
                   kind: str = "an HDF5 file") -> None:
    """Fail before a run, not after it, when the result file cannot be written.

    Refuses to overwrite the input files in ``protect`` and a name without one of
    ``suffixes`` (any case), creates the output's folder and tries a scratch file in it.

    Parameters
    ----------
    out : Path
        The result file to be written (``--output``).
    protect : list of Path
        Input files that ``out`` must not be.
    suffixes : tuple of str
        Accepted endings, lower case (``RESULT_SUFFIXES``); empty: any name.
    option : str
        How messages name the option (``--junit`` for ``csim batch``'s report).
    kind : str
        What the file is, for the message on a wrong ending.

    Raises
    ------
    ResultFileError
        Naming the option, the path and what was expected.
    """
    check_output_path(out, option)
    if out.exists() and any(out.resolve() == p.resolve() for p in protect):
        raise ResultFileError(f"{option} {out}: that is an input file; choose another result path")
    if out.is_dir():
        raise ResultFileError(f"{option} {out}: cannot write, it is a directory")
    if suffixes and out.suffix.lower() not in suffixes:
        raise ResultFileError(f"{option} {out}: expected {kind} name ending in {' or '.join(suffixes)}, "
                              f"e.g. {out.with_suffix(suffixes[0])}")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as exc:
        raise ResultFileError(f"{option} {out}: cannot write there ({exc.strerror or exc})") from None


def check_output_path(out: Path, option: str | None = "--output", folder: bool = False) -> None:
    """The checks of an output path that change nothing on disk: no name in it longer than
    :data:`MAX_NAME_BYTES`, and no file where a folder must be.

    Parameters
    ----------
    out : Path
        The file (or, with ``folder``, the folder) to be written.
    option : str or None
        How messages name the option (``--output``); None: by the path alone (an argument).
    folder : bool
        ``out`` is a folder to write files into (``csim plot``, ``export``, ``examples``):
        it may not be a file either.

    Raises
    ------
    ResultFileError
        Naming the option, the path and the cause.
    """
    where = f"{option} " if option else ""
    too_long = next((part for part in out.parts if len(os.fsencode(part)) > MAX_NAME_BYTES), None)
    if too_long is not None:  # a temporary file beside it, and OUT.interrupted.h5, add to the name
        raise ResultFileError(f"{where}{short_repr(str(out))}: the name {short_repr(too_long)} is "
                              f"{len(os.fsencode(too_long))} bytes long; expected at most {MAX_NAME_BYTES} (file "
                              f"systems allow 255, and the temporary and interrupted files beside it add to it)")
    above = [*reversed(out.parents), out] if folder else reversed(out.parents)
    blocker = next((p for p in above if p.exists() and not p.is_dir()), None)
    if blocker is not None:
        raise ResultFileError(f"{where}{out}: cannot write there, {blocker} is a file, not a folder; expected a "
                              f"{'folder path' if folder else 'path in a folder'}")


#: what the summary adds to the result path when -o was left out
DEFAULT_NOTE = " (the default for this case file; -o names another)"


def default_output(case: Path, tail: str = "") -> Path:
    """The result path when ``-o`` is left out.

    Parameters
    ----------
    case : Path
        The case file.
    tail : str
        Added to its stem (``"_compare"`` for ``csim compare``).

    Returns
    -------
    Path
        ``results/<case file stem><tail>.h5``, relative to the current folder
        (``results/quick_return.h5`` for ``configs/quick_return.yaml``, as ``make run`` writes).
    """
    return Path("results") / f"{case.stem}{tail}.h5"


def interrupted_path(out: Path) -> Path:
    """Where an interrupted command puts its partial result, so that ``out`` stays as it was.

    Parameters
    ----------
    out : Path
        The result path, e.g. ``results/qr.h5``.

    Returns
    -------
    Path
        ``OUT.interrupted.h5`` beside it, e.g. ``results/qr.interrupted.h5``.
    """
    return out.with_name(f"{out.stem}.interrupted{out.suffix}")


class _CtrlC:
    """Whether Ctrl-C (SIGINT) arrived, including one that the integration caught itself."""

    interrupted = False


@contextmanager
def _watch_ctrl_c() -> Iterator[_CtrlC]:
    """Record SIGINT inside the block while passing it on (as KeyboardInterrupt).

    The Python driver turns a KeyboardInterrupt inside an integration into a failed run
    with its samples so far; the record tells the command that the user stopped it.
    """
    watch = _CtrlC()
    old = signal.getsignal(signal.SIGINT)
    hooked = threading.current_thread() is threading.main_thread() and callable(old)
    if hooked:
        def handler(signum, frame):
            watch.interrupted = True
            old(signum, frame)
        signal.signal(signal.SIGINT, handler)
    try:
        yield watch
    except KeyboardInterrupt:
        watch.interrupted = True
        raise
    finally:
        if hooked:
            signal.signal(signal.SIGINT, old)


def _interruptible(command):
    """Ctrl-C anywhere in ``command`` outside the run itself: exit 130 with one line, no
    traceback (result files are written atomically, so none is left half-written)."""
    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except KeyboardInterrupt:
            typer.echo("\ncsim: interrupted (Ctrl-C); result files are written whole or not at all", err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
    return wrapper


def _version(value: bool):
    if value:
        typer.echo(f"csim {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
):
    """csim: simulate constrained multibody mechanisms from YAML case files."""


SET_HELP = ("Override a case-file value, KEY=VALUE with a dotted key path; repeatable. "
            "Example: --set simulation.t_end=10 --set simulation.integrator=RK4 --set simulation.step=1e-3")


@app.command(cls=_Command)
@_interruptible
def run(
    case: Annotated[Path, typer.Argument(help="Case file (YAML). Example: configs/quick_return.yaml",
                                         show_default=False, metavar="CASE.yaml")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="OUT.h5",
        help="Result file (HDF5, a name ending in .h5 or .hdf5), written atomically. Default: "
             "results/CASE.h5 (the case file's name, under the current folder). Example: -o out/qr.h5")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", metavar="KEY=VALUE", help=SET_HELP)] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors; no progress bar.")] = False,
):
    """Simulate one case and write its result file.

    Finds consistent initial conditions by Newton-Raphson, integrates, writes HDF5 and
    prints a summary (final state, constraint errors, energy balance, cost).

    Exit codes: 0 success; 1 the simulation failed (the file is still written); 2 bad
    input, or a mechanism that cannot be assembled; 130 interrupted (Ctrl-C: the
    partial result goes to OUT.interrupted.h5, OUT is left as it was).

    Example: csim run configs/quick_return.yaml -o results/qr.h5 --set simulation.t_end=10
    """
    from csim.case import load_case
    from csim.pipeline import run_case
    from csim.progress import RunProgress, reporting, status

    try:
        c = load_case(case, set_ or [])
        out = output or default_output(case)
        check_writable(out, protect=[case], suffixes=RESULT_SUFFIXES)
    except CsimError as exc:
        _fail_input(exc)
    for warning in [] if quiet else c.warnings:  # a failure names the cause again, --quiet or not
        typer.echo(f"csim: warning: {warning}", err=True)
    result = None
    with reporting(not quiet), _watch_ctrl_c() as ctrl_c:
        try:
            with status(f"simulating {case.name} to t = {c.simulation.t_end:g} s"), \
                    RunProgress(c.simulation.t_end) as bar:
                result = run_case(c, progress=bar)
        except KeyboardInterrupt:
            pass  # no result came back (interrupted before the integration, or in compiled code)
        except Exception:
            if not ctrl_c.interrupted:
                raise
            # Ctrl-C inside a numba kernel comes back as SystemError ("returned a result with an exception set")
    if ctrl_c.interrupted:
        _keep_interrupted(c, result, out, quiet)
    replaced = out.exists()
    _write(out, result, c.mechanism.coordinate_units)
    if not quiet:
        where = "" if output else DEFAULT_NOTE
        _print_summary(result, f"{out}{where}" + (", replacing the file there" if replaced else ""), case=case)
    if result.failure == "assembly" and result.t.size == 0:  # at the start (a kinematic analysis may lose it later)
        typer.echo(f"csim: error: the mechanism cannot be assembled at its initial values: {result.message}; "
                   f"expected mechanism.parameters that close the mechanism, and initial.q, initial.guess on an "
                   f"assembly branch (result file with status failed: {out})", err=True)
        raise typer.Exit(EXIT_BAD_INPUT)
    if not result.ok:
        typer.echo(f"csim: simulation failed: {result.message} (partial result in {out})", err=True)
        raise typer.Exit(EXIT_FAILED)


def _print_summary(run, where: str, case: Path | None = None) -> None:
    """Print a run's summary (rich on a terminal, plain aligned ``key: value`` lines
    otherwise), after the case file and before where the result file went."""
    from csim.report import Fields, Report, emit
    from csim.result import SUMMARY_WIDTH

    items = ([("case", str(case))] if case is not None else []) + run.summary_items() + [("result", where)]
    emit(Report([Fields(items, width=SUMMARY_WIDTH)]))


def _write(out: Path, result, coordinate_units: list[str], code: int = EXIT_BAD_INPUT) -> None:
    """Write a run's result file; an OSError (e.g. the disk filled up during the run) exits ``code``."""
    from csim.io.hdf5 import write_result

    try:
        write_result(out, result, coordinate_units)
    except OSError as exc:
        typer.echo(f"csim: error: cannot write {out}: {exc}", err=True)
        raise typer.Exit(code) from None


def _keep_interrupted(c, result, out: Path, quiet: bool) -> NoReturn:
    """Write an interrupted run beside ``out`` (``out`` is left as it was), say where, exit 130.

    ``result`` is the run up to the interrupt, or None when none came back (it is then
    written without samples). Either way it is marked: status failed, failure interrupted.
    """
    from csim.result import Result

    if result is None:
        from csim.fast import resolve_backend

        m = c.mechanism
        result = Result.empty(
            m.name, m.coordinate_names, [ld.name for ld in m.loads], [ob.name for ob in m.observables],
            m.n_constraints, c.to_yaml(), message="interrupted by the user (Ctrl-C) before the run returned samples",
            run_kind="kinematic" if c.kinematic else "simulation", backend=resolve_backend(c))
    result.status, result.failure = "failed", "interrupted"
    if not result.message.startswith("interrupted"):
        result.message = f"interrupted by the user (Ctrl-C); {result.message}"
    partial = interrupted_path(out)
    _write(partial, result, c.mechanism.coordinate_units, code=EXIT_INTERRUPTED)
    if not quiet:
        _print_summary(result, f"{partial} (partial)")
    kept = f"{out} was left as it was" if out.exists() else f"nothing was written to {out}"
    typer.echo(f"csim: interrupted (Ctrl-C): partial result in {partial}; {kept}", err=True)
    raise typer.Exit(EXIT_INTERRUPTED)


@app.command(cls=_Command)
@_interruptible
def compare(
    case: Annotated[Path, typer.Argument(help="Case file (YAML). Example: configs/quick_return.yaml",
                                         show_default=False, metavar="CASE.yaml")],
    methods: Annotated[str | None, typer.Option(
        "--methods", "-m", metavar="A,B,...",
        help="Stabilization methods to compare, separated by commas. Default: every registered method "
             "the case allows. Example: --methods none,baumgarte,sliding_mode,projection")] = None,
    tolerances: Annotated[str | None, typer.Option(
        "--tolerances", "-t", metavar="TOL,TOL,...",
        help="Work-precision study: run each method at each value, which sets simulation.rtol = "
             "simulation.atol (simulation.step in s for RK4). Example: --tolerances 1e-4,1e-6,1e-8,1e-10")] = None,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="OUT.h5",
        help="Comparison file (HDF5, a name ending in .h5 or .hdf5), written atomically: one group per "
             "method. Default: results/CASE_compare.h5 (the case file's name, under the current folder)")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", metavar="KEY=VALUE", help=SET_HELP)] = None,
    jobs: Annotated[int | None, typer.Option(
        "--jobs", "-j", metavar="N",
        help="Worker processes. Default: one per run, at most one per CPU. 1 runs everything in "
             "this process.")] = None,
    reference_method: Annotated[str, typer.Option(
        "--reference-method", metavar="NAME", help="Stabilization method of the reference run.")] = "projection",
    reference_tol: Annotated[str, typer.Option(
        "--reference-tol", metavar="TOL",
        help="rtol = atol of the reference run (integrator DOP853).")] = "1e-12",
    repeat: Annotated[int, typer.Option(
        "--repeat", metavar="N",
        help="Run each case N times and keep the median wall time: timings for a work-precision chart "
             "(a single run's time varies with what else the machine does).")] = 1,
    strict: Annotated[bool, typer.Option(
        "--strict", help="Exit 1 when any run failed (for CI). Without it a failed run is a finding of the "
                         "study, a row of the file, and the exit code is 0 once every run ran.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Run one case with several stabilization methods and compare them.

    Each method runs the same case (stabilization.method set to it), in
    parallel processes. A tight reference run (projection, DOP853,
    rtol = atol = 1e-12) measures the error of the motion. One row per
    method: max |Phi|, final |Phi|, max |Phi_q qd|, motion error against
    the reference, wall time, RHS evaluations and status. With
    --tolerances, each method runs at each tolerance (work-precision).

    Exit codes: 0 every run ran (a run that failed numerically is a row of
    the file, named on stderr); 1 a run could not be made (it raised, or its
    worker died), the reference run failed, or with --strict any run failed
    (the file is still written); 2 bad input; 130 interrupted (Ctrl-C: the
    runs so far go to OUT.interrupted.h5, OUT is left as it was).

    Example: csim compare configs/quick_return.yaml
    --methods none,baumgarte,projection --tolerances 1e-6,1e-8,1e-10
    """
    from csim.compare import ReferenceSettings, parse_methods, parse_tolerances
    from csim.compare import compare as run_comparison

    problems: list[str] = []

    def attempt(parse):
        try:
            return parse()
        except CaseError as exc:
            problems.extend(exc.problems)
            return None

    method_list = attempt(lambda: parse_methods(methods)) if methods is not None else None
    tol_list = attempt(lambda: parse_tolerances(tolerances)) if tolerances is not None else None
    ref_tol = attempt(lambda: parse_tolerances(reference_tol, "--reference-tol"))
    if ref_tol is not None and len(ref_tol) != 1:
        problems.append(f"--reference-tol: got {reference_tol!r}; expected one positive number, e.g. 1e-12")
    attempt(lambda: parse_methods(reference_method, "--reference-method"))
    if jobs is not None and jobs < 1:
        problems.append(f"--jobs: got {jobs}; expected a whole number >= 1")
    if repeat < 1:
        problems.append(f"--repeat: got {repeat}; expected a whole number >= 1")
    if problems:
        _fail_input(CaseError(problems))
    out = output or default_output(case, "_compare")
    progress = None
    if not quiet and sys.stderr.isatty():
        def progress(run, done, total):
            typer.echo(f"[{done}/{total}] {run.method} {run.tolerance:g}: {run.status} "
                       f"({run.wall_time:.2f} s)", err=True)
    try:
        check_writable(out, protect=[case], suffixes=RESULT_SUFFIXES)
        comparison = run_comparison(case, methods=method_list, tolerances=tol_list, overrides=set_ or [],
                                    reference=ReferenceSettings(method=reference_method, tol=ref_tol[0]),
                                    jobs=jobs, progress=progress, repeat=repeat,
                                    warn=None if quiet else lambda w: typer.echo(f"csim: warning: {w}", err=True))
    except CsimError as exc:
        _fail_input(exc)
    _finish_comparison(comparison, out, default=output is None, quiet=quiet, strict=strict)


def _finish_comparison(comparison, out: Path, default: bool, quiet: bool, strict: bool = False) -> None:
    """Write a comparison (after Ctrl-C beside ``out``, as ``OUT.interrupted.h5``), print its
    table, and exit 130 when interrupted; 1 when a run could not be made or the reference
    failed, or with ``strict`` when any run failed."""
    target = interrupted_path(out) if comparison.interrupted else out
    try:
        comparison.write(target)
    except OSError as exc:
        typer.echo(f"csim: error: cannot write {target}: {exc}", err=True)
        raise typer.Exit(EXIT_INTERRUPTED if comparison.interrupted else EXIT_BAD_INPUT) from None
    if not quiet:
        from csim.report import Fields, Lines, emit

        where = f"{target}" + (DEFAULT_NOTE if default else "")
        emit(comparison.report().add(Lines([""]), Fields([("result", where)])))
    if comparison.interrupted:
        kept = f"{out} was left as it was" if out.exists() else f"nothing was written to {out}"
        typer.echo(f"csim: comparison interrupted (Ctrl-C): partial results in {target}; {kept}", err=True)
        raise typer.Exit(EXIT_INTERRUPTED)
    if not comparison.ok:
        names = ", ".join(comparison.label(r) for r in comparison.failed)
        not_run = [r for r in comparison.failed if r.result is None or r is comparison.reference_run]
        if strict or not_run:
            typer.echo(f"csim: comparison incomplete, {len(comparison.failed)} run(s) failed: {names} "
                       f"(results in {out})", err=True)
            raise typer.Exit(EXIT_FAILED)
        typer.echo(f"csim: note: {len(comparison.failed)} run(s) failed, each a row of {out}: {names} "
                   f"(--strict exits 1 on a failed run)", err=True)


@app.command(cls=_Command)
@_interruptible
def sweep(
    case: Annotated[Path, typer.Argument(help="Case file (YAML): the base case every run varies.",
                                         show_default=False, metavar="CASE.yaml")],
    vary: Annotated[list[str] | None, typer.Option(
        "--vary", "-v", metavar="KEY=VALUES",
        help="A case key and its values: a list (stabilization.method=none,baumgarte), a range "
             "(simulation.step=lin:1e-3:1e-2:10, stabilization.w=log:1:1000:13) or @FILE (one value per "
             "line); values may carry their unit (initial.q.q1=170 deg,172 deg; simulation.t_end=lin:1 s:2 s:5). "
             "Several --vary make a grid of every combination.")] = None,
    sample: Annotated[str, typer.Option(
        "--sample", metavar="grid|random|lhs",
        help="grid: every combination; random or lhs (Latin hypercube): --samples runs drawn from the "
             "ranges (lin: uniform, log: log-uniform, a list: each item alike).")] = "grid",
    samples: Annotated[int | None, typer.Option("--samples", "-n", metavar="N",
                                                help="Runs of a random or lhs design.")] = None,
    seed: Annotated[int | None, typer.Option(
        "--seed", metavar="N", help="Seed of a random or lhs design (default: drawn, and stored in the file).")] = None,
    reference: Annotated[list[str] | None, typer.Option(
        "--reference", "-r", metavar="KEY=VALUE",
        help="A reference run: the base case with these --set overrides (repeat the option), e.g. "
             "-r simulation.rtol=1e-12 -r simulation.atol=1e-12; each run's motion error is measured "
             "against it.")] = None,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="OUT.h5",
        help="Sweep file (HDF5, .h5 or .hdf5), written atomically at checkpoints and at the end. "
             "Default: results/CASE_sweep.h5")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", metavar="KEY=VALUE", help=SET_HELP)] = None,
    jobs: Annotated[int | None, typer.Option(
        "--jobs", "-j", metavar="N", help="Worker processes. Default: one per CPU; 1 runs in this process.")] = None,
    scheduler: Annotated[str | None, typer.Option(
        "--scheduler", metavar="ADDRESS",
        help="Run on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786 "
             "(pip install 'csim-multibody\\[dask]').")] = None,
    keep: Annotated[bool, typer.Option(
        "--keep", help="Also store each run's signals (t, q, qd, Phi, Phi_q qd, energy-balance error).")] = False,
    resume: Annotated[bool, typer.Option(
        "--resume", help="Go on with the runs an interrupted sweep file (OUT) left pending.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Run one case over a grid or a random design of case values (a parameter study).

    Any case key can vary: gains, step sizes, tolerances, mechanism
    parameters, loads, initial conditions. The runs reuse the loaded model
    and compiled kernels in each worker. One row per run: status and why it
    failed, max |Phi|, max |Phi_q qd|, energy-balance error, motion error
    against the reference run, wall time, RHS evaluations, events. csim plot
    draws a stability map of two varied keys, or curves of one.

    Exit codes: 0 every run ran (failed runs are data: the file says why);
    2 bad input; 130 interrupted (Ctrl-C: OUT holds the finished runs;
    --resume goes on).

    Example: csim sweep configs/quick_return.yaml -v stabilization.w=lin:10:400:40
    -v simulation.step=log:1e-3:2e-2:30 --set stabilization.method=baumgarte
    --set simulation.integrator=RK4 -o results/map.h5
    """
    from csim.case import read_case_file, validate_case
    from csim.progress import CountProgress, reporting
    from csim.study import make_plan, parse_variation, run_sweep

    out = output or default_output(case, "_sweep")
    try:
        data = read_case_file(case, set_ or [])
        c = validate_case(copy.deepcopy(data), source=str(case))
        problems = _sweep_option_problems(jobs, scheduler, reference, resume, out)
        variations = []
        for text in vary or []:
            try:
                variations.append(parse_variation(text))
            except CaseError as exc:
                problems += exc.problems
        if problems:
            raise CaseError(problems)
        if resume and seed is None and sample != "grid":  # the design is the file's: its seed
            from csim.study.sweep_file import read_sweep

            seed = int(read_sweep(out).attrs.get("seed", -1))
            seed = None if seed < 0 else seed
        plan = make_plan(c, variations, sampling=sample, samples=samples, seed=seed, data=data)
        check_writable(out, protect=[case], suffixes=RESULT_SUFFIXES)
        with reporting(not quiet), CountProgress(len(plan), label=f"sweep of {case.name}") as bar:
            result = run_sweep(plan, out, jobs=jobs, scheduler=scheduler, keep=keep, reference=reference,
                               resume=resume, progress=bar)
    except CsimError as exc:
        _fail_input(exc)
    if not quiet:
        from csim.report import emit

        emit(sweep_report(result, out))
    _sweep_exit(result, out)


def _sweep_exit(result, out: Path) -> None:
    """Exit 130 after Ctrl-C and 1 when runs were lost with a worker, each saying which runs
    are pending and that --resume runs them; return when every run ran."""
    if result.interrupted:
        stopped = sorted(result.stopped)
        under_way = (f"{len(stopped)} stopped while running (run{'s' if len(stopped) > 1 else ''} "
                     f"{', '.join(map(str, stopped[:20]))}{', ...' if len(stopped) > 20 else ''}: status pending, "
                     f"reason interrupted), " if stopped else "")
        typer.echo(f"csim: sweep interrupted (Ctrl-C): {result.done} of {len(result.rows)} runs finished in {out}; "
                   f"{under_way}{len(result.rows) - result.done - len(stopped)} not started; "
                   f"add --resume to the same command to run the rest", err=True)
        raise typer.Exit(EXIT_INTERRUPTED)
    if result.lost:
        typer.echo(f"csim: sweep incomplete: {result.done} of {len(result.rows)} runs in {out}; {result.lost}, and "
                   f"its runs are pending; add --resume to the same command to run them", err=True)
        raise typer.Exit(EXIT_FAILED)


def _sweep_option_problems(jobs, scheduler, reference, resume: bool, out: Path) -> list[str]:
    """Options of csim sweep that contradict one another, or a --resume without its file."""
    problems = []
    if jobs is not None and jobs < 1:
        problems.append(f"--jobs: got {jobs}; expected a whole number >= 1")
    if jobs is not None and scheduler is not None:
        problems.append("--jobs: the Dask cluster of --scheduler decides how many runs go at once; give one of them")
    if resume and reference:
        problems.append("--reference: --resume goes on with the file's own reference run; leave --reference out")
    if resume and not out.is_file():
        problems.append(f"--resume: no sweep file {out} to resume")
    return problems


def sweep_report(result, out: Path):
    """What was varied, the runs by outcome, and where the file went (a :class:`csim.report.Report`)."""
    from csim.report import Fields, Report

    counts = ", ".join(f"{n} {label}" for label, n in sorted(result.counts().items(), key=lambda kv: -kv[1]))
    keys = " x ".join(f"{v.key} ({len(set(map(str, result.plan.column(v.key))))})" for v in result.plan.variations)
    return Report([Fields([("sweep", f"{len(result.rows)} runs of {keys} ({result.plan.sampling})"),
                           ("outcomes", counts), ("result", str(out))], width=12)])


@app.command(cls=_Command)
@_interruptible
def batch(
    manifest: Annotated[Path, typer.Argument(help="Batch manifest (YAML): cases with overrides and expectations. "
                                             "Example: configs/batch/accuracy.yaml",
                                             show_default=False, metavar="MANIFEST.yaml")],
    junit: Annotated[Path | None, typer.Option(
        "--junit", metavar="REPORT.xml",
        help="Write a JUnit XML report: one test case per entry, a failure per failed expectation.")] = None,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="DIR",
        help="Keep each run's result file, DIR/NAME.h5 (failed runs included, marked failed). "
             "Default: none is written.")] = None,
    jobs: Annotated[int | None, typer.Option(
        "--jobs", "-j", metavar="N",
        help="Worker processes. Default: one per entry, at most one per CPU. 1 runs everything in "
             "this process.")] = None,
    only: Annotated[str | None, typer.Option(
        "--only", metavar="NAME,NAME,...", help="Run only these entries of the manifest.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Run the cases of a manifest and check each run against its expectations (for CI).

    Each entry names a case file (relative to the manifest), --set style
    overrides and expectations: status, max_phi, max_phi_dot,
    energy_error, value (a coordinate at a time), wall_time, final_time,
    events, nfev, backend. The entries run in parallel processes. Prints a
    pass/fail table, with each failed expectation's measured value against
    its bound.

    Exit codes: 0 every expectation holds; 1 an expectation failed; 2 bad
    input (the manifest, a case in it, an option); 130 interrupted (Ctrl-C).

    Example: csim batch configs/batch/accuracy.yaml --junit results/batch_junit.xml
    """
    from csim.batch import load_manifest, run_batch

    problems = []
    if jobs is not None and jobs < 1:
        problems.append(f"--jobs: got {jobs}; expected a whole number >= 1")
    names = [n.strip() for n in only.split(",") if n.strip()] if only is not None else None
    if names == []:
        problems.append(f"--only: got {only!r}; expected entry names separated by commas")
    try:
        if problems:
            raise CaseError(problems)
        loaded = load_manifest(manifest, only=names)
        if junit is not None:
            check_writable(junit, protect=[manifest], suffixes=(".xml",), option="--junit", kind="an XML file")
        if output is not None:
            _check_folder(output)
    except CsimError as exc:
        _fail_input(exc)
    from csim.progress import reporting, status

    progress, terminal = None, sys.stderr.isatty()
    if not quiet and terminal:
        def progress(run, done, total):
            typer.echo(f"[{done}/{total}] {run.entry.name}: {'pass' if run.passed else 'FAIL'} "
                       f"({run.wall_time:.2f} s)", err=True)
    # a log (CI) gets one line when the batch takes a while; a terminal gets a line per run
    with reporting(not quiet and not terminal), \
            status(f"running the {len(loaded.entries)} cases of {manifest.name} (a cold cache first compiles "
                   f"each mechanism's kernels, ~30 s)"):
        result = run_batch(loaded, jobs=jobs, progress=progress)
    _finish_batch(result, junit, output, quiet)


def _check_folder(folder: Path) -> None:
    """Fail before the runs when the result folder (``-o DIR``) cannot be created or written."""
    if folder.exists() and not folder.is_dir():
        raise ResultFileError(f"--output {folder}: that is a file; expected a folder for the result files")
    check_output_path(folder, folder=True)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        raise ResultFileError(f"--output {folder}: cannot write there ({exc.strerror or exc})") from None


def _finish_batch(result, junit: Path | None, output: Path | None, quiet: bool) -> None:
    """Write a batch's result files and JUnit report, print its table, and exit 130 when
    interrupted, 1 when an expectation failed."""
    try:
        if output is not None:
            result.write_results(output)
        if junit is not None:
            result.write_junit(junit)
    except OSError as exc:
        typer.echo(f"csim: error: cannot write the batch's files: {exc}", err=True)
        raise typer.Exit(EXIT_INTERRUPTED if result.interrupted else EXIT_BAD_INPUT) from None
    if not quiet:
        from csim.report import Fields, Lines, emit

        files = [(label, str(path)) for label, path in (("results", output), ("junit", junit)) if path is not None]
        emit(result.report().add(*([Lines([""]), Fields(files, width=12)] if files else [])))
    if result.interrupted:
        typer.echo("csim: batch interrupted (Ctrl-C); unfinished runs are reported as failed", err=True)
        raise typer.Exit(EXIT_INTERRUPTED)
    if not result.passed:
        names = ", ".join(r.entry.name for r in result.failed)
        typer.echo(f"csim: batch failed: {len(result.failed)} of {len(result.runs)} case(s) missed an expectation: "
                   f"{names}", err=True)
        raise typer.Exit(EXIT_FAILED)


@app.command(cls=_Command)
@_interruptible
def plot(
    result: Annotated[Path, typer.Argument(help="Result file (csim run) or comparison file (csim compare).",
                                           show_default=False, metavar="RESULT.h5")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="DIR", help="Folder for the figures, one file per figure (NAME.FORMAT). "
                                              "Default: RESULT_plots beside the result file.")] = None,
    fmt: Annotated[str, typer.Option("--format", "-f", metavar="png|pdf|svg", help="Figure file format.")] = "png",
    only: Annotated[str | None, typer.Option(
        "--only", metavar="NAME,NAME,...",
        help="Make only these figures. Run figures: the mechanism's own (quick_return: crank_velocity, "
             "ram_displacement, ram_position_velocity, rocker_rod_angles, constraint_error, configurations), "
             "then coordinates, velocities, constraints, energy, multipliers, loads, mechanism. Comparison "
             "figures: constraint_errors, baumgarte_vs_sliding_mode, velocity_constraint_errors, "
             "motion_errors, work_precision_time, work_precision_nfev.")] = None,
    group: Annotated[str | None, typer.Option(
        "--group", "-g", metavar="METHOD",
        help="Plot one run of a comparison file (a method, or reference) with the figures of a single run.")] = None,
    dpi: Annotated[float, typer.Option("--dpi", help="Resolution of PNG figures, in dots per inch.")] = 150.0,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Draw the figures of a result or comparison file.

    A single run gives the figures its mechanism declares (for the
    quick-return mechanism the paper's H.2 to H.7), then coordinates,
    velocities, constraint residuals, energy balance, multipliers and
    loads. A comparison file gives the constraint error of every method
    (H.8, H.9), the motion error against the reference and, with a
    tolerance study, work-precision charts.

    Example: csim plot results/qr.h5 -o results/qr_plots --format pdf
    """
    from csim.plot import plot_file
    from csim.plot.files import parse_only

    out = output or result.parent / f"{result.stem}_plots"
    try:
        check_output_path(out, folder=True)
    except CsimError as exc:
        _fail_input(exc)
    if out.suffix.lower().lstrip(".") in ("png", "pdf", "svg", "jpg", "jpeg", "gif", "mp4") and not out.is_dir():
        _fail_input(ResultFileError(f"--output {out}: csim plot writes a folder of figures, one file per figure; "
                                    f"expected a folder name such as {out.with_suffix('')} (--format {fmt} sets "
                                    f"the files' type, --only NAME picks figures)"))
    try:
        report = plot_file(result, out, fmt=fmt, only=parse_only(only), group=group, dpi=dpi)
    except CsimError as exc:
        _fail_input(exc)
    if not quiet:
        for path in report.written:
            typer.echo(f"wrote {path}")
        for name, reason in report.skipped.items():
            typer.echo(f"skipped {name}: {reason}")


@app.command(cls=_Command)
@_interruptible
def export(
    result: Annotated[Path, typer.Argument(help="Result, comparison or sweep file (csim run, compare, sweep).",
                                           show_default=False, metavar="RESULT.h5")],
    fmt: Annotated[str, typer.Option("--format", "-f", metavar="csv|parquet",
                                     help="csv: the header gives each column's unit, 'q:q1 \\[rad]'; parquet: "
                                          "the units in the fields' metadata.")] = "csv",
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="DIR", help="Folder for the files, one per table and run. "
                                              "Default: RESULT_export beside the result file.")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Write a result file's tables and time series as CSV or Parquet files.

    One file per table (a comparison's summary and work_precision, a sweep's runs) and per
    run (one row per output time, a column per coordinate, constraint, load: q:q1, phi:1,
    ...), and per run's events. Needs the optional extra data (pandas; pyarrow for
    Parquet). In Python, csim.load(RESULT) reads the same file into xarray and pandas.

    Example: csim export results/qr.h5 --format parquet -o results/qr_tables
    """
    from csim.api import FORMATS
    from csim.api import export as write_tables

    if fmt not in FORMATS:
        _fail_input(CsimError(f"--format {fmt!r}: expected one of {', '.join(FORMATS)}"))
    out = output or result.parent / f"{result.stem}_export"
    try:
        check_output_path(out, folder=True)
        written = write_tables(result, out, fmt)
    except CsimError as exc:
        _fail_input(exc)
    except OSError as exc:
        _fail_input(ResultFileError(f"--output {out}: cannot write there ({exc.strerror or exc})"))
    if not quiet:
        for path in written:
            typer.echo(f"wrote {path}")


@app.command(cls=_Command)
def examples(
    folder: Annotated[Path, typer.Argument(help="Folder to copy the example cases into (created).",
                                           show_default=False, metavar="DIR")],
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Copy the example case files (and the batch manifest) into a folder.

    The cases of the documentation: the quick-return mechanism, the pendulum, Andrews'
    squeezing mechanism, the link-coupling examples and the stability maps, with the case
    schema as csim-case.schema.json beside them for editors. Files already there are never
    replaced (exit 2).

    Example: csim examples my_cases && csim run my_cases/quick_return.yaml
    """
    from csim.case import json_schema
    from csim.io.examples import copy_examples

    try:
        check_output_path(folder, option=None, folder=True)
        written = copy_examples(folder, json_schema())
    except CsimError as exc:
        _fail_input(exc)
    if not quiet:
        for path in written:
            typer.echo(f"wrote {path}")


@app.command(cls=_Command)
@_interruptible
def animate(
    result: Annotated[Path, typer.Argument(help="Result file (csim run), or a comparison file with --group.",
                                           show_default=False, metavar="RESULT.h5")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="FILE.gif",
        help="Animation file: .gif, or .mp4 when ffmpeg is on the PATH. Default: RESULT.gif beside the "
             "result file.")] = None,
    group: Annotated[str | None, typer.Option(
        "--group", "-g", metavar="METHOD", help="The run of a comparison file to animate (a method, or "
                                                "reference).")] = None,
    fps: Annotated[float, typer.Option("--fps", help="Frames per second.")] = 20.0,
    speed: Annotated[float, typer.Option(
        "--speed", help="Simulated seconds per second of animation (1: real time; a long run is sped up "
                        "to stay within --max-frames).")] = 1.0,
    max_frames: Annotated[int, typer.Option("--max-frames", help="At most this many frames (2 to 1,000; fewer "
                                                                 "at a --dpi over 100).")] = 300,
    dpi: Annotated[float, typer.Option("--dpi", help="Resolution, in dots per inch; the figure is 6.4 in "
                                                     "wide.")] = 100.0,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Animate the mechanism of a run: its links moving, drawn from its geometry, with the time.

    Example: csim animate results/qr.h5 -o results/qr.gif --speed 0.5
    """
    from csim.plot import animate_file

    out = output or result.with_suffix(".gif")
    try:
        check_output_path(out)
        animation = animate_file(result, out, group=group, fps=fps, speed=speed, max_frames=max_frames, dpi=dpi)
    except CsimError as exc:
        _fail_input(exc)
    if not quiet:
        typer.echo(f"wrote {out} ({len(animation)} frames at {fps:g} fps, {animation.speed:.3g}x real time)")


@app.command(cls=_Command)
@_interruptible
def describe(
    case: Annotated[Path, typer.Argument(help="Link-coupling case file (YAML). Example: configs/rrr3_planar.yaml",
                                         show_default=False, metavar="CASE.yaml")],
    latex: Annotated[bool, typer.Option("--latex", help="Print transforms and equations as LaTeX.")] = False,
    json_: Annotated[bool, typer.Option("--json", help="Print everything as JSON (joint_variables, "
                                        "constraints, dof, cut_joints, ...).")] = False,
    link: Annotated[list[int] | None, typer.Option("--link", "-l", metavar="N",
                                                   help="Show the global transform of link N; repeatable. "
                                                        "Default: every moving link.")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", metavar="KEY=VALUE", help=SET_HELP)] = None,
):
    """Show what csim derives from a link-coupling description: substructures, cut joints,
    joint variables, global transforms, independent constraint equations, DOF, reactions.

    Example: csim describe configs/rrr3_planar.yaml --link 7
    """
    from csim.describe import describe_main
    from csim.progress import reporting

    try:
        with reporting(True):  # a line on stderr for a step over a second (a long chain)
            text = describe_main(case, latex=latex, json=json_, links=link or None, overrides=set_ or [])
    except CsimError as exc:
        _fail_input(exc)
    typer.echo(text, nl=False)


@app.command(cls=_Command)
@_interruptible
def schema(
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="FILE.json",
        help="Write the schema to this file (JSON). Default: print it.")] = None,
):
    """Print the case-file schema as JSON Schema (draft-07, which editors support in full).

    Generated from csim's own schema: every key with its type, default, bounds, choices
    (mechanisms, integrators, methods, switching functions) and a description with its
    unit; the parameters, coordinates and loads of each registered mechanism; the
    link-coupling tables. With yaml-language-server (VS Code's YAML extension, ...), the
    first line of a case file, # yaml-language-server: $schema=PATH/csim-case.schema.json,
    turns on validation and completion.

    Example: csim schema -o csim-case.schema.json
    """
    import json

    from csim.case import json_schema

    text = json.dumps(json_schema(), indent=2) + "\n"
    if output is None:
        typer.echo(text, nl=False)
        return
    from csim.io.atomic import write_atomically

    try:
        check_writable(output, suffixes=(), option="--output")
        write_atomically(output, text.encode())
    except CsimError as exc:
        _fail_input(exc)
    except OSError as exc:
        _fail_input(ResultFileError(f"--output {output}: cannot write there ({exc.strerror or exc})"))


def main() -> None:
    """Console-script entry point.

    An expected error (:class:`csim.errors.CsimError`) that reaches it is printed as a message:
    exit 2 for bad input (:class:`~csim.errors.CaseError`), 1 for any other; ``CSIM_TRACEBACK=1``
    prints its traceback too, for a bug report. After Ctrl-C (exit 130) the process ends at once,
    without the interpreter's clean-up of its objects (up to half a second with a derived model
    loaded): every file is written and closed by then, and the user asked it to stop.
    """
    try:
        app(prog_name="csim")
    except CsimError as exc:  # one a command did not turn into its own message: still a message, not a traceback
        if os.environ.get("CSIM_TRACEBACK", "") not in ("", "0"):
            traceback.print_exc()
        if isinstance(exc, CaseError):
            for line in _input_lines(exc):
                typer.echo(line, err=True)
            sys.exit(EXIT_BAD_INPUT)
        typer.echo(f"csim: error: {exc}", err=True)
        sys.exit(EXIT_FAILED)
    except SystemExit as exc:
        if exc.code == EXIT_INTERRUPTED:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(EXIT_INTERRUPTED)
        raise


if __name__ == "__main__":
    main()
