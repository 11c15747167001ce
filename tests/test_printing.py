"""The quick printer of csim.model.printing against sympy's own evaluation: the same value in
Python and in C syntax, for the node types it prints itself and for those it hands on."""
from __future__ import annotations

import math

import pytest
import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from csim.model.printing import QuickPrinter

x, y, z = sp.symbols("x y z", real=True)
VALUES = {x: 0.7, y: -1.3, z: 2.1}
EXPRESSIONS = [
    x * y - z,
    -x * y + sp.Rational(3, 7) * z ** 2,
    sp.sin(x + y) * sp.cos(z) - 2 * x ** 3,
    (x - y) / (z ** 2 + 1),
    sp.Float("0.1", 17) * x - sp.Rational(-5, 3),
    sp.sqrt(z) + sp.atan2(y, x),                       # handed to the sympy printer
    -(x + y) * (y - z),
    x ** -2 - y ** -1,
    sp.Integer(10) ** 20 * x / sp.Integer(10) ** 21,   # beyond 2^53: a double in C
]


def python_value(text: str) -> float:
    return eval(text, {"math": math}, {str(k): v for k, v in VALUES.items()})


def c_value(text: str) -> float:
    """Evaluate C syntax as Python: same operators; pow/sqrt/sin/... from math, doubles as floats."""
    names = {f"s_{k}": v for k, v in VALUES.items()}
    names.update(pow=math.pow, sqrt=math.sqrt, sin=math.sin, cos=math.cos, atan2=math.atan2)
    return eval(text, {}, names)


@pytest.mark.parametrize("expr", EXPRESSIONS, ids=range(len(EXPRESSIONS)))
def test_quick_printer_keeps_the_value(expr):
    expected = float(expr.xreplace(VALUES))
    py = QuickPrinter(PythonCodePrinter(), "python", str).doprint(expr)
    assert python_value(py) == pytest.approx(expected, rel=1e-14)
    from csim.fast.ccodegen import _Printer

    c = QuickPrinter(_Printer(), "c", lambda s: f"s_{s.name}").doprint(expr)
    assert c_value(c) == pytest.approx(expected, rel=1e-14)


def test_quick_printer_rejects_an_unknown_language():
    with pytest.raises(ValueError, match="language"):
        QuickPrinter(PythonCodePrinter(), "fortran", str)
