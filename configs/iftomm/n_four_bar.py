"""Write the IFToMM A02 case for N four-bars: ``python configs/iftomm/n_four_bar.py N > FILE``.

The shipped a02_n_four_bar_2.yaml and a02_n_four_bar_40.yaml were written by this script.
"""
from __future__ import annotations

import sys

HALF_PI = "1.5707963267948966"


def n_four_bar(n: int) -> str:
    """The case file of N four-bars in a row (2 N + 1 moving links), as YAML text."""
    rod = "mass: 1, com: [0.5, 0, 0], inertia: 1/12"
    pivots = ", ".join(f"[R, [{i}, 0, 0], O{i}]" for i in range(n + 1))
    lines = [
        "# yaml-language-server: $schema=../../csim-case.schema.json",
        f"# IFToMM benchmark A02: N = {n} four-bars in a row. Cranks pinned to ground at x = 0, 1, ..., N,",
        "# horizontal couplers joining their tops; every link a uniform 1 m, 1 kg rod; starts",
        "# rectangular (cranks vertical) with the top B0 of the first crank moving at 1 m/s along x.",
        "# Whenever every link is horizontal Phi_q loses rank N (the mobility jumps from 1 to N + 1):",
        "# a singular crossing, twice a turn. The exact motion keeps the parallelogram: every crank",
        "# turns by the same angle, a one-degree-of-freedom pendulum (tests/iftomm_reference.py).",
        f"# Written by configs/iftomm/n_four_bar.py {n}.",
        "mechanism:",
        f"  label: a02_n_four_bar_{n}",
        "  gravity: [0, -9.81, 0]                      # [m/s^2]",
        "  links:",
        f"    - {{link: 0, name: ground, joints: [{pivots}]}}",
    ]
    lines += [f"    - {{link: {i + 1}, name: crank{i}, joints: [[R, 0, O{i}], [R, [1, 0, 0], B{i}]], {rod}}}"
              for i in range(n + 1)]
    lines += [f"    - {{link: {n + 2 + j}, name: coupler{j}, joints: [[R, 0, P{j}], [R, [1, 0, 0], Q{j}]], {rod}}}"
              for j in range(n)]
    lines.append("  couplings:")
    lines += [f"    - {{name: crank{i}, couple: [ground, O{i}, crank{i}, O{i}]}}" for i in range(n + 1)]
    lines.append("    - {name: B0, couple: [crank0, B0, coupler0, P0]}")
    lines += [f"    - {{name: B{i}, couple: [[crank{i}, B{i}], [coupler{i - 1}, Q{i - 1}], [coupler{i}, P{i}]]}}"
              for i in range(1, n)]
    lines.append(f"    - {{name: B{n}, couple: [coupler{n - 1}, Q{n - 1}, crank{n}, B{n}]}}")
    lines += [
        "",
        "initial:",
        f"  q: {{q_crank0: {HALF_PI}}}        # [rad]: cranks vertical",
        "  qd: {q_crank0: -1.0}                     # [rad/s]: B0 moves at +1 m/s along x",
        # the rectangle: cranks at +90 deg, each coupler at -90 deg from the crank that carries it
        # in the spanning tree (B0, B2 ... B(N-1)) and +90 deg from the last crank's frame (BN)
        "  guess: {" + ", ".join([f"q_crank{i}: {HALF_PI}" for i in range(1, n + 1)]
                                 + [f"q_B{i}: -{HALF_PI}" for i in [0, *range(2, n)]] + [f"q_B{n}: {HALF_PI}"]) + "}",
        "",
        "stabilization:",
        "  method: minimal        # chooses its independent coordinate again at every crossing",
        "  # or: --set stabilization.method=augmented_lagrangian --set simulation.integrator=trapezoidal",
        "",
        "simulation:",
        "  t_end: 20.0",
        "  rtol: 1.0e-10",
        "  atol: 1.0e-10",
        "output:",
        "  dt: 0.05                                 # 400 output steps",
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.stdout.write(n_four_bar(int(sys.argv[1])))
