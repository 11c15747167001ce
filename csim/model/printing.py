"""A quick printer of the statements of a mechanism built link by link, as Python or C.

The named intermediates of :mod:`csim.model.recursive` are thousands of short sums of
products of symbols, numbers, sines and cosines; sympy's code printers spend about a
millisecond on each (assumption queries, term ordering), most of the code generation of
a large mechanism. :class:`QuickPrinter` prints these node types directly, always
parenthesizing sums and powers inside products, and hands any other node (atan2, sqrt,
a piecewise law, ...) to the sympy printer it wraps, so that the code means the same.
"""
from __future__ import annotations

import sympy as sp


class QuickPrinter:
    """Print sympy expressions as Python (``math.``) or C (``math.h``) expressions.

    Parameters
    ----------
    fallback : sympy CodePrinter
        Prints what this printer does not (and defines how symbols are named).
    language : {"python", "c"}
    symbol : callable Symbol -> str
        The name of a symbol in the code.
    """

    def __init__(self, fallback, language: str, symbol):
        if language not in ("python", "c"):
            raise ValueError(f"language {language!r}; expected 'python' or 'c'")
        self.fallback, self.c, self.symbol = fallback, language == "c", symbol
        self.functions = {sp.sin: "sin", sp.cos: "cos"}
        self.prefix = "" if self.c else "math."
        self.memo: dict = {}

    def doprint(self, expr) -> str:
        if expr not in self.memo:
            self.memo[expr] = self._print(sp.sympify(expr))
        return self.memo[expr]

    def _number(self, expr) -> str:
        if expr.is_Integer:
            n = int(expr)
            return str(n) if abs(n) < 2**53 or not self.c else repr(float(n))
        if expr.is_Rational:
            p, q = int(expr.p), int(expr.q)
            return f"({p}.0/{q}.0)" if self.c else f"({p}/{q})"
        if expr.is_Float:
            return repr(float(expr))
        return f"({self.fallback.doprint(expr)})"

    def _print(self, expr) -> str:
        if expr.is_Symbol:
            return self.symbol(expr)
        if expr.is_Number:
            text = self._number(expr)
            return f"({text})" if text.startswith("-") else text
        if expr.is_Add:
            out = []
            for term in expr.args:
                coeff, rest = term.as_coeff_Mul()
                if coeff.is_Number and coeff < 0:
                    out.append(" - " + self._print(-term))
                else:
                    out.append(" + " + self._print(term))
            text = "".join(out)
            return "(" + (text[3:] if text.startswith(" + ") else "-" + text[3:]) + ")"
        if expr.is_Mul:
            coeff, rest = expr.as_coeff_Mul()
            factors = [self._print(f) for f in sp.Mul.make_args(rest)]
            if coeff == -1:
                return "(-" + "*".join(factors) + ")"
            if coeff != 1:
                factors.insert(0, self._print(coeff))
            return "*".join(factors)
        if expr.is_Pow and expr.exp.is_Integer:
            n = int(expr.exp)
            base = self._print(expr.base)
            if 0 < n <= 3:
                return "(" + "*".join([base] * n) + ")"
            if -3 <= n < 0:
                return "(1.0/(" + "*".join([base] * -n) + "))"
        if expr.func in self.functions and len(expr.args) == 1:
            return f"{self.prefix}{self.functions[expr.func]}({self._print(expr.args[0])})"
        return f"({self.fallback.doprint(expr)})"


def expression_printer(derived, printer, language: str, symbol):
    """The print function of one generated module, each distinct expression printed once: the
    sympy ``printer``, or for a mechanism built link by link
    (:class:`csim.model.printing.QuickPrinter`) a quick printer falling back to it."""
    if derived.intermediates:
        return QuickPrinter(printer, language, symbol).doprint
    memo: dict = {}

    def doprint(expr) -> str:
        if expr not in memo:
            memo[expr] = printer.doprint(expr)
        return memo[expr]

    return doprint
