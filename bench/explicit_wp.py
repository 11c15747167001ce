"""Right-hand-side evaluations against accuracy of RK45, Tsit5, Vern7 and DOP853 on the Python path.

``python bench/explicit_wp.py``: the quick-return with projection over 10 s at four tolerances;
the error is the largest |q - q_ref| against a run at 1e-13 [rad or m]. Evaluation counts do
not depend on the machine.
"""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from csim.case import load_case  # noqa: E402
from csim.pipeline import run_case  # noqa: E402

CASE = ROOT / "configs" / "quick_return.yaml"
base = ["simulation.t_end=10", "simulation.backend=python", "stabilization.method=projection"]
ref = run_case(load_case(CASE, [*base, "simulation.rtol=1e-13", "simulation.atol=1e-13"]))
INTEGRATORS = ("RK45", "Tsit5", "Vern7", "DOP853")
print("| rtol = atol | " + " | ".join(f"{name} nfev, error" for name in INTEGRATORS) + " |")
print("|---" * (len(INTEGRATORS) + 1) + "|")
for tol in ("1e-4", "1e-6", "1e-8", "1e-10", "1e-12"):
    row = []
    for integ in INTEGRATORS:
        sets = [*base, f"simulation.rtol={tol}", f"simulation.atol={tol}", f"simulation.integrator={integ}"]
        r = run_case(load_case(CASE, sets))
        err = np.max(np.abs(r.q - ref.q)) if r.ok else float("nan")
        row.append(f"{r.nfev}, {err:.1e}")
    print(f"| {tol} | " + " | ".join(row) + " |")
