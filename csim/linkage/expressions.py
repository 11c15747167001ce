"""Numbers and expressions of the named parameters, as they may be written in the tables.

A number may be written as an expression of the ``parameters`` (``l1``, ``xB/2``,
``90*deg``, ``pi/2``), built from + - * / ^, parentheses and :data:`FUNCTIONS`. It must be
finite and real at the parameter values (``acos(2)`` is not). Where the entry's unit is
known (a joint frame's p, a link's mass, com and inertia, gravity, a force element's
constants, a drive), a number may instead be written with a unit, ``50 mm``, ``30 deg``,
``4.5 kN/m``, converted to it (:func:`quantity_text`); a unit inside an expression
(``l1 + 5 mm``) is not read.

Before sympy sees an expression, its size is bounded (:func:`bound_problem`): at most
:data:`MAX_EXPRESSION_CHARS` characters, every constant part within the float range
(``9^999999999`` and ``((9^99)^99)^99`` are refused, not computed exactly), and a power
of anything not constant at most :data:`MAX_EXPONENT` (``(a+b)^100000``).
"""
from __future__ import annotations

import ast
import keyword
import math
import operator
import re
from dataclasses import dataclass
from typing import Any

import sympy as sp
from sympy.parsing.sympy_parser import parse_expr

from csim.quantities import convert, split
from csim.schema import cut, describe, finite_number

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


#: the longest expression, in characters
MAX_EXPRESSION_CHARS = 1000
#: the largest |exponent| of a power of a non-constant expression (of the parameters, the
#: coordinates or t), whose expansion or derivatives would otherwise grow without bound
MAX_EXPONENT = 64
#: the most digits of the exact value of a constant part (sympy computes 0.5^999999999 exactly; and
#: Python prints no integer of more than 4,300 digits)
MAX_EXACT_DIGITS = 4_000
#: the deepest nesting of parentheses and calls
MAX_NESTING = 50
#: the largest |exponent| of a number written 1e-5 (floats reach 1e308; below 1e-324 they are 0)
MAX_DECIMAL_EXPONENT = 400
#: the largest magnitude of a table entry's value [SI]: the model multiplies entries (a
#: position in a dot product with another, a mass with a length squared), and products of
#: three such values stay within the float range (1e308); a finite 1e308 written for a
#: joint's position overflowed in the closure equations' Jacobian
MAX_MAGNITUDE = 1e100
_EXPONENT = re.compile(r"[0-9.][eE]([-+]?[0-9]+)")

_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow}
_FLOAT_FUNCTIONS = {"sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin, "acos": math.acos,
                    "atan": math.atan, "atan2": math.atan2, "sqrt": math.sqrt, "exp": math.exp}
_FLOAT_CONSTANTS = {"pi": math.pi, "deg": math.pi / 180}


class _TooLarge(Exception):
    """An expression that :func:`bound_problem` refuses (the message says why)."""


def bound_problem(text: str) -> str | None:
    """Why the expression ``text`` (``^`` for powers) is too large to hand to sympy, or None.

    Walks Python's parse of the text, computing every constant part in floating point:
    a constant beyond the float range (``9^999999999``, ``((9^99)^99)^99``), a power of
    constants with a huge exact value (``0.5^999999999``, :data:`MAX_EXACT_DIGITS`) or a
    power of a non-constant part beyond :data:`MAX_EXPONENT` is refused, so that sympy never
    computes a huge exact integer, fraction or expansion. The cost is that of the text.
    """
    if len(text) > MAX_EXPRESSION_CHARS:
        return f"{len(text):,} characters long; expected at most {MAX_EXPRESSION_CHARS:,}"
    depth = deepest = 0
    for char in text:
        depth += (char == "(") - (char == ")")
        deepest = max(deepest, depth)
    if deepest > MAX_NESTING:
        return f"nested {deepest} parentheses deep; expected at most {MAX_NESTING}"
    for match in _EXPONENT.finditer(text):  # sympy turns 1e-400000000 into an exact fraction
        if abs(int(match.group(1))) > MAX_DECIMAL_EXPONENT:
            return (f"a number with the exponent {cut(match.group(1), 20)}; expected a number within the float "
                    f"range (an exponent of at most {MAX_DECIMAL_EXPONENT} in magnitude)")
    source = text.replace("^", "**")
    try:
        tree = ast.parse(source, mode="eval")
    except (SyntaxError, ValueError, RecursionError, MemoryError):
        return None  # not an expression: sympy's parser reports it
    try:
        _Constants(source).value(tree.body)
    except _TooLarge as exc:
        return str(exc)
    return None


class _Constants:
    """The float value of each constant part of an expression, with an estimate of the
    digits of its exact value (sympy's: a written number is a fraction, 0.1 = 1/10, and
    1e-300 has 301 digits); raises :class:`_TooLarge` for a part out of bounds."""

    def __init__(self, source: str):
        self.source = source

    def value(self, node: ast.AST) -> float | None:
        """The float value of ``node`` where it is constant (None otherwise)."""
        return self._walk(node)[0]

    def _walk(self, node: ast.AST) -> tuple[float | None, float]:
        """(float value or None, digits of the exact value; 0 for a part that is not constant)."""
        if isinstance(node, ast.Constant):
            return self._literal(node)
        if isinstance(node, ast.Name):
            value = _FLOAT_CONSTANTS.get(node.id)
            return value, (3.0 if value is not None else 0.0)  # pi, deg = pi/180
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            value, digits = self._walk(node.operand)
            return (None if value is None else (-value if isinstance(node.op, ast.USub) else value)), digits
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return self._binary(node)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
            parts = [self._walk(a) for a in node.args]
            function = _FLOAT_FUNCTIONS.get(node.func.id)
            if function is None or any(v is None for v, _ in parts) or node.keywords:
                return None, 0.0
            return _checked(lambda: function(*(v for v, _ in parts))), sum(d for _, d in parts)
        for child in ast.iter_child_nodes(node):  # anything else: its parts are still bounded
            self._walk(child)
        return None, 0.0

    def _literal(self, node: ast.Constant) -> tuple[float | None, float]:
        if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
            return None, 0.0
        try:
            value = float(node.value)
        except OverflowError:
            value = math.inf
        if math.isinf(value):  # 1e999 reads as inf
            raise _TooLarge("a number beyond the float range (about 1.8e308); expected a finite number")
        written = (ast.get_source_segment(self.source, node) or repr(node.value)).lower()
        mantissa, _, exponent = written.partition("e")
        return value, float(sum(c.isdigit() for c in mantissa) + abs(int(exponent or 0)))

    def _binary(self, node: ast.BinOp) -> tuple[float | None, float]:
        (left, d_left), (right, d_right) = self._walk(node.left), self._walk(node.right)
        power = isinstance(node.op, ast.Pow)
        if power and left is None and right is not None and abs(right) > MAX_EXPONENT:
            raise _TooLarge(f"a power ^{right:g} of an expression that is not constant; expected an exponent of at "
                            f"most {MAX_EXPONENT} in magnitude")
        if left is None or right is None:
            return None, 0.0
        value = _checked(lambda: _BINARY[type(node.op)](left, right))  # beyond the float range: refused here
        # the exact value's digits: a power multiplies the base's (0.5^999999999 is 1/2^999999999,
        # a billion digits, though 0.0 as a float); a sum, product or quotient adds them at most
        digits = d_left * max(1.0, abs(right)) + d_right if power else d_left + d_right
        if digits > MAX_EXACT_DIGITS:
            what = f"a power of constants ({left:g}^{right:g})" if power else "a constant"
            raise _TooLarge(f"{what} whose exact value has about {digits:.3g} digits, which sympy would compute; "
                            f"expected at most {MAX_EXACT_DIGITS:,} (write the value as a number)")
        return value, digits


def _checked(compute) -> float | None:
    """``compute()`` as a real float; :class:`_TooLarge` when it leaves the float range;
    None for a domain error, a division by zero or a complex value (sympy reports those)."""
    try:
        value = compute()
    except OverflowError:
        value = math.inf
    except (ValueError, ZeroDivisionError, TypeError):
        return None
    if isinstance(value, complex):
        return None
    if math.isinf(value):
        raise _TooLarge("a constant beyond the float range (about 1.8e308), which sympy would compute exactly; "
                        "expected constants within it")
    return value


def valid_name(name: Any) -> bool:
    """A name usable as a symbol in generated code: an identifier, not reserved."""
    return isinstance(name, str) and bool(_NAME.match(name)) and not keyword.iskeyword(name) \
        and name not in RESERVED


def parse_expression(path: str, value: Any, symbols: dict[str, sp.Symbol], problems: list[str],
                     values: dict[sp.Symbol, float] | None = None, unit: str | None = None) -> sp.Expr | None:
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
    unit : str, optional
        The entry's unit (``m``, ``rad``, ``kg m^2``): a number written with a unit
        (``50 mm``, ``30 deg``; :func:`quantity_text`) is converted to it. Without it such
        a value is refused, saying so.

    Returns
    -------
    sympy expression, or None when the value is not valid.
    """
    expr = _parse(path, value, symbols, problems, unit)
    if expr is None or values is None:
        return expr
    what = value_problem(expr, values)
    if what is not None:
        problems.append(f"{path}: got {describe(value)}; at the parameter values it is {what}; expected a finite "
                        f"real value of magnitude at most {MAX_MAGNITUDE:g}")
        return None
    return expr


def evaluate(expr: sp.Expr, values: dict[sp.Symbol, float]) -> complex | None:
    """The value of ``expr`` at ``values`` (nan for a pole), or None when other symbols remain."""
    if expr.free_symbols - set(values):
        return None
    exact = sp.sympify(expr).xreplace({s: sp.Float(v) for s, v in values.items()}).evalf()
    try:
        return complex(exact)
    except OverflowError:  # beyond the float range
        return complex(math.inf)
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
    if abs(value) > MAX_MAGNITUDE:
        return f"{value.real:.6g} (products of such values overflow the float range)"
    if abs(value.imag) > 1e-12 * max(1.0, abs(value.real)):
        return f"complex ({value:.6g})"
    return None


def quantity_text(text: str, symbols: dict[str, sp.Symbol]) -> tuple[str, str] | None:
    """(number, unit) of an entry written as a number with a unit and a space between them
    (``50 mm``, ``30 deg``), or None for a number or an expression. Text that names a
    parameter (or ``t``, a joint variable: any of ``symbols``) is an expression (``2*l1``,
    ``2 l1``); so is a number times a name (``90*deg``, ``2*pi*t``, and ``0.5*g`` with no
    parameter ``g``, which is reported as an unknown name rather than read as grams)."""
    parts = split(text)
    if parts is None:
        return None
    number, unit, star = parts
    names = _IDENT.findall(unit)
    if star or any(name in symbols for name in names):
        return None
    return number, unit


#: units written for degrees (converted to rad exactly: 90 deg is pi/2)
_DEGREES = ("deg", "degree", "degrees", "°")


def _quantity(path: str, value: str, number: str, unit_text: str, unit: str | None,
              problems: list[str]) -> sp.Expr | None:
    """A table entry written with a unit, converted to the entry's ``unit``, exactly for degrees
    to rad."""
    if unit is None:
        problems.append(f"{path}: got {describe(value)}; a unit is not read in this entry; expected a number or an "
                        f"expression of the parameters, in SI units (90*deg for an angle)")
        return None
    converted, problem = convert(value, unit)
    if problem is not None:
        problems.append(f"{path}: got {describe(value)}; {problem}")
        return None
    if not finite_number(converted):
        problems.append(f"{path}: got {describe(value)} = {converted} {unit}; expected a finite number")
        return None
    if unit == "rad" and unit_text in _DEGREES:
        return sp.Rational(repr(float(number))) * sp.pi / 180
    return sp.Rational(repr(converted))


def _parse(path: str, value: Any, symbols: dict[str, sp.Symbol], problems: list[str],
           unit: str | None = None) -> sp.Expr | None:
    """:func:`parse_expression` without the check at the parameter values."""
    allowed = ", ".join(sorted(symbols)) or "none"
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        problems.append(f"{path}: got {describe(value)}; expected a number or an expression of the parameters "
                        f"({allowed})")
        return None
    if isinstance(value, (int, float)) and not finite_number(value):  # .nan, .inf, 10**400
        problems.append(f"{path}: got {describe(value)}; expected a finite number")
        return None
    if isinstance(value, (int, float)) and abs(value) > MAX_MAGNITUDE:
        problems.append(f"{path}: got {describe(value)}; expected a number of magnitude at most {MAX_MAGNITUDE:g}")
        return None
    if isinstance(value, int):
        return sp.Integer(value)
    if isinstance(value, float):
        return sp.Rational(repr(value))
    text = value.strip()
    quantity = quantity_text(text, symbols)
    if quantity is not None:
        return _quantity(path, value, *quantity, unit, problems)
    if "//" in text or "**" in text or re.search(r"\^[^()+\-*/]*\^", text):
        problems.append(f"{path}: got {describe(value)}; expected + - * / and single powers ^ (no //, ** or "
                        f"a^b^c)")
        return None
    if not text or not _EXPRESSION_CHARS.match(text):
        problems.append(f"{path}: got {describe(value)}; expected an expression of numbers, the parameters "
                        f"({allowed}), + - * / ^ ( ) and {', '.join(FUNCTIONS)}")
        return None
    too_large = bound_problem(text)
    if too_large is not None:
        problems.append(f"{path}: got {describe(value)}; {too_large}")
        return None
    unknown = [name for name in _IDENT.findall(re.sub(r"\d+\.?\d*[eE][-+]?\d+", "0", text))
               if name not in symbols and name not in FUNCTIONS]
    if unknown:
        problems.append(f"{path}: got {describe(value)}; unknown name {unknown[0]!r}, not a parameter of "
                        f"mechanism.parameters (define it there) nor a name this value may use; expected one of "
                        f"{allowed} or {', '.join(FUNCTIONS)}")
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

    def parse(self, path: str, value: Any, problems: list[str], unit: str | None = None) -> sp.Expr | None:
        """:func:`parse_expression` of a table entry in ``unit``, checked at the parameter values."""
        return parse_expression(path, value, self.symbols, problems, self.values, unit)
