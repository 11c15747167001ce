"""Shared fixtures: the quick-return case, its numeric model, and a private model cache."""
from __future__ import annotations

import signal
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"


@pytest.fixture(scope="session", autouse=True)
def _cache_dir(tmp_path_factory):
    """Keep generated model code of the test run out of the user's cache.

    The compiled kernels are the installation's (``csim.model.cache.kernels_dir`` as the
    user's environment gives it, which ``make install`` fills): they do not depend on any
    mechanism and are filed under the hash of their sources and versions, so the test
    session loads them instead of compiling them again (two to five minutes on 2 cores).
    ``CSIM_TEST_CACHE_DIR`` names a cache to reuse across test sessions instead (its files
    are filed under hashes of their sources, so an edit never reuses a stale copy), the
    kernels included.
    """
    import os

    from csim.model.cache import kernels_dir

    saved = {key: os.environ.get(key) for key in ("CSIM_CACHE_DIR", "CSIM_KERNELS_DIR")}
    shared = os.environ.get("CSIM_TEST_CACHE_DIR")
    if not shared:
        os.environ["CSIM_KERNELS_DIR"] = str(kernels_dir())
    os.environ["CSIM_CACHE_DIR"] = shared or str(tmp_path_factory.mktemp("csim-cache"))
    yield
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope="session")
def qr_model(_cache_dir):
    from csim.mechanisms import get_mechanism
    from csim.model import build_numeric_model

    return build_numeric_model(get_mechanism("quick_return"))


@pytest.fixture(scope="session")
def qr_par(qr_model):
    return qr_model.parameter_vector()


@pytest.fixture(scope="session")
def reference():
    """The minimal-coordinate reference solution at t = 5 s (and its event times)."""
    from quick_return_reference import MinimalQuickReturn

    t, y, events = MinimalQuickReturn().solve(t_end=5.0)
    return dict(q1=y[-1, 0], qd1=y[-1, 1], events=events)


def qr_case(*overrides: str):
    """The default quick-return case with ``--set``-style overrides."""
    from csim.case import load_case

    return load_case(CONFIGS / "quick_return.yaml", list(overrides))


def simulated_file(tmp_path_factory, config: str, name: str, *overrides: str) -> Path:
    """Run ``configs/CONFIG`` with overrides and write its result file in a temporary folder."""
    from csim.case import load_case
    from csim.io.hdf5 import write_result
    from csim.pipeline import run_case

    case = load_case(CONFIGS / config, list(overrides))
    path = tmp_path_factory.mktemp("run") / name
    write_result(path, run_case(case), case.mechanism.coordinate_units)
    return path


def invoke(*args):
    """Run the csim command line in process with ``args`` (converted to str)."""
    from typer.testing import CliRunner

    from csim.cli import app

    return CliRunner().invoke(app, [str(a) for a in args])


def assert_bad_input(result, *fragments):
    """Exit 2 through csim's own handling, no traceback, the message naming the problem."""
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exc_info
    assert "Traceback" not in result.output
    for fragment in fragments:
        assert fragment in result.output, result.output


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler (KeyboardInterrupt) during a test, as in csim started at a terminal.

    A pytest started in the background by a non-interactive shell (``pytest &`` in a script)
    inherits SIGINT ignored (POSIX), Python then keeps SIG_IGN, and a test that raises SIGINT
    to stand for Ctrl-C would see nothing happen.
    """
    old = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old if old is not None else signal.SIG_DFL)
