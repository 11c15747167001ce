"""Numbers and expressions of the named parameters, as they may be written in the tables.

A number may be written as an expression of the ``parameters`` (``l1``, ``xB/2``,
``90*deg``, ``pi/2``), built from + - * / ^, parentheses and :data:`FUNCTIONS`. It must be
finite and real at the parameter values (``acos(2)`` is not).
"""
from __future__ import annotations

import keyword
import math
import re
from dataclasses import dataclass
from typing import Any

import sympy as sp
from sympy.parsing.sympy_parser import parse_expr

from csim.schema import describe, finite_number

#: Functions and constants an expression may use besides the parameters.
FUNCTIONS: dict[str, Any] = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos, "atan": sp.atan,
    "atan2": sp.atan2, "sqrt": sp.sqrt, "exp": sp.exp, "pi": sp.pi, "deg": sp.pi / 180,
}

#: Names a parameter may not take: the generated code's arguments and locals, the time.
RESERVED = {"q", "qd", "par", "out", "math", "np", "t", "float"} | set(FUNCTIONS)

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_EXPRESSION_CHARS = re.compile(r"^[A-Za-z0-9_+\-*/().,^ \t]*$")
_GLOBALS = {"Integer": sp.Integer, "Float": sp.Float, "Rational": sp.Rational, "Symbol": sp.Symbol,
            "__builtins__": {}}


def valid_name(name: Any) -> bool:
    """A name usable as a symbol in generated code: an identifier, not reserved."""
    return isinstance(name, str) and bool(_NAME.match(name)) and not keyword.iskeyword(name) \
        and name not in RESERVED


def parse_expression(path: str, value: Any, symbols: dict[str, sp.Symbol], problems: list[str],
                     values: dict[sp.Symbol, float] | None = None) -> sp.Expr | None:
    """A number, or an expression string in ``symbols``, as an exact sympy expression.

    Floats become rationals (0.1 -> 1/10), so that sums cancel exactly.

    Parameters
    ----------
    path : str
        Key path for messages.
    value : int, float or str
    symbols : dict name -> Symbol
        The names the expression may use (besides :data:`FUNCTIONS`).
    problems : list of str
        Appended to, one line per problem.
    values : dict Symbol -> float, optional
        The parameter values. When given, an expression of these symbols only must be
        finite and real at them (``acos(e)`` with e = 2 is rejected).

    Returns
    -------
    sympy expression, or None when the value is not valid.
    """
    expr = _parse(path, value, symbols, problems)
    if expr is None or values is None:
        return expr
    what = value_problem(expr, values)
    if what is not None:
        problems.append(f"{path}: got {describe(value)}; at the parameter values it is {what}; expected a finite "
                        f"real value")
        return None
    return expr


def evaluate(expr: sp.Expr, values: dict[sp.Symbol, float]) -> complex | None:
    """The value of ``expr`` at ``values`` (nan for a pole), or None when other symbols remain."""
    if expr.free_symbols - set(values):
        return None
    exact = sp.sympify(expr).xreplace({s: sp.Float(v) for s, v in values.items()}).evalf()
    try:
        return complex(exact)
    except (TypeError, ValueError):
        return complex(math.nan)


def value_problem(expr: sp.Expr, values: dict[sp.Symbol, float]) -> str | None:
    """``"not finite"`` or ``"complex (VALUE)"`` when ``expr`` is not a finite real number at
    ``values``; None otherwise (or when other symbols remain)."""
    value = evaluate(expr, values)
    if value is None:
        return None
    if not (math.isfinite(value.real) and math.isfinite(value.imag)):
        return "not finite"
    if abs(value.imag) > 1e-12 * max(1.0, abs(value.real)):
        return f"complex ({value:.6g})"
    return None


def _parse(path: str, value: Any, symbols: dict[str, sp.Symbol], problems: list[str]) -> sp.Expr | None:
    """:func:`parse_expression` without the check at the parameter values."""
    allowed = ", ".join(sorted(symbols)) or "none"
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        problems.append(f"{path}: got {describe(value)}; expected a number or an expression of the parameters "
                        f"({allowed})")
        return None
    if isinstance(value, (int, float)) and not finite_number(value):  # .nan, .inf, 10**400
        problems.append(f"{path}: got {describe(value)}; expected a finite number")
        return None
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        return sp.Rational(repr(value))
    text = value.strip()
    if "//" in text or "**" in text or re.search(r"\^[^()+\-*/]*\^", text):
        problems.append(f"{path}: got {describe(value)}; expected + - * / and single powers ^ (no //, ** or "
                        f"a^b^c)")
        return None
    if not text or not _EXPRESSION_CHARS.match(text):
        problems.append(f"{path}: got {describe(value)}; expected an expression of numbers, the parameters "
                        f"({allowed}), + - * / ^ ( ) and {', '.join(FUNCTIONS)}")
        return None
    unknown = [name for name in _IDENT.findall(re.sub(r"\d+\.?\d*[eE][-+]?\d+", "0", text))
               if name not in symbols and name not in FUNCTIONS]
    if unknown:
        problems.append(f"{path}: got {describe(value)}; unknown name {unknown[0]!r}: expected a parameter "
                        f"({allowed}) or one of {', '.join(FUNCTIONS)}")
        return None
    try:
        expr = parse_expr(text.replace("^", "**"), local_dict={**FUNCTIONS, **symbols}, global_dict=dict(_GLOBALS))
        expr = sp.nsimplify(sp.sympify(expr), rational=True)
    except Exception as exc:
        problems.append(f"{path}: got {describe(value)}; not a valid expression ({type(exc).__name__})")
        return None
    if not isinstance(expr, sp.Expr) or expr.has(sp.zoo, sp.oo, sp.nan, sp.I):
        problems.append(f"{path}: got {describe(value)}; expected a finite real expression")
        return None
    return expr


@dataclass(frozen=True)
class Scope:
    """The names a table entry may use and their values.

    Attributes
    ----------
    symbols : dict name -> Symbol
        The parameters (real symbols).
    values : dict Symbol -> float
        Their values.
    """

    symbols: dict[str, sp.Symbol]
    values: dict[sp.Symbol, float]

    def parse(self, path: str, value: Any, problems: list[str]) -> sp.Expr | None:
        """:func:`parse_expression` of a table entry, checked at the parameter values."""
        return parse_expression(path, value, self.symbols, problems, self.values)
