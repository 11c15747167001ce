"""The compiled integration rows of the 10 s quick-return, in process, for side-by-side comparisons of two trees.

Run from a tree's root with that tree first on the path, alternating the trees::

    (cd OLD && PYTHONPATH=OLD python /path/to/bench/compiled_rows.py)
    (cd NEW && PYTHONPATH=NEW python bench/compiled_rows.py)

``python bench/compiled_rows.py ROW ...`` runs only the rows named (``ggl/Radau``, ...), e.g. to leave out a row
that an older tree runs on the Python path. Prints one JSON object: for each row ``method/integrator`` the median
over 9 runs of
``Result.wall_time`` [ms] (the integration, without loading the kernels), the backend, the
RHS evaluations (equal in both trees when the numerics are unchanged) and the status.
"""
from __future__ import annotations

import json
import statistics
import sys

from csim.case import load_case
from csim.pipeline import run_case

ROWS = [("projection", "DOP853", ["simulation.rtol=1e-9", "simulation.atol=1e-9"]),
        ("none", "DOP853", ["simulation.rtol=1e-10", "simulation.atol=1e-10"]),
        ("baumgarte", "DOP853", ["simulation.rtol=1e-10", "simulation.atol=1e-10"]),
        ("none", "RK4", ["simulation.step=1e-3"]),
        ("projection", "RK4", ["simulation.step=1e-3"]),
        ("minimal", "DOP853", ["simulation.rtol=1e-9", "simulation.atol=1e-9"]),
        ("projection", "Radau", ["simulation.rtol=1e-7", "simulation.atol=1e-7"]),
        ("ggl", "Radau", ["simulation.rtol=1e-7", "simulation.atol=1e-7"])]
REPEAT = 9


def main(names: list[str]) -> None:
    out = {}
    unknown = set(names) - {f"{method}/{integrator}" for method, integrator, _ in ROWS}
    if unknown:
        sys.exit(f"unknown rows {sorted(unknown)}; the rows are {[f'{m}/{i}' for m, i, _ in ROWS]}")
    for method, integrator, extra in ROWS:
        if names and f"{method}/{integrator}" not in names:
            continue
        overrides = [f"stabilization.method={method}", f"simulation.integrator={integrator}", "simulation.t_end=10",
                     "simulation.backend=auto", *extra]
        case = load_case("configs/quick_return.yaml", overrides=overrides)
        times = []
        for _ in range(REPEAT):
            result = run_case(case)
            times.append(result.wall_time)
        out[f"{method}/{integrator}"] = (round(statistics.median(times) * 1e3, 3), result.backend, int(result.nfev),
                                         result.status)
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1:])
