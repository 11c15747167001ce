"""Command-line interface: a thin layer over :mod:`csim.pipeline` and :mod:`csim.io`.

Exit codes: 0 success; 1 the simulation ran but failed (the result file says why);
2 bad input (case file, option or result file), reported without a traceback.
"""
from __future__ import annotations

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


def main() -> None:
    """Console-script entry point."""
    app(prog_name="csim")


if __name__ == "__main__":
    main()
