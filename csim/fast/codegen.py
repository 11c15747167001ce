"""The model functions of one mechanism for the compiled kernels, generated from its derivation.

Every function has one C interface (:mod:`csim.fast.layout`),
``void f(double t, const double *y, const double *par, double *out)``, so that the kernels,
compiled once for every mechanism, call any mechanism's functions through their addresses.
They write into the flat workspace ``w`` at offsets fixed here (integer literals;
matrices row-major), and the terms one evaluation needs share one common-subexpression
elimination (each sin and cos of the coordinates is computed once):

``terms``
    M (m, m), C qd (m,), h (m,), Phi (r,), Phi_q (r, m), gamma (r,), s (k,), B (m, k),
    S = ds/dq^T (m, k), the load laws f(q, qd, t) (k,), Phi_t (r,) (zero but for the rows
    of drives, :func:`csim.model.derive.with_drive_rows`); t is the time [s]
``phi_``, ``jac``, ``mass``
    the pieces the projection and the divergence checks need on their own (``phi_``: Phi and
    Phi_t, the projection's velocity target)
``loads_``
    load coordinates s and their Jacobian S, for the switching functions
``kinetic``, ``potential``
    energies [J] into out[0]
``observe``
    the observables (o,) and their rates (o,) into ``out`` (2 o,), for the result's samples

``y`` is a state [q, qd, ...]. This module plans the functions (which expression goes to
which entry, after CSE) and prints them as numba cfuncs, the fallback where no C
compiler works; :mod:`csim.fast.ccodegen` prints the same plan as C.
"""
from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from csim.fast.layout import MODEL_FUNCTIONS, model_offsets
from csim.model.printing import expression_printer

#: the terms the right-hand side needs, in their order in the workspace w
TERMS = ("mass", "velocity_terms", "gravity", "phi", "phi_q", "gamma", "load_coordinates", "load_matrix",
         "load_jacobian", "load_law", "phi_t")
#: DerivedModel attribute -> name of its offset in w (csim.fast.layout.MODEL_TERMS)
OFFSETS = {"mass": "W_M", "velocity_terms": "W_CQD", "gravity": "W_H", "phi": "W_PHI", "phi_q": "W_J",
           "gamma": "W_GAM", "load_coordinates": "W_S", "load_matrix": "W_B", "load_jacobian": "W_SQ",
           "load_law": "W_L", "phi_t": "W_PT"}

#: function name -> the DerivedModel attributes it writes into w
FUNCTIONS = {
    "terms": TERMS,
    "phi_": ("phi", "phi_t"),
    "jac": ("phi_q",),
    "mass": ("mass",),
    "loads_": ("load_coordinates", "load_jacobian"),
}

#: scalar functions: name -> DerivedModel attribute, written to out[0]
SCALARS = {"kinetic": "kinetic_energy", "potential": "potential_energy"}

#: the name of the time symbol a load law may use (unpacked from the argument t)
TIME = "t"


@dataclass
class Plan:
    """One model function: its statements after CSE, and the symbols it reads."""

    name: str
    #: (CSE temporary, expression), in order
    temps: list
    #: (index in out, expression)
    outputs: list
    #: (symbol name, argument, index) of the symbols read: argument "y", "par" or "t"
    unpack: list


def dims(derived) -> tuple[int, int, int, int]:
    """(m, r, k, o): coordinates, constraints, loads, observables."""
    d = derived.definition
    return len(d.coordinates), derived.phi.shape[0], len(d.loads), len(d.observables)


def _plan(name, outputs, sources, intermediates=()) -> Plan:
    """The statements of one function: the named intermediates its outputs use (in order of
    definition, :mod:`csim.model.recursive`), then one CSE over the outputs."""
    from csim.model.recursive import common_subexpressions, needed

    exprs = [e for _, e in outputs]
    temps, reduced = common_subexpressions(exprs, intermediates)
    temps = needed([t[1] for t in temps] + list(reduced), intermediates) + list(temps)
    used = set()
    for e in [t[1] for t in temps] + list(reduced):
        used |= {str(s) for s in e.free_symbols}
    unpack = [(sym, arg, i) for sym, arg, i in sources if sym in used]
    return Plan(name, temps, [(ix, e) for (ix, _), e in zip(outputs, reduced)], unpack)


def plans(derived) -> list[Plan]:
    """The model functions of ``derived``, in the order of :data:`csim.fast.layout.MODEL_FUNCTIONS`."""
    d = derived.definition
    m, r, k, _ = dims(derived)
    sources = [(name, "y", i) for i, name in enumerate(d.coordinate_names)]
    sources += [(str(s), "y", m + i) for i, s in enumerate(d.velocities)]
    sources += [(name, "par", i) for i, name in enumerate(d.parameter_names)]
    sources.append((TIME, "t", 0))
    offsets, _ = model_offsets(m, r, k)
    out = {}
    for fname, attrs in FUNCTIONS.items():
        targets = []
        for attr in attrs:
            base = offsets[OFFSETS[attr]]
            targets += [(base + i, e) for i, e in enumerate(_term(derived, attr))]  # row-major
        out[fname] = _plan(fname, targets, sources, derived.intermediates)
    for fname, attr in SCALARS.items():
        out[fname] = _plan(fname, [(0, getattr(derived, attr))], sources, derived.intermediates)
    obs = list(derived.observables) if derived.observables is not None else []
    rates = list(derived.observable_jacobian * sp.Matrix(d.velocities)) if obs else []
    out["observe"] = _plan("observe", list(enumerate(obs + rates)), sources, derived.intermediates)
    return [out[name] for name in MODEL_FUNCTIONS]


def _term(derived, attr: str):
    """A term of ``derived`` (Phi_t: zeros where no row depends on time)."""
    value = getattr(derived, attr)
    return sp.zeros(derived.phi.shape[0], 1) if value is None else value


class _Printer(PythonCodePrinter):
    def _print_Symbol(self, expr):
        return str(expr)


CFUNC_HEADER = '''"""csim model functions of {name!r} as numba cfuncs (the fallback without a C compiler),
generated by csim.fast.codegen. Do not edit."""
import math

from numba import cfunc, types

_P = types.CPointer(types.float64)
SIGNATURE = types.void(types.float64, _P, _P, _P)
#: coordinates, constraints, loads, observables
DIMS = {dims}
'''


def cfunc_source(derived) -> str:
    """A module of numba cfuncs, one per model function (their ``.address`` is what the kernels call)."""
    doprint = expression_printer(derived, _Printer(), "python", str)
    chunks = [CFUNC_HEADER.format(name=derived.definition.name, dims=dims(derived))]
    args = {"y": "_y", "par": "_par", "t": "_t"}
    for plan in plans(derived):
        lines = ['@cfunc(SIGNATURE, cache=True, error_model="numpy")', f"def {plan.name}(_t, _y, _par, _w):"]
        lines += [f"    {sym} = {args[arg]}" + ("" if arg == "t" else f"[{i}]") for sym, arg, i in plan.unpack]
        lines += [f"    {sym} = {doprint(value)}" for sym, value in plan.temps]
        lines += [f"    _w[{ix}] = {doprint(value)}" for ix, value in plan.outputs]
        lines.append("    return")
        chunks.append("\n".join(lines))
    return "\n\n\n".join(chunks) + "\n"
