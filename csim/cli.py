"""Command-line interface: a thin layer over :mod:`csim.pipeline` and :mod:`csim.io`.

Exit codes: 0 success; 1 the simulation ran but failed (the result file says why);
2 bad input (case file, option or result file), reported without a traceback.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path
from typing import Annotated

import typer

from csim import __version__
from csim.errors import CaseError, CsimError, ResultFileError

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    help="csim: simulate constrained multibody mechanisms from YAML case files.\n\n"
         "Example: csim run configs/quick_return.yaml -o results/quick_return.h5",
)

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


def _fail_input(exc: CsimError) -> None:
    lines = exc.problems if isinstance(exc, CaseError) else [str(exc)]
    typer.echo(f"csim: error: {len(lines)} problem(s):" if len(lines) > 1 else "csim: error:", err=True)
    for line in lines:
        typer.echo(f"  {line}", err=True)
    raise typer.Exit(EXIT_BAD_INPUT)


def check_writable(out: Path, protect: list[Path] = ()) -> None:
    """Fail before a run, not after it, when the result file cannot be written.

    Creates the output's folder, tries a scratch file in it, and refuses to overwrite the
    input files in ``protect``.
    """
    if out.exists() and any(out.resolve() == p.resolve() for p in protect):
        raise ResultFileError(f"--output {out}: that is an input file; choose another result path")
    if out.is_dir():
        raise ResultFileError(f"--output {out}: cannot write, it is a directory")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as exc:
        raise ResultFileError(f"--output {out}: cannot write there ({exc.strerror or exc})") from None


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


@app.command()
def run(
    case: Annotated[Path, typer.Argument(help="Case file (YAML). Example: configs/quick_return.yaml",
                                         show_default=False, metavar="CASE.yaml")],
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", metavar="OUT.h5", help="Result file (HDF5), written atomically. Default: results/CASE.h5. "
                               "Example: -o out/qr.h5")] = None,
    set_: Annotated[list[str] | None, typer.Option("--set", "-s", metavar="KEY=VALUE", help=SET_HELP)] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors; no progress bar.")] = False,
):
    """Simulate one case and write its result file.

    Finds consistent initial conditions by Newton-Raphson, integrates, writes HDF5 and
    prints a summary (final state, constraint errors, energy balance, cost).

    Example: csim run configs/quick_return.yaml -o results/qr.h5 --set simulation.t_end=10
    """
    from csim.case import load_case
    from csim.io.hdf5 import write_result
    from csim.pipeline import run_case
    from csim.progress import ProgressBar

    try:
        c = load_case(case, set_ or [])
    except CsimError as exc:
        _fail_input(exc)
    out = output or Path("results") / f"{case.stem}.h5"
    try:
        check_writable(out, protect=[case])
    except CsimError as exc:
        _fail_input(exc)
    bar = ProgressBar.for_terminal(c.data["simulation"]["t_end"], quiet)
    try:
        result = run_case(c, progress=bar)
    finally:
        bar.close()
    try:
        write_result(out, result, c.mechanism.coordinate_units)
    except OSError as exc:  # e.g. the disk filled up during the run
        typer.echo(f"csim: error: cannot write {out}: {exc}", err=True)
        raise typer.Exit(EXIT_BAD_INPUT) from None
    if not quiet:
        typer.echo(f"case:              {case}")
        typer.echo(result.summary())
        typer.echo(f"result:            {out}")
    if not result.ok:
        typer.echo(f"csim: simulation failed: {result.message} (partial result in {out})", err=True)
        raise typer.Exit(EXIT_FAILED)


@app.command()
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
        help="Comparison file (HDF5), written atomically: one group per method. "
             "Default: results/CASE_compare.h5")] = None,
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
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors.")] = False,
):
    """Run one case with several stabilization methods and compare them.

    Each method runs the same case (stabilization.method set to it), in
    parallel processes. A tight reference run (projection, DOP853,
    rtol = atol = 1e-12) measures the error of the motion. One row per
    method: max |Phi|, final |Phi|, max |Phi_q qd|, motion error against
    the reference, wall time, RHS evaluations and status. With
    --tolerances, each method runs at each tolerance (work-precision).

    Exit codes: 0 every run succeeded; 1 a run failed (the file is still
    written); 2 bad input.

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
    if problems:
        _fail_input(CaseError(problems))
    out = output or Path("results") / f"{case.stem}_compare.h5"
    progress = None
    if not quiet and sys.stderr.isatty():
        def progress(run, done, total):
            typer.echo(f"[{done}/{total}] {run.method} {run.tolerance:g}: {run.status} "
                       f"({run.wall_time:.2f} s)", err=True)
    try:
        check_writable(out, protect=[case])
        comparison = run_comparison(case, methods=method_list, tolerances=tol_list, overrides=set_ or [],
                                    reference=ReferenceSettings(method=reference_method, tol=ref_tol[0]),
                                    jobs=jobs, progress=progress)
    except CsimError as exc:
        _fail_input(exc)
    try:
        comparison.write(out)
    except OSError as exc:
        typer.echo(f"csim: error: cannot write {out}: {exc}", err=True)
        raise typer.Exit(EXIT_BAD_INPUT) from None
    if not quiet:
        typer.echo(comparison.table())
        typer.echo(f"\nresult:     {out}")
    if not comparison.ok:
        failed = comparison.failed
        names = ", ".join(comparison.label(r) for r in failed)
        what = "interrupted" if comparison.interrupted else f"{len(failed)} run(s) failed: {names}"
        typer.echo(f"csim: comparison incomplete, {what} (results in {out})", err=True)
        raise typer.Exit(EXIT_FAILED)


@app.command()
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
        report = plot_file(result, out, fmt=fmt, only=parse_only(only), group=group, dpi=dpi)
    except CsimError as exc:
        _fail_input(exc)
    if not quiet:
        for path in report.written:
            typer.echo(f"wrote {path}")
        for name, reason in report.skipped.items():
            typer.echo(f"skipped {name}: {reason}")


@app.command()
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
    max_frames: Annotated[int, typer.Option("--max-frames", help="At most this many frames.")] = 300,
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
        animation = animate_file(result, out, group=group, fps=fps, speed=speed, max_frames=max_frames, dpi=dpi)
    except CsimError as exc:
        _fail_input(exc)
    if not quiet:
        typer.echo(f"wrote {out} ({len(animation)} frames at {fps:g} fps, {animation.speed:.3g}x real time)")


@app.command()
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
    from csim.linkage.describe import describe_main

    try:
        text = describe_main(case, latex=latex, json=json_, links=link or None, overrides=set_ or [])
    except CsimError as exc:
        _fail_input(exc)
    typer.echo(text, nl=False)


def main() -> None:
    """Console-script entry point."""
    app(prog_name="csim")


if __name__ == "__main__":
    main()
