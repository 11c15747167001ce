"""Where the kernels' cold compile goes: numba's compile time of each function, and of each file.

Compiles the copy of the kernels (:mod:`csim.fast.kernels`) into a new, empty cache, by a short
compiled run of the quick-return (its loop, right-hand side and samples' evaluation), and
records numba's ``numba:compile`` events: the time of each function's compile less the
compiles nested in it (exclusive), summed by function and by the kernels' file (``system``,
``radau``, ...; the core's functions under their module's name). Also the time spent holding
LLVM's lock (optimization and machine code)::

    python bench/compile_profile.py                 # a run with the method none
    python bench/compile_profile.py --minimal       # a run with minimal (the same copy, the same functions)

The core's own functions (:mod:`csim.physics`, the method files) are cached beside their
sources, where an earlier run may have left them: compiled already, they are not in the
figures. Minutes on 2 cores; one process, one core.
"""
from __future__ import annotations

import argparse
import atexit
import collections
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _name(event) -> str:
    """``file:function`` for a function of the kernels' copy (``system:rhs``), else ``module:function``
    (``csim.physics.events:check_chatter``, numba's own ``numba.np.arrayobj:ol_np_empty.<locals>.impl``)."""
    fn = getattr(event.data.get("dispatcher"), "py_func", None)
    if fn is None:
        return "?"
    module = fn.__module__
    if module.startswith("csim_fast_kernels"):
        module = module.split(".", 1)[-1]
    return f"{module}:{fn.__qualname__}"


def exclusive_times(buffer) -> dict[str, float]:
    """Seconds per function from numba's ``numba:compile`` (timestamp, event) pairs, nested compiles left out."""
    stack, out = [], collections.Counter()
    for stamp, event in buffer:
        if event.is_start:
            stack.append([_name(event), stamp, 0.0])
            continue
        name, start, nested = stack.pop()
        out[name] += stamp - start - nested
        if stack:
            stack[-1][2] += stamp - start
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minimal", action="store_true", help="run with minimal instead of none")
    parser.add_argument("--top", type=int, default=25, help="functions to list")
    options = parser.parse_args()
    cache = tempfile.mkdtemp(prefix="csim-compile-profile-")
    atexit.register(shutil.rmtree, cache, ignore_errors=True)
    os.environ["CSIM_CACHE_DIR"] = cache
    os.environ.pop("CSIM_KERNELS_DIR", None)
    sys.path.insert(0, str(ROOT))
    from numba.core import event

    from csim.case import load_case
    from csim.pipeline import run_case

    method = "minimal" if options.minimal else "none"
    case = load_case(ROOT / "configs" / "quick_return.yaml", overrides=[
        "simulation.t_end=0.01", "simulation.backend=compiled", f"stabilization.method={method}"])
    with event.install_recorder("numba:compile") as compiles, event.install_recorder("numba:llvm_lock") as llvm:
        start = time.perf_counter()
        result = run_case(case)
        wall = time.perf_counter() - start
    if result.backend != "compiled":
        raise SystemExit(f"the run did not compile the kernels: {result.message}")
    stamps = [stamp for stamp, _ in llvm.buffer]
    locked = sum(b - a for a, b in zip(stamps[::2], stamps[1::2]))
    by_function = exclusive_times(compiles.buffer)
    by_file = collections.Counter()
    for name, seconds in by_function.items():
        by_file[name.split(":", 1)[0]] += seconds
    print(f"{method}: the run {wall:.1f} s, numba compiling {sum(by_function.values()):.1f} s "
          f"(LLVM {locked:.1f} s), {len(by_function)} functions")
    print("\nby file [s]")
    for name, seconds in by_file.most_common():
        print(f"  {seconds:7.2f}  {name}")
    print(f"\nby function, the {options.top} longest [s]")
    for name, seconds in by_function.most_common(options.top):
        print(f"  {seconds:7.2f}  {name}")


if __name__ == "__main__":
    main()
