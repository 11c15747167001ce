"""The compiled integration rows of the 10 s quick-return, in process, for side-by-side comparisons of two trees.

Run from a tree's root with that tree first on the path, alternating the trees::

    (cd OLD && PYTHONPATH=OLD python /path/to/bench/compiled_rows.py)
    (cd NEW && PYTHONPATH=NEW python bench/compiled_rows.py)

Prints one JSON object: for each row ``method/integrator`` the median over 9 runs of
``Result.wall_time`` [ms] (the integration, without loading the kernels), the backend, the
RHS evaluations (equal in both trees when the numerics are unchanged) and the status.
"""
from __future__ import annotations

import json
import statistics

from csim.case import load_case
from csim.pipeline import run_case

ROWS = [("projection", "DOP853", ["simulation.rtol=1e-9", "simulation.atol=1e-9"]),
        ("none", "DOP853", ["simulation.rtol=1e-10", "simulation.atol=1e-10"]),
        ("baumgarte", "DOP853", ["simulation.rtol=1e-10", "simulation.atol=1e-10"]),
        ("none", "RK4", ["simulation.step=1e-3"]),
        ("projection", "RK4", ["simulation.step=1e-3"]),
        ("minimal", "DOP853", ["simulation.rtol=1e-9", "simulation.atol=1e-9"])]
REPEAT = 9


def main() -> None:
    out = {}
    for method, integrator, extra in ROWS:
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
    main()
