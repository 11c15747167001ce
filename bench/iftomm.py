"""The IFToMM benchmark problems (configs/iftomm/): error, tolerance, integration and whole-process time.

Run with ``make bench`` (after bench/run.py) or ``python bench/iftomm.py [--repeat N]``. For each
shipped case: the benchmark's error against a motion computed independently of csim
(tests/iftomm_reference.py; Andrews: the IVP test set's solution; Bricard: the energy balance,
having no closed form; the governor: Lagrange's equations in the rotating frame), the median
integration time over ``--repeat`` warm runs in this process
(``Result.wall_time``: the integration and the evaluation of the samples), and the median
whole-process time of ``csim run CASE`` (warm cache), beside the CPU times of the OpenSim
reproduction of the benchmark (rehabenggroup.github.io/MBSbenchmarksInOpenSim, Intel i5-4570).
The first run of each case (derivation, compilation) is not timed.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from iftomm_reference import a01_point, a02_b0, a05_motion  # noqa: E402
from test_andrews import Q_END  # noqa: E402

from csim.case import load_case  # noqa: E402
from csim.pipeline import run_case  # noqa: E402

IFTOMM = ROOT / "configs" / "iftomm"
CSIM = str(Path(sys.executable).with_name("csim"))


def a01_error(r):
    return float(np.max(np.hypot(*(r.q - a01_point(r.t)).T))), "m (largest P1 distance)"


def a02_error(n):
    def error(r):
        p, _ = a02_b0(r.t, n)
        th = r.q[:, 0]
        return float(np.max(np.hypot(np.cos(th) - p[:, 0], np.sin(th) - p[:, 1]))), "m (largest B0 distance)"
    return error


#: the test set's coordinates (beta, Theta, gamma, Phi, delta, Omega, epsilon) as joint variables of the tables
A03_VARIABLES = ["q_O", "q_F", "q_B", "q_G", "q_AG", "q_H", "q_AH"]


def a03_error(r):
    q = r.q[-1, [r.coordinate_names.index(n) for n in A03_VARIABLES]]
    return float(np.max(np.abs(q - Q_END) / np.abs(Q_END))), "relative, q(0.03 s)"


def a04_error(r):
    return float(r.energy_error_relative), "relative energy balance (no closed form)"


def a05_error(r):
    s = r.q[:, r.coordinate_names.index("s_slide")]
    return float(np.max(np.abs(s - a05_motion(r.t)[0][:, 0]))), "m (largest slider error)"


#: (problem, case file, error, tolerance, OpenSim CPU time [s] or None, what that time is for)
CASES = [
    ("A01 pendulum, 2000 s", "a01_pendulum.yaml", a01_error, 1e-3, 0.637, "10 s"),
    ("A02 N-four-bar, N = 2", "a02_n_four_bar_2.yaml", a02_error(2), 1e-3, 0.455, "20 s"),
    ("A03 Andrews", "a03_andrews.yaml", a03_error, 1e-6, 0.384, "0.03 s"),
    ("A04 Bricard, 10 s", "a04_bricard.yaml", a04_error, 1e-6, 0.258, "10 s"),
    ("A05 flyball governor, 10 s", "a05_flyball_governor.yaml", a05_error, 1e-3, 0.233, "10 s"),
]


def whole_process(path: Path, repeat: int) -> float:
    """Median wall time of ``csim run PATH`` in a new process (warm cache) [s]."""
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(repeat):
            start = time.perf_counter()
            subprocess.run([CSIM, "run", str(path), "-o", str(Path(tmp) / "out.h5")],
                           check=False, capture_output=True)
            times.append(time.perf_counter() - start)
    return statistics.median(times)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per case (median)")
    parser.add_argument("--cases", nargs="*", default=None, help="case files to run (default: all shipped)")
    args = parser.parse_args(argv)
    print("| problem | method | error | tolerance | integration [s] | csim run [s] | OpenSim CPU [s] |")
    print("|---|---|---|---|---|---|---|")
    for name, file, error, tol, opensim, span in CASES:
        if args.cases and file not in args.cases:
            continue
        case = load_case(IFTOMM / file)
        result = run_case(case)  # derivation, compilation: not timed
        runs = [run_case(case) for _ in range(args.repeat)]
        err, what = error(runs[-1])
        method = f"{case.stabilization.method} {case.simulation.integrator} ({runs[-1].backend})"
        wall = statistics.median(r.wall_time for r in runs)
        process = whole_process(IFTOMM / file, args.repeat)
        ok = "" if runs[-1].status == "success" and err <= tol else " FAILED"
        print(f"| {name} | {method} | {err:.2g} {what}{ok} | {tol:g} | {wall:.3f} | {process:.2f} | "
              f"{opensim} ({span}) |")
        del result


if __name__ == "__main__":
    main()
