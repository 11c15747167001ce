"""How csim scales with mechanism size: the scaling table of issue 12.

Run with ``make bench-scaling`` (``python bench/scaling.py --help`` for options). Two
link-coupling families, generated as case documents by bench/scaling_cases.py (planar, R
joints, uniform bars under gravity, released at rest):

* ``chain N``: a chain of N four-bar loops, each sharing its rocker with the next loop's
  crank: 1 DOF for every N, 2N + 1 joint variables, 2N constraints;
* ``loop N``: one closed planar loop of N links, the ground included: N - 1 joint
  variables, 2 constraints, N - 3 DOF.

For each size, every step in a fresh process with a fresh ``CSIM_CACHE_DIR`` into which the
compiled generic kernels (``<cache>/fast/kernels_<key>/`` and numba's machine code next to
it, csim.fast.module) are copied from the installation's cache, so that only the
per-mechanism cost is measured:

(a) ``derive``: the case's linkage analysis (``analyse``: tree, transforms, constraints, rank
    checks), the symbolic derivation (csim.model.derive) and code generation (the Python
    source of the numeric model and the C source of the model functions);
(b) ``cc``: compiling that C source as csim does (csim.fast.module._load_c);
(c) ``first run``: ``csim run CASE -o x.h5 --quiet --set simulation.t_end=0.1`` end to end,
    in another fresh cache (the new user's first run: derivation, cc, integration);
(d) ``RHS``: one compiled right-hand-side evaluation (the kernels' ``rhs_repeat``, KKT,
    stabilization none), in the cache the first run filled;
(e) with ``--plain-c``: the same right-hand side as plain C generated from the same
    derivation (bench/c_rhs.py), and the ratio (d)/(e).

Each step has a time limit (``--limit``, 120 s); a size that does not finish is shown as
``> limit`` and the family's larger sizes are skipped. The growth of derive and RHS time is
fitted as a power law c N^p (least squares in log-log) over the sizes that finished.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

import yaml  # noqa: E402
from scaling_cases import fourbar_chain, nbar_loop  # noqa: E402

FAMILIES = {"chain": fourbar_chain, "loop": nbar_loop}
DEFAULT_SIZES = {"chain": [1, 2, 4, 8, 16, 32], "loop": [4, 5, 6, 8, 12]}
ENV = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))


# ---------------------------------------------------------------------------------------
# the steps, each run in its own process (python bench/scaling.py --worker STEP CASE)
# ---------------------------------------------------------------------------------------
def worker_derive(case_path: str) -> dict:
    """(a) and (b): linkage analysis, derivation, code generation, then cc on the C source."""
    from csim.case import load_case
    from csim.fast.ccodegen import CFLAGS, c_source
    from csim.fast.module import c_compiler
    from csim.model.codegen import generate_source
    from csim.model.derive import derive

    t0 = time.perf_counter()
    case = load_case(case_path)
    t1 = time.perf_counter()
    derived = derive(case.mechanism)
    t2 = time.perf_counter()
    generate_source(derived)
    source = c_source(derived)
    t3 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        src, out = Path(tmp) / "model.c", Path(tmp) / "model.so"
        src.write_text(source)
        subprocess.run([c_compiler(), *CFLAGS, "-o", str(out), str(src), "-lm"], check=True)
    t4 = time.perf_counter()
    return dict(analyse=t1 - t0, derive_only=t2 - t1, codegen=t3 - t2, derive=t3 - t0, cc=t4 - t3,
                c_lines=source.count("\n"))


def worker_rhs(case_path: str) -> dict:
    """(d): ns per compiled right-hand-side evaluation, and the sizes."""
    from run import compiled_rhs  # bench/run.py (this folder)

    from csim.case import load_case

    system, y, mode, mod, (par, pf, pi) = compiled_rhs(load_case(case_path))
    n = 100
    while True:  # aim at about 0.2 s per timing loop
        start = time.perf_counter()
        mod.rhs_repeat(y, mode, par, pf, pi, n)
        wall = time.perf_counter() - start
        if wall > 0.05:
            break
        n *= 4
    n = max(n, int(n * 0.2 / wall))
    runs = []
    for _ in range(3):
        start = time.perf_counter()
        mod.rhs_repeat(y, mode, par, pf, pi, n)
        runs.append((time.perf_counter() - start) / n)
    return dict(rhs_ns=min(runs) * 1e9, m=system.m, r=system.r)


def worker_plain_c(case_path: str) -> dict:
    """(e), with ``--plain-c``: ns per evaluation of the same KKT right-hand side as plain C
    generated from the same derivation (bench/c_rhs.py), checked against the Python one."""
    import c_rhs
    import numpy as np
    from run import compiled_rhs

    from csim.case import load_case

    system, y, mode, mod, (par, pf, pi) = compiled_rhs(load_case(case_path))
    start = time.perf_counter()
    mod.rhs_repeat(y, mode, par, pf, pi, 100)
    n_eval = max(1000, int(0.3 / max((time.perf_counter() - start) / 100, 1e-9)))
    exe, tmp = c_rhs.build(system.model.definition, y, system.par, system.loads.values(mode), n_eval)
    try:
        runs = [c_rhs.run(exe) for _ in range(3)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    qdd_py = system.rhs(0.0, y, mode)[system.m:2 * system.m]
    diff = float(np.max(np.abs(runs[0][1] - qdd_py)))
    if not diff <= 1e-9 * max(1.0, float(np.max(np.abs(qdd_py)))):
        raise SystemExit(f"bench: the plain-C right-hand side differs from the Python one by {diff:.3g}")
    return dict(plain_c_ns=min(r[0] for r in runs))


WORKERS = {"derive": worker_derive, "rhs": worker_rhs, "plain_c": worker_plain_c}


# ---------------------------------------------------------------------------------------
# the driver
# ---------------------------------------------------------------------------------------
def installation_cache() -> Path:
    from csim.model.cache import cache_dir

    return cache_dir()


def kernel_files(cache: Path) -> list[Path]:
    """The compiled kernels in ``cache``: the package's copy and numba's files of it."""
    from csim.fast.module import kernels_key

    copy = cache / "fast" / f"kernels_{kernels_key()}"
    return [p for p in [*sorted(copy.glob("*.py")), *sorted((copy / "__pycache__").glob("*.nb[ic]"))] if p.is_file()]


def warm_installation(cache: Path, tmp: Path, limit: float) -> None:
    """Compile the kernels into the installation's cache if they are not there (once per installation)."""
    files = kernel_files(cache)
    if any(p.suffix == ".nbi" and ".integrate-" in p.name for p in files) and \
            any(".rhs_repeat-" in p.name for p in files):
        return
    print(f"compiling the generic kernels into {cache} (once per installation) ...", flush=True)
    path = write_case(fourbar_chain(1), tmp / "warm.yaml")
    env = dict(ENV, CSIM_CACHE_DIR=str(cache))
    subprocess.run([sys.executable, "-m", "csim", "run", str(path), "-o", str(tmp / "warm.h5"), "--quiet"],
                   check=True, env=env, stdout=subprocess.DEVNULL, timeout=30 * limit)
    run_worker("rhs", path, cache, 30 * limit)


def fresh_cache(tmp: Path, name: str, installation: Path) -> Path:
    """A new cache directory holding only the compiled kernels (time stamps kept: numba checks them)."""
    cache = tmp / name
    for src in kernel_files(installation):
        dst = cache / src.relative_to(installation)
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)
    return cache


def write_case(doc: dict, path: Path) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def run_worker(step: str, case_path: Path, cache: Path, limit: float) -> dict | None:
    """The worker's result, or None when it ran past ``limit`` seconds."""
    env = dict(ENV, CSIM_CACHE_DIR=str(cache))
    try:
        done = subprocess.run([sys.executable, __file__, "--worker", step, str(case_path)], env=env,
                              capture_output=True, text=True, timeout=limit)
    except subprocess.TimeoutExpired:
        return None
    if done.returncode != 0:
        raise RuntimeError(f"bench/scaling.py --worker {step} {case_path} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def first_run(case_path: Path, cache: Path, out: Path, limit: float) -> float | None:
    env = dict(ENV, CSIM_CACHE_DIR=str(cache))
    start = time.perf_counter()
    try:
        done = subprocess.run([sys.executable, "-m", "csim", "run", str(case_path), "-o", str(out), "--quiet",
                               "--set", "simulation.t_end=0.1"], env=env, capture_output=True, text=True,
                              timeout=limit)
    except subprocess.TimeoutExpired:
        return None
    wall = time.perf_counter() - start
    if done.returncode != 0:
        if "simulation failed" not in done.stdout + done.stderr:  # not the motion: the case or csim
            raise RuntimeError(f"csim run {case_path} failed:\n{done.stdout[-1000:]}{done.stderr[-2000:]}")
        # the motion failed before 0.1 s (e.g. an N-bar loop falling into a singular
        # configuration): derivation, compilation and integration were still timed
        print(f"  note: {case_path.stem}: {' '.join((done.stdout + done.stderr).split())[:200]}", flush=True)
    return wall


def measure(family: str, n: int, tmp: Path, installation: Path, limit: float, plain_c: bool = False) -> dict:
    doc = FAMILIES[family](n)
    case_path = write_case(doc, tmp / f"{family}_{n}.yaml")
    row = dict(family=family, n=n, links=len(doc["mechanism"]["links"]), dof=len(doc["initial"]["q"]))
    derive = run_worker("derive", case_path, fresh_cache(tmp, f"{family}_{n}_a", installation), limit)
    if derive is None:
        return dict(row, timeout=True)
    row.update(derive)
    cache = fresh_cache(tmp, f"{family}_{n}_b", installation)
    row["first_run"] = first_run(case_path, cache, tmp / f"{family}_{n}.h5", limit)
    if row["first_run"] is None:
        return dict(row, timeout=True)
    row.update(run_worker("rhs", case_path, cache, limit) or {})
    if plain_c:
        row.update(run_worker("plain_c", case_path, cache, limit) or {})
    return row


def power_fit(ns: list[float], values: list[float]) -> float | None:
    """The exponent p of values ~ c n^p (least squares in log-log); None with fewer than 2 sizes."""
    if len(ns) < 2 or len(set(ns)) < 2:
        return None
    x, y = [math.log(v) for v in ns], [math.log(v) for v in values]
    mx, my = sum(x) / len(x), sum(y) / len(y)
    return sum((a - mx) * (b - my) for a, b in zip(x, y)) / sum((a - mx) ** 2 for a in x)


def fmt(value, spec, limit=None):
    if value is None:
        return f"> {limit:g}" if limit is not None else "-"
    return format(value, spec)


def report(rows: list[dict], limit: float) -> str:
    head = (f"{'family':<7}{'N':>4}{'links':>6}{'m':>5}{'r':>5}{'DOF':>4}  {'analyse s':>9}{'derive s':>9}"
            f"{'codegen s':>10}{'(a) total s':>12}{'(b) cc s':>9}{'(c) first run s':>16}{'(d) RHS us':>11}")
    if any(row.get("plain_c_ns") for row in rows):
        head += f"{'(e) plain C us':>14}{'(d)/(e)':>8}"
    lines = [head, "-" * len(head)]
    for row in rows:
        if row.get("timeout") and "derive" not in row:
            lines.append(f"{row['family']:<7}{row['n']:>4}{row['links']:>6}{'':>5}{'':>5}{row['dof']:>4}  "
                         f"{'':>9}{'':>9}{'':>10}{fmt(None, '', limit):>12}")
            continue
        rhs = row.get("rhs_ns")
        plain = row.get("plain_c_ns")
        extra = "" if plain is None else f"{plain / 1e3:>13.3f}{fmt(None if rhs is None else rhs / plain, '.2f'):>7}"
        lines.append(
            f"{row['family']:<7}{row['n']:>4}{row['links']:>6}{row.get('m', '?'):>5}{row.get('r', '?'):>5}"
            f"{row['dof']:>4}  {row['analyse']:>9.2f}{row['derive_only']:>9.2f}{row['codegen']:>10.2f}"
            f"{row['derive']:>12.2f}{row['cc']:>9.2f}{fmt(row.get('first_run'), '.2f', limit):>16}"
            f"{fmt(None if rhs is None else rhs / 1e3, '.3f'):>11}{extra}")
    lines.append("")
    lines.append("growth, fitted as c N^p over the sizes that finished (N: loops of the chain, links of the loop):")
    for family in FAMILIES:
        done = [r for r in rows if r["family"] == family and "derive" in r]
        timed = [r for r in done if r.get("rhs_ns")]
        p_derive = power_fit([r["n"] for r in done], [r["derive"] for r in done])
        p_cc = power_fit([r["n"] for r in done], [r["cc"] for r in done])
        p_rhs = power_fit([r["n"] for r in timed], [r["rhs_ns"] for r in timed])
        lines.append(f"  {family:<6} derive + codegen p = {fmt(p_derive, '.2f')}, cc p = {fmt(p_cc, '.2f')}, "
                     f"RHS p = {fmt(p_rhs, '.2f')}  (sizes {[r['n'] for r in done]})")
    return "\n".join(lines)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--worker", nargs=2, metavar=("STEP", "CASE"), help=argparse.SUPPRESS)
    parser.add_argument("--chain", type=int, nargs="*", default=DEFAULT_SIZES["chain"],
                        help="numbers of four-bar loops in the chain (default: %(default)s)")
    parser.add_argument("--loop", type=int, nargs="*", default=DEFAULT_SIZES["loop"],
                        help="numbers of links of the closed loop, ground included (default: %(default)s)")
    parser.add_argument("--limit", type=float, default=120.0, help="time limit of each step of each size [s]")
    parser.add_argument("--json", type=Path, help="also write the rows to this file")
    parser.add_argument("--plain-c", action="store_true",
                        help="also time (e) the same right-hand side as plain C (bench/c_rhs.py) and the ratio")
    args = parser.parse_args(argv)
    if args.worker:
        step, case_path = args.worker
        print(json.dumps(WORKERS[step](case_path)))
        return
    installation = installation_cache()
    rows = []
    with tempfile.TemporaryDirectory(prefix="csim-scaling-") as tmp_name:
        tmp = Path(tmp_name)
        warm_installation(installation, tmp, args.limit)
        if not kernel_files(installation):
            raise SystemExit(f"bench: no compiled kernels in {installation}/fast after the warm-up")
        for family, sizes in (("chain", args.chain), ("loop", args.loop)):
            for n in sorted(sizes):
                start = time.perf_counter()
                row = measure(family, n, tmp, installation, args.limit, args.plain_c)
                rows.append(row)
                print(report([row], args.limit).split("\n")[2], flush=True)
                print(f"  {family} {n}: {'> limit' if row.get('timeout') else 'done'} "
                      f"({time.perf_counter() - start:.0f} s)", flush=True)
                if row.get("timeout"):
                    break  # the larger sizes take longer still
                shutil.rmtree(tmp / f"{family}_{n}_a", ignore_errors=True)
                shutil.rmtree(tmp / f"{family}_{n}_b", ignore_errors=True)
    print()
    print(report(rows, args.limit))
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
