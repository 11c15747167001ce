"""Generate numba-compilable model functions from the symbolic derivation.

Unlike :mod:`csim.model.codegen` (array-in, new-array-out functions for the Python path),
the functions generated here write into one flat workspace array ``w`` that the compiled
loop allocates once per run, at offsets that are compile-time constants (``W_M``, ``W_CQD``,
...; matrices row-major), and the terms one evaluation needs share one
common-subexpression elimination (each sin and cos of the coordinates is computed once):

``terms(t, y, par, w)``
    M (m, m), C qd (m,), h (m,), Phi (r,), Phi_q (r, m), gamma (r,), s (k,), B (m, k),
    S = ds/dq^T (m, k), the load laws f(q, qd, t) (k,); t is the time [s]
``phi_(y, par, w)``, ``jac(y, par, w)``, ``mass(y, par, w)``
    the pieces the projection and the divergence checks need on their own
``loads_(y, par, w)``
    load coordinates s and their Jacobian S, for the switching functions
``kinetic(y, par)``, ``potential(y, par)``
    energies [J] (floats)
``observe(y, par, out)``
    the observables (o,) and their rates (o,) into ``out`` (2 o,), for the result's samples

``y`` is a state [q, qd, ...] (functions of q alone read its first m entries). The symbols
of the mechanism are unpacked into locals of the same name, as in
:mod:`csim.model.codegen`; the arguments are named ``_y``, ``_par``, ``_w`` so that no
parameter name can shadow them; ``terms`` unpacks ``_t`` into the time symbol ``t``.
"""
from __future__ import annotations

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

#: the terms the right-hand side needs, in their order in the workspace w
TERMS = ("mass", "velocity_terms", "gravity", "phi", "phi_q", "gamma", "load_coordinates", "load_matrix",
         "load_jacobian", "load_law")
#: DerivedModel attribute -> name of its offset in w (matrices row-major)
OFFSETS = {"mass": "W_M", "velocity_terms": "W_CQD", "gravity": "W_H", "phi": "W_PHI", "phi_q": "W_J",
           "gamma": "W_GAM", "load_coordinates": "W_S", "load_matrix": "W_B", "load_jacobian": "W_SQ",
           "load_law": "W_L"}

#: function name -> the DerivedModel attributes it writes into w
FUNCTIONS = {
    "terms": TERMS,
    "phi_": ("phi",),
    "jac": ("phi_q",),
    "mass": ("mass",),
    "loads_": ("load_coordinates", "load_jacobian"),
}
#: the functions that take the time [s] as their first argument (the load laws may depend on it)
TIMED = ("terms",)

#: scalar functions: name -> DerivedModel attribute
SCALARS = {"kinetic": "kinetic_energy", "potential": "potential_energy"}

DECORATOR = '@njit(cache=True, error_model="numpy", _nrt=False)'  # they allocate nothing


class _Printer(PythonCodePrinter):
    def _print_Symbol(self, expr):
        return str(expr)


def _unpack_lines(used, unpack):
    return [f"    {name} = {src}" for name, src in unpack if name in used]


def _cse(exprs):
    temps, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("_x"), optimizations="basic")
    used = set()
    for e in [t[1] for t in temps] + reduced:
        used |= {str(s) for s in e.free_symbols}
    return temps, reduced, used


def function_source(fname, attrs, derived, unpack) -> str:
    """One njit function ``fname(_y, _par, _w)`` (``fname(_t, _y, _par, _w)`` if in :data:`TIMED`)
    writing the terms ``attrs`` into _w."""
    printer = _Printer()
    targets = []
    for attr in attrs:
        matrix = getattr(derived, attr)
        targets += [(f"{OFFSETS[attr]} + {i}", e) for i, e in enumerate(matrix)]  # row-major
    temps, reduced, used = _cse([e for _, e in targets])
    timed = fname in TIMED
    lines = [DECORATOR, f"def {fname}({'_t, ' if timed else ''}_y, _par, _w):"]
    lines += _unpack_lines(used, unpack + ([("t", "_t")] if timed else []))
    lines += [f"    {sym} = {printer.doprint(value)}" for sym, value in temps]
    lines += [f"    _w[{ix}] = {printer.doprint(value)}" for (ix, _), value in zip(targets, reduced)]
    lines.append("    return None")
    return "\n".join(lines)


def scalar_source(fname, expr, unpack) -> str:
    """``fname(_y, _par)`` -> float."""
    printer = _Printer()
    temps, reduced, used = _cse([expr])
    lines = [DECORATOR, f"def {fname}(_y, _par):"]
    lines += _unpack_lines(used, unpack)
    lines += [f"    {sym} = {printer.doprint(value)}" for sym, value in temps]
    lines.append(f"    return float({printer.doprint(reduced[0])})")
    return "\n".join(lines)


def observe_source(derived, unpack) -> str:
    """``observe(_y, _par, _o)``: the observables, then their rates d/dt obs = (d obs / dq) qd, into _o."""
    printer = _Printer()
    obs = list(derived.observables) if derived.observables is not None else []
    qd = sp.Matrix(derived.definition.velocities)
    rates = list(derived.observable_jacobian * qd) if obs else []
    temps, reduced, used = _cse(obs + rates) if obs else ([], [], set())
    lines = [DECORATOR, "def observe(_y, _par, _o):"]
    lines += _unpack_lines(used, unpack)
    lines += [f"    {sym} = {printer.doprint(value)}" for sym, value in temps]
    lines += [f"    _o[{i}] = {printer.doprint(value)}" for i, value in enumerate(reduced)]
    lines.append("    return None")
    return "\n".join(lines)


def model_source(derived) -> str:
    """Source of the model part of a compiled module: sizes, workspace layout, njit functions."""
    d = derived.definition
    m, r, k = len(d.coordinates), len(d.constraints), len(d.loads)
    unpack = [(name, f"_y[{i}]") for i, name in enumerate(d.coordinate_names)]
    unpack += [(str(s), f"_y[{m + i}]") for i, s in enumerate(d.velocities)]
    unpack += [(name, f"_par[{i}]") for i, name in enumerate(d.parameter_names)]
    sizes = {"mass": m * m, "velocity_terms": m, "gravity": m, "phi": r, "phi_q": r * m, "gamma": r,
             "load_coordinates": k, "load_matrix": m * k, "load_jacobian": m * k, "load_law": k}
    layout, offset = [], 0
    for attr in TERMS:
        layout.append(f"{OFFSETS[attr]} = {offset}")
        offset += sizes[attr]
    layout.append(f"W_MODEL = {offset}  # end of the model terms in w")
    chunks = [
        f"# ---- model {d.name!r}, generated from its symbolic derivation ----",
        f"NQ = {m}  # coordinates\nNC = {r}  # constraints\nNL = {k}  # loads\n"
        f"NO = {len(d.observables)}  # observables",
        "# offsets of the model terms in the workspace w (matrices row-major)\n" + "\n".join(layout),
    ]
    for fname, attrs in FUNCTIONS.items():
        chunks.append(function_source(fname, attrs, derived, unpack))
    for fname, attr in SCALARS.items():
        chunks.append(scalar_source(fname, getattr(derived, attr), unpack))
    chunks.append(observe_source(derived, unpack))
    return "\n\n\n".join(chunks) + "\n"
