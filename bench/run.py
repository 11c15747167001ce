"""Speed and accuracy of csim on the quick-return mechanism, measured side by side.

Run with ``make bench``. Prints one row per (formulation, integrator, tolerance): median
wall time of the integration over several runs, right-hand-side evaluations, the error of
the crank angle at t_end against a tight-tolerance reference run (DOP853, rtol = atol =
1e-12, events located), and the largest constraint residual max |Phi|.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from csim.case import load_case  # noqa: E402
from csim.pipeline import run_case  # noqa: E402

CASE = ROOT / "configs" / "quick_return.yaml"

#: (formulation, integrator, tolerance or step)
MATRIX = [
    ("kkt", "DOP853", 1e-6), ("kkt", "DOP853", 1e-8), ("kkt", "DOP853", 1e-10),
    ("elimination", "DOP853", 1e-10),
    ("kkt", "RK45", 1e-8), ("kkt", "Radau", 1e-8), ("kkt", "LSODA", 1e-8),
    ("kkt", "RK4", 1e-3), ("kkt", "RK4", 2.5e-4),
]


def case_for(formulation, integrator, tol, t_end):
    sets = [f"formulation.method={formulation}", f"simulation.integrator={integrator}", f"simulation.t_end={t_end}"]
    if integrator == "RK4":
        sets.append(f"simulation.step={tol}")
    else:
        sets += [f"simulation.rtol={tol}", f"simulation.atol={tol}"]
    return load_case(CASE, sets)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per row (the median is reported)")
    parser.add_argument("--t-end", type=float, default=5.0, help="simulated time [s]")
    args = parser.parse_args(argv)

    run_case(case_for("kkt", "DOP853", 1e-6, 0.1))  # build and cache the model before timing
    ref = run_case(load_case(CASE, ["simulation.rtol=1e-12", "simulation.atol=1e-12",
                                    f"simulation.t_end={args.t_end}"]))
    print(f"quick_return, t_end = {args.t_end:g} s, median of {args.repeat} runs")
    header = f"{'formulation':<12} {'integrator':<8} {'tol/step':>9} {'wall [s]':>9} {'RHS evals':>10} " \
             f"{'|q1 err| [rad]':>15} {'max|Phi|':>10} status"
    print(header)
    print("-" * len(header))
    for formulation, integrator, tol in MATRIX:
        case = case_for(formulation, integrator, tol, args.t_end)
        times, result = [], None
        for _ in range(args.repeat):
            start = time.perf_counter()
            result = run_case(case)
            times.append(time.perf_counter() - start)
        err = abs(result.q[-1, 0] - ref.q[-1, 0]) if result.ok else float("nan")
        print(f"{formulation:<12} {integrator:<8} {tol:>9.1e} {statistics.median(times):>9.3f} {result.nfev:>10d} "
              f"{err:>15.2e} {result.max_phi:>10.2e} {result.status}")


if __name__ == "__main__":
    main()
