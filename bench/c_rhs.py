"""The KKT right-hand side of a mechanism in plain C, for the per-evaluation cost ratio.

The C source is generated from the same symbolic derivation as csim's model functions
(sympy's C99 printer after the same common-subexpression elimination), with the same
KKT assembly and LU with partial pivoting as the compiled kernels (stabilization none,
loads held in a mode), compiled with the system compiler (``cc -O2``) into a small
program that times N evaluations and prints ns per evaluation.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import tempfile

import numpy as np
import sympy as sp
from sympy.printing.c import C99CodePrinter

from csim.fast.codegen import TERMS, _term
from csim.model.derive import derive
from csim.model.recursive import needed


class _Printer(C99CodePrinter):
    def _print_Integer(self, expr):
        # an integer literal beyond 64 bits overflows in C (exact rationals of float inputs,
        # e.g. an inertia m L^2 / 12): print it as a double, as csim.fast.ccodegen does
        n = int(expr)
        return super()._print_Integer(expr) if abs(n) < 2**53 else repr(float(n))


def c_source(definition, y, par, u, n_eval: int) -> str:
    d = derive(definition)
    m, r, k = len(definition.coordinates), len(definition.constraints), len(definition.loads)
    printer = _Printer()
    exprs, offsets, off = [], {}, 0
    for attr in TERMS:
        mat = _term(d, attr)  # (Phi_t: zeros, no drives here)
        offsets[attr] = off
        exprs += list(mat)
        off += len(list(mat))
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("x_"), optimizations="basic")
    # the named intermediates of a mechanism built link by link (csim.model.recursive) come first
    temps = needed([t[1] for t in temps] + list(reduced), d.intermediates) + list(temps)
    body = []
    for i, name in enumerate(definition.coordinate_names):
        body.append(f"  const double {name} = y[{i}];")
    for i, s in enumerate(definition.velocities):
        body.append(f"  const double {s} = y[{m + i}];")
    for i, name in enumerate(definition.parameter_names):
        body.append(f"  const double {name} = par[{i}];")
    body += [f"  const double {s} = {printer.doprint(v)};" for s, v in temps]
    body += [f"  w[{i}] = {printer.doprint(v)};" for i, v in enumerate(reduced)]
    n = m + r
    o = offsets
    arr = lambda v: ", ".join(repr(float(x)) for x in v) or "0"  # noqa: E731
    return f"""
#include <math.h>
#include <stdio.h>
#include <time.h>
#define NQ {m}
#define NC {r}
#define NL {k}
#define NK {n}
static void terms(const double *y, const double *par, double *w) {{
{chr(10).join(body)}
}}
/* KKT right-hand side: f = [qd, qdd, u ds/dt]; returns 0 if singular */
static int rhs(const double *y, const double *par, const double *u, double *w, double *f) {{
  double A[NK][NK], x[NK]; int piv[NK];
  terms(y, par, w);
  const double *M = w + {o['mass']}, *Cqd = w + {o['velocity_terms']}, *h = w + {o['gravity']};
  const double *J = w + {o['phi_q']}, *gam = w + {o['gamma']}, *B = w + {o['load_matrix']};
  for (int i = 0; i < NQ; i++) {{
    double Q = 0; for (int kk = 0; kk < NL; kk++) Q += B[i * NL + kk] * u[kk];
    x[i] = Q - Cqd[i] - h[i];
    for (int j = 0; j < NQ; j++) A[i][j] = M[i * NQ + j];
    for (int j = 0; j < NC; j++) A[i][NQ + j] = J[j * NQ + i];
  }}
  for (int i = 0; i < NC; i++) {{
    for (int j = 0; j < NQ; j++) A[NQ + i][j] = J[i * NQ + j];
    for (int j = 0; j < NC; j++) A[NQ + i][NQ + j] = 0;
    x[NQ + i] = gam[i];
  }}
  for (int c = 0; c < NK; c++) {{
    int p = c; double big = fabs(A[c][c]);
    for (int i = c + 1; i < NK; i++) if (fabs(A[i][c]) > big) {{ big = fabs(A[i][c]); p = i; }}
    piv[c] = p; if (A[p][c] == 0.0) return 0;
    if (p != c) for (int j = 0; j < NK; j++) {{ double t = A[c][j]; A[c][j] = A[p][j]; A[p][j] = t; }}
    double inv = 1.0 / A[c][c];
    for (int i = c + 1; i < NK; i++) {{
      A[i][c] *= inv; double l = A[i][c];
      if (l != 0.0) for (int j = c + 1; j < NK; j++) A[i][j] -= l * A[c][j];
    }}
  }}
  for (int c = 0; c < NK; c++) {{ int p = piv[c]; if (p != c) {{ double t = x[c]; x[c] = x[p]; x[p] = t; }} }}
  for (int i = 0; i < NK; i++) for (int j = 0; j < i; j++) x[i] -= A[i][j] * x[j];
  for (int i = NK - 1; i >= 0; i--) {{ for (int j = i + 1; j < NK; j++) x[i] -= A[i][j] * x[j]; x[i] /= A[i][i]; }}
  for (int i = 0; i < NQ; i++) {{ f[i] = y[NQ + i]; f[NQ + i] = x[i]; }}
  for (int kk = 0; kk < NL; kk++) {{
    double sd = 0; for (int i = 0; i < NQ; i++) sd += B[i * NL + kk] * y[NQ + i];
    f[2 * NQ + kk] = u[kk] * sd;
  }}
  return 1;
}}
int main(void) {{
  double y[] = {{{arr(y)}}}, par[] = {{{arr(par)}}}, u[] = {{{arr(u)}}};
  double w[{off + 1}], f[{2 * m + k}];
  volatile double acc = 0; struct timespec a, b;
  for (int i = 0; i < 1000; i++) {{ rhs(y, par, u, w, f); acc += f[NQ]; }}
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (long i = 0; i < {n_eval}L; i++) {{ y[0] += 1e-300; rhs(y, par, u, w, f); acc += f[NQ]; }}
  clock_gettime(CLOCK_MONOTONIC, &b);
  double ns = ((b.tv_sec - a.tv_sec) * 1e9 + (b.tv_nsec - a.tv_nsec)) / {n_eval}.0;
  printf("%.3f", ns);
  for (int i = 0; i < NQ; i++) printf(" %.17g", f[NQ + i]);
  printf("\\n");
  return 0;
}}
"""


def build(definition, y, par, u, n_eval: int) -> tuple[str, str]:
    """Compile the C benchmark into a temporary directory; returns (executable, directory)."""
    cc = shutil.which("gcc") or shutil.which("cc")
    if cc is None:
        raise RuntimeError("no C compiler (gcc or cc) found")
    tmp = tempfile.mkdtemp(prefix="csim-bench-c-")
    src = os.path.join(tmp, "rhs.c")
    exe = os.path.join(tmp, "rhs")
    with open(src, "w") as fh:
        fh.write(c_source(definition, y, par, u, n_eval))
    subprocess.run([cc, "-O2", "-o", exe, src, "-lm"], check=True)
    return exe, tmp


def run(exe: str) -> tuple[float, np.ndarray]:
    """ns per evaluation, and qdd at the state (to check the C code computes the same thing)."""
    out = subprocess.run([exe], check=True, capture_output=True, text=True).stdout.split()
    return float(out[0]), np.array([float(v) for v in out[1:]])
