"""Speed and accuracy of csim on the quick-return mechanism, measured side by side in one run.

Run with ``make bench`` (``python bench/run.py --help`` for options). Prints:

1. one row per (backend, stabilization method, integrator, tolerance): median wall time of
   the integration alone over several runs, RHS evaluations, the crank-angle error at
   t_end against an independent reference (the minimal-coordinate model of
   tests/quick_return_reference.py, rtol = atol = 1e-13), max |Phi| over the output, and
   for the rows run on both backends, the speed-up of the compiled path over the Python one;
2. the 20 ms target row (10 s, crank error <= 1e-6 rad, max |Phi| <= 1e-10);
3. the cost of one KKT right-hand-side evaluation: compiled (numba), plain C (generated
   from the same derivation and compiled with ``cc -O2`` here), and the Python path;
4. ``csim run configs/quick_return.yaml`` end to end, warm (median) and cold (a fresh
   cache directory: derivation plus compilation);
5. sweep throughput: runs of the 10 s quick-return per minute, ``csim sweep`` on every core
   against a shell loop of ``csim run --set ...`` (target >= 1,000 per minute on 2 cores).

How the cost grows with mechanism size (derivation, cc, first run and per-RHS time of a
chain of N four-bar loops and of a closed N-bar loop, with fitted exponents) is the
scaling table of bench/scaling.py: ``make bench-scaling`` (``make bench`` runs it after this).
"""
from __future__ import annotations

import argparse
import os
import shutil
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
sys.path.insert(0, str(ROOT / "bench"))

from csim.case import load_case  # noqa: E402
from csim.fast import integrate_compiled  # noqa: E402
from csim.fast.module import load_module  # noqa: E402
from csim.fast.runner import pack_problem  # noqa: E402
from csim.pipeline import build_system, initial_state  # noqa: E402
from csim.solver.simulate import integrate  # noqa: E402

CASE = ROOT / "configs" / "quick_return.yaml"
CSIM = str(Path(sys.executable).with_name("csim"))

#: (stabilization, integrator, rtol = atol or RK4 step, also on the Python path)
MATRIX = [
    ("none", "DOP853", 1e-8, False), ("none", "DOP853", 1e-10, True),
    ("projection", "DOP853", 1e-8, False), ("projection", "DOP853", 1e-9, True),
    ("projection", "DOP853", 1e-10, False),
    ("baumgarte", "DOP853", 1e-10, False), ("sliding_mode", "DOP853", 1e-10, False),
    ("none", "RK4", 1e-3, True), ("none", "RK4", 2.5e-4, False), ("projection", "RK4", 1e-3, False),
    ("minimal", "DOP853", 1e-9, True),
    ("projection", "Tsit5", 1e-9, False), ("projection", "Vern7", 1e-9, False),
    ("ggl", "Radau", 1e-7, True),
]
#: the configuration of the 20 ms target (chosen from the table: the cheapest that meets both bounds)
TARGET = ("projection", "DOP853", 1e-9)


def case_for(method, integrator, tol, t_end):
    sets = [f"stabilization.method={method}", f"simulation.integrator={integrator}", f"simulation.t_end={t_end}",
            "stabilization.w=100"]
    sets += [f"simulation.step={tol}"] if integrator == "RK4" else [f"simulation.rtol={tol}", f"simulation.atol={tol}"]
    return load_case(CASE, sets)


def timed(fn, repeat):
    times, out = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def measure(method, integrator, tol, t_end, backend, repeat, q1_ref):
    case = case_for(method, integrator, tol, t_end)
    system = build_system(case)
    y0 = initial_state(case, system)
    settings = case.integration_settings()
    run = integrate_compiled if backend == "compiled" else integrate
    wall, traj = timed(lambda: run(system, y0, settings), repeat)
    q = traj.y[:, :system.m]
    max_phi = max(float(np.max(np.abs(system.model.phi(qi, system.par)))) for qi in q)
    err = abs(traj.y[-1, 0] - q1_ref) if traj.status == "success" else float("nan")
    return dict(wall=wall, nfev=traj.nfev, err=err, max_phi=max_phi, status=traj.status)


def compiled_rhs(case):
    """(system, y0, mode, kernels, (par, pf, pi)) of a case, its compiled right-hand side loaded
    and called once: what a timing loop of ``kernels.rhs_repeat(y0, mode, par, pf, pi, n)`` needs."""
    system = build_system(case)
    y = initial_state(case, system)
    mode = system.mode_at(y)
    mod = load_module(system.model.definition)
    packed = pack_problem(system)
    mod.rhs_repeat(y, mode, *packed, 10)
    return system, y, mode, mod, packed


def rhs_costs(n_eval):
    """ns per KKT right-hand-side evaluation: compiled, C, Python (stabilization none)."""
    import c_rhs

    system, y, mode, mod, (par, pf, pi) = compiled_rhs(load_case(CASE, []))
    numba_ns = statistics.median(timed(lambda: mod.rhs_repeat(y, mode, par, pf, pi, n_eval), 1)[0] / n_eval * 1e9
                                 for _ in range(5))
    exe, tmp = c_rhs.build(system.model.definition, y, system.par, system.loads.values(mode), n_eval)
    try:
        runs = [c_rhs.run(exe) for _ in range(5)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    c_ns = statistics.median(r[0] for r in runs)
    qdd_c = runs[0][1]
    qdd_py = system.rhs(0.0, y, mode)[system.m:2 * system.m]
    n_py = max(1000, n_eval // 1000)
    py_ns = timed(lambda: [system.rhs(0.0, y, mode) for _ in range(n_py)], 3)[0] / n_py * 1e9
    diff = float(np.max(np.abs(qdd_c - qdd_py)))
    # the ratio means something only if C computes the same accelerations
    if not diff <= 1e-9 * max(1.0, float(np.max(np.abs(qdd_py)))):
        raise SystemExit(f"bench: the C right-hand side differs from the Python one by {diff:.3g}; no ratio")
    return numba_ns, c_ns, py_ns, diff


def csim_run_time(cache_dir, out):
    env = dict(os.environ, CSIM_CACHE_DIR=str(cache_dir))
    start = time.perf_counter()
    subprocess.run([CSIM, "run", str(CASE), "-o", str(out), "--quiet"], check=True, env=env,
                   stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def sweep_throughput(cache_dir, tmp, n_runs, n_loop):
    """Runs per minute of the 10 s quick-return: csim sweep (all cores) and a loop of csim run."""
    env = dict(os.environ, CSIM_CACHE_DIR=str(cache_dir))
    sweep = [CSIM, "sweep", str(CASE), "--set", "simulation.t_end=10", "-v",
             f"loads.torque=lin:165000:185000:{n_runs}", "-o", str(Path(tmp) / "sweep.h5"), "--quiet"]
    start = time.perf_counter()
    subprocess.run(sweep, check=True, env=env, stdout=subprocess.DEVNULL)
    per_minute_sweep = n_runs / (time.perf_counter() - start) * 60
    start = time.perf_counter()
    for i in range(n_loop):
        subprocess.run([CSIM, "run", str(CASE), "--set", "simulation.t_end=10", "--set",
                        f"loads.torque={165000 + 2000 * i}", "-o", str(Path(tmp) / "loop.h5"), "--quiet"],
                       check=True, env=env, stdout=subprocess.DEVNULL)
    per_minute_loop = n_loop / (time.perf_counter() - start) * 60
    return per_minute_sweep, per_minute_loop


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs per compiled row (the median is reported)")
    parser.add_argument("--python-repeat", type=int, default=1, help="runs per Python-path row")
    parser.add_argument("--t-end", type=float, default=10.0, help="simulated time [s]")
    parser.add_argument("--n-eval", type=int, default=2_000_000, help="RHS evaluations per timing loop")
    parser.add_argument("--skip-cold", action="store_true", help="skip the cold-start run (fresh cache)")
    parser.add_argument("--sweep-runs", type=int, default=1000, help="runs of the sweep throughput row")
    args = parser.parse_args(argv)

    from quick_return_reference import MinimalQuickReturn

    _, y_ref, _ = MinimalQuickReturn().solve(t_end=args.t_end, rtol=1e-13, atol=1e-13)
    q1_ref = y_ref[-1, 0]
    measure("none", "DOP853", 1e-6, 0.1, "compiled", 1, q1_ref)  # load the compiled module before timing

    print(f"quick_return, t_end = {args.t_end:g} s, KKT; integration wall time, median of {args.repeat} runs "
          f"(compiled) / {args.python_repeat} (python); error = |q1 - q1_ref| at t_end")
    header = (f"{'method':<13}{'integrator':<11}{'tol/step':>9} {'backend':<9}{'wall [ms]':>10}{'RHS evals':>10}"
              f"{'|q1 err| [rad]':>15}{'max|Phi|':>10}{'speed-up':>9}  status")
    print(header)
    print("-" * len(header))
    rows = {}
    for method, integrator, tol, both in MATRIX:
        fast = measure(method, integrator, tol, args.t_end, "compiled", args.repeat, q1_ref)
        rows[(method, integrator, tol)] = fast
        print(f"{method:<13}{integrator:<11}{tol:>9.1e} {'compiled':<9}{fast['wall'] * 1e3:>10.2f}{fast['nfev']:>10d}"
              f"{fast['err']:>15.2e}{fast['max_phi']:>10.1e}{'':>9}  {fast['status']}")
        if both:
            slow = measure(method, integrator, tol, args.t_end, "python", args.python_repeat, q1_ref)
            print(f"{'':<13}{'':<11}{'':>9} {'python':<9}{slow['wall'] * 1e3:>10.1f}{slow['nfev']:>10d}"
                  f"{slow['err']:>15.2e}{slow['max_phi']:>10.1e}{slow['wall'] / fast['wall']:>8.0f}x  "
                  f"{slow['status']}")

    t = rows.get(TARGET) or measure(*TARGET, args.t_end, "compiled", args.repeat, q1_ref)
    ok = t["wall"] <= 0.020 and t["err"] <= 1e-6 and t["max_phi"] <= 1e-10
    print(f"\ntarget (10 s, |q1 err| <= 1e-6 rad, max|Phi| <= 1e-10, <= 20 ms): {TARGET[0]} + {TARGET[1]}, "
          f"rtol = atol = {TARGET[2]:g}: {t['wall'] * 1e3:.2f} ms, |q1 err| = {t['err']:.2e} rad, "
          f"max|Phi| = {t['max_phi']:.1e} -> {'met' if ok else 'NOT met'}")

    numba_ns, c_ns, py_ns, diff = rhs_costs(args.n_eval)
    print(f"\nKKT RHS evaluation (stabilization none): compiled {numba_ns:.0f} ns, plain C (cc -O2) {c_ns:.0f} ns, "
          f"Python path {py_ns / 1e3:.1f} us")
    print(f"  compiled / C = {numba_ns / c_ns:.2f} (target <= 3), Python / compiled = {py_ns / numba_ns:.0f}x, "
          f"|qdd_C - qdd_python| = {diff:.1e}")

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "qr.h5"
        cache = Path(tmp) / "cache"
        if args.skip_cold:
            cache = Path(os.environ.get("CSIM_CACHE_DIR", Path.home() / ".cache" / "csim"))
            cold = None
        else:
            cold = csim_run_time(cache, out)
        warm = statistics.median(csim_run_time(cache, out) for _ in range(3))
        sweep_rate, loop_rate = sweep_throughput(cache, tmp, args.sweep_runs, 10)
    print(f"\ncsim run configs/quick_return.yaml end to end: warm {warm:.2f} s (median of 3, target <= 2 s)" +
          (f"; cold (fresh cache: derivation + compilation) {cold:.1f} s" if cold is not None else ""))

    print(f"\nsweep of the 10 s quick-return ({args.sweep_runs} runs, {os.cpu_count()} CPUs): csim sweep "
          f"{sweep_rate:.0f} runs/min, a shell loop of csim run {loop_rate:.0f} runs/min "
          f"({sweep_rate / loop_rate:.0f}x; target >= 1,000 runs/min)")


if __name__ == "__main__":
    main()
