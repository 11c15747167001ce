"""The kernels compiled once per installation against a mechanism-specific module, side by side.

Run as ``python bench/before_after.py --before DIR`` where DIR is a source tree of the
version to compare with (e.g. ``git archive <commit> | tar -x -C DIR``). Each tree gets its
own cache directory, warmed first (the quick-return compiled, as on an installation that
has run once). Then, alternating between the trees, each in fresh processes:

a. the first run of a new mechanism end to end on that warm installation: ``csim run
   CONFIG`` after removing only that mechanism's entries from the cache (every file whose
   name holds the mechanism's name);
b. the cost of one KKT right-hand-side evaluation of the quick-return, compiled, against
   plain C generated from the same derivation (``bench/run.py``'s ``rhs_costs``);
c. the 10 s quick-return run of ``bench/run.py``'s 20 ms target row (projection, DOP853,
   rtol = atol = 1e-9): the integration's wall time, median of 5.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

AFTER = Path(__file__).resolve().parent.parent

PROBE = r"""
import json, sys
sys.path[:0] = ["{tree}", "{tree}/bench", "{tree}/tests"]
import run as bench
from quick_return_reference import MinimalQuickReturn
what = sys.argv[1]
if what == "rhs":
    numba_ns, c_ns, _, _ = bench.rhs_costs(1_000_000)
    print(json.dumps(dict(compiled=numba_ns, c=c_ns)))
else:
    _, y_ref, _ = MinimalQuickReturn().solve(t_end=10.0, rtol=1e-13, atol=1e-13)
    bench.measure("none", "DOP853", 1e-6, 0.1, "compiled", 1, y_ref[-1, 0])
    row = bench.measure(*bench.TARGET, 10.0, "compiled", 5, y_ref[-1, 0])
    print(json.dumps(dict(wall=row["wall"], nfev=row["nfev"], err=row["err"])))
"""


def _env(tree: Path, cache: Path) -> dict:
    return dict(os.environ, PYTHONPATH=str(tree), CSIM_CACHE_DIR=str(cache))


def csim_run(tree: Path, cache: Path, config: str, out: Path) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "csim", "run", str(tree / "configs" / config), "-o", str(out), "--quiet",
                    "--set", "simulation.backend=compiled"], check=True, env=_env(tree, cache), cwd=tree,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def forget(cache: Path, mechanism: str) -> int:
    """Remove the cache entries of one mechanism (files whose name holds its name); returns how many."""
    gone = [p for p in cache.rglob(f"*{mechanism}*") if p.is_file()]
    for p in gone:
        p.unlink()
    return len(gone)


def probe(tree: Path, cache: Path, what: str) -> dict:
    out = subprocess.run([sys.executable, "-c", PROBE.replace("{tree}", str(tree)), what], check=True,
                         env=_env(tree, cache), capture_output=True, text=True, cwd=tree).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", type=Path, required=True, help="source tree of the version to compare with")
    parser.add_argument("--after", type=Path, default=AFTER, help="source tree of this version (default: here)")
    parser.add_argument("--config", default="fourbar_gravity.yaml", help="the new mechanism of (a)")
    parser.add_argument("--mechanism", default="fourbar", help="its name in the cache's file names")
    parser.add_argument("--repeat", type=int, default=2, help="first runs per tree in (a)")
    args = parser.parse_args(argv)
    trees = {"before": args.before.resolve(), "after": args.after.resolve()}
    with tempfile.TemporaryDirectory() as tmp:
        caches = {name: Path(tmp) / f"cache-{name}" for name in trees}
        out = Path(tmp) / "out.h5"
        for name, tree in trees.items():  # a warm installation: the quick-return has run
            warm = csim_run(tree, caches[name], "quick_return.yaml", out)
            print(f"warming {name}: csim run quick_return.yaml {warm:.1f} s", flush=True)
        first = {name: [] for name in trees}
        for _ in range(args.repeat):
            for name, tree in trees.items():
                forget(caches[name], args.mechanism)
                first[name].append(csim_run(tree, caches[name], args.config, out))
        again = {name: csim_run(tree, caches[name], args.config, out) for name, tree in trees.items()}
        rhs = {name: probe(tree, caches[name], "rhs") for name, tree in trees.items()}
        target = {name: probe(tree, caches[name], "target") for name, tree in trees.items()}
    print(f"\n{'':<60}{'before':>14}{'after':>14}")
    row = lambda label, b, a: print(f"{label:<60}{b:>14}{a:>14}")  # noqa: E731
    row(f"(a) first csim run {args.config}, warm install [s]", *(", ".join(f"{v:.2f}" for v in first[n])
                                                                for n in trees))
    row("    second run (all cached) [s]", *(f"{again[n]:.2f}" for n in trees))
    row("(b) quick-return RHS, compiled [ns]", *(f"{rhs[n]['compiled']:.0f}" for n in trees))
    row("    plain C, same run [ns]", *(f"{rhs[n]['c']:.0f}" for n in trees))
    row("    compiled / C", *(f"{rhs[n]['compiled'] / rhs[n]['c']:.2f}" for n in trees))
    row("(c) 10 s quick-return, projection DOP853 1e-9 [ms]", *(f"{target[n]['wall'] * 1e3:.2f}" for n in trees))
    row("    RHS evaluations", *(f"{target[n]['nfev']}" for n in trees))
    print(f"\n(c) after / before = {target['after']['wall'] / target['before']['wall']:.2f}; "
          f"(a) median first run after / before = "
          f"{statistics.median(first['after']) / statistics.median(first['before']):.2f}")


if __name__ == "__main__":
    main()
