"""Compile the kernels once for this installation: ``python -m csim.warmup`` (``make install``).

Runs the default case for a few steps with the compiled backend, once with a method of the
plain kernels and once with ``minimal`` (the partitioned copy), so that numba compiles both
copies into :func:`csim.model.cache.kernels_dir` and no later command, test session
included, waits for them. Exits 0 with a note when numba or the compiled backend is not
available (csim then runs on the Python path).
"""
from __future__ import annotations

import sys
import time


def main() -> int:
    from csim.case import load_case
    from csim.fast.support import numba_available
    from csim.io.examples import examples_dir
    from csim.model.cache import kernels_dir
    from csim.pipeline import run_case

    if not numba_available():
        print("csim: numba is not installed; csim runs on the Python path (nothing to compile)")
        return 0
    start = time.perf_counter()
    print(f"csim: compiling the kernels into {kernels_dir()} (once per installation; minutes on 2 cores) ...",
          flush=True)
    for method in ("none", "minimal"):
        settings = ["simulation.t_end=0.01", "simulation.backend=compiled", f"stabilization.method={method}"]
        result = run_case(load_case(examples_dir() / "quick_return.yaml", settings))
        if result.backend != "compiled" or not result.ok:
            print(f"csim: the compiled backend did not run ({method}): {result.message}", file=sys.stderr)
            return 1
    print(f"csim: kernels ready ({time.perf_counter() - start:.0f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
