"""Values written with a unit in case files: ``172 deg``, ``10 ms``, ``4530 N/m``, ``1.5e-3 kg*m^2``.

A value that is a number followed by a unit (a space or ``*`` between them, or nothing) is
converted with pint to the unit of its key: :attr:`csim.schema.Field.unit`, a mechanism
parameter's unit, rad or m for a coordinate (rad/s or m/s for a velocity), the unit of a
link-coupling table entry. A plain number is taken in the key's unit, as always; pint is
imported only when a value carries a unit, so the plain path costs nothing.

- ``deg`` converts to rad, ``ms`` to s, ``mm`` to m, ``rpm`` to rad/s. pint counts an
  angle as dimensionless: ``30 deg`` is accepted by a dimensionless key (as 0.5236); on a
  key in rad or rad/s, a frequency (``Hz``: 1 rad/s to pint, not a turn per second) and a
  percentage are refused (write ``rpm`` or ``rad/s``).
- A key without a unit (``""`` or ``"-"``: counts, ratios such as ``rtol``) refuses a unit;
  so does a key in the unit of the constraints (``unit of Phi``), which depends on the
  mechanism.
- A key whose unit is :data:`SI_BASE` (a link-coupling parameter, an extra parameter of
  force elements: csim does not know what it measures) takes the value in SI base units:
  ``50 mm`` is 0.05, ``30 deg`` is 0.5236, ``4530 N/m`` is 4530.

Every failure is a sentence saying what was expected (:func:`convert`), for the caller to
put after the key and the value.
"""
from __future__ import annotations

import functools
import math
import re
from typing import Any

#: the unit of a key that takes any unit, converted to SI base units (m, kg, s, rad, ...)
SI_BASE = "SI base units"
#: units that mean "no unit": such a key refuses a value with a unit
NO_UNIT = ("", "-")
#: the longest value read as a quantity
MAX_QUANTITY_CHARS = 80

_NUMBER = r"[-+]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][-+]?[0-9]+)?"
#: how a unit starts: a letter (or %, °, µ), or 1/ after a space (10 1/s; 101/s is not a quantity)
_UNIT_START = r"(?:(?<=\s)1\s*/\s*)?[A-Za-z_%°µμΩ]"
_UNIT_CHARS = "A-Za-z0-9_%°µμΩ *·/^().+-"
#: the number ends where a unit starts: 1e-3 is a number, not 1 with the unit e-3
_NUMBER_END = r"(?![eE][-+]?[0-9])"
QUANTITY = re.compile(rf"^\s*({_NUMBER}){_NUMBER_END}\s*(\*?)\s*({_UNIT_START}[{_UNIT_CHARS}]*?)\s*$")
#: a power in a unit: ^ or ** and an integer of at most two digits (m^2, s^-1, m**(-2))
_BAD_POWER = re.compile(r"(?:\^|\*\*)(?!\s*\(?\s*[-+]?[0-9]{1,2}\s*\)?(?![0-9.]))")
#: a power of a power (s^9^9^9: pint reads it right to left, 9**(9**9), and does not return)
_POWER_TOWER = re.compile(r"(?:\^|\*\*)\s*\(?\s*[-+]?[0-9]+\s*\)?\s*(?:\^|\*\*)")

#: JSON Schema (ECMA-262 regex) of a value with a unit, for editors: a number, then a unit
JSON_PATTERN = rf"^\s*{_NUMBER}{_NUMBER_END}\s*\*?\s*(?:1\s*/\s*)?[A-Za-z_%°µμΩ][{_UNIT_CHARS}]*$"
JSON_QUANTITY_DEFINITION = {"type": "string", "pattern": JSON_PATTERN,
                            "description": "a number with its unit, converted to the key's unit (172 deg, 10 ms, "
                                           "4530 N/m)"}
#: where a value may be written with its unit: a reference to the case schema's ``definitions``
#: (:func:`csim.case.json_schema` puts :data:`JSON_QUANTITY_DEFINITION` there)
JSON_QUANTITY = {"$ref": "#/definitions/quantity"}


def split(value: Any) -> tuple[str, str, bool] | None:
    """(number text, unit text, written with ``*``) of a value with a unit; None for anything else
    (a number, a word, text too long)."""
    if not isinstance(value, str) or len(value) > MAX_QUANTITY_CHARS:
        return None
    match = QUANTITY.match(value)
    if match is None:
        return None
    return match.group(1), match.group(3).strip(), bool(match.group(2))


def is_quantity(value: Any) -> bool:
    """Whether ``value`` is text written as a number followed by a unit (``10 ms``)."""
    return split(value) is not None


def convertible(unit: str | None) -> bool:
    """Whether a key in ``unit`` takes a value with a unit (a unit pint reads, or :data:`SI_BASE`)."""
    return unit is not None and unit not in NO_UNIT and "unit of Phi" not in unit


#: (unit written, key's unit) -> factor, converted without pint
_FAST = {**{(name, "rad"): math.pi / 180 for name in ("deg", "degree", "degrees", "°")},
         **{(name, name): 1.0 for name in ("rad", "m", "s", "kg", "N", "N m", "m/s", "rad/s")}}


@functools.cache
def registry():
    """pint's unit registry (imported on first use: only a value with a unit needs it)."""
    import pint

    return pint.UnitRegistry()


def convert(value: str, unit: str | None) -> tuple[float | None, str | None]:
    """``value`` (``"10 ms"``) as a number in ``unit`` (``"s"``).

    Parameters
    ----------
    value : str
        A number followed by a unit (:func:`is_quantity`).
    unit : str
        The key's unit as csim declares it (``s``, ``kg m^2``, ``rad/s``, ``1``), or
        :data:`SI_BASE`.

    Returns
    -------
    (number, None), or (None, problem): ``problem`` says why the value is refused and what
    was expected, e.g. ``"'kg' is the unit of a mass ([mass]), not of a time; expected a
    number in s, or a time ([time]) with its unit (such as 10 ms)"``.
    """
    parts = split(value)
    if parts is None:
        return None, f"expected a number{_in(unit)}, or a number followed by its unit (such as 10 ms)"
    number_text, unit_text, _ = parts
    if unit is None or unit in NO_UNIT:
        return None, "this key has no unit; expected a plain number, without a unit"
    if "unit of Phi" in unit:
        return None, (f"this key is in {unit}, which depends on the mechanism's constraints (m or 1), so csim does "
                      f"not convert it; expected a plain number, without a unit")
    fast = _FAST.get((unit_text, "rad" if unit == SI_BASE else unit))
    if fast is not None:  # an angle in degrees, a value in the key's own unit: no pint (1 s to load)
        return float(number_text) * fast, None
    if _POWER_TOWER.search(unit_text):
        return None, f"the unit {unit_text!r} raises a power to a power; expected powers such as m^2 or s^-1"
    if _BAD_POWER.search(unit_text):
        return None, (f"the unit {unit_text!r} has a power that is not a small integer; expected powers such as m^2 "
                      f"or s^-1")
    try:
        ureg = registry()
    except ImportError:
        return None, (f"a value with a unit needs pint, which is not installed (pip install 'pint>=0.23'); "
                      f"expected a number{_in(unit)}")
    import pint

    try:
        given = ureg.parse_units(unit_text.replace("·", "*"))
    except pint.UndefinedUnitError as exc:
        names = getattr(exc, "unit_names", None) or ()
        names = [names] if isinstance(names, str) else [str(n) for n in names]
        where = f" in {unit_text!r}" if names and names != [unit_text] else ""
        unknown = ", ".join(repr(n) for n in names) or repr(unit_text)
        return None, f"unknown unit {unknown}{where}; expected a number{_in(unit)}{_example(ureg, unit)}"
    except Exception as exc:  # pint's parser: a syntax error, an unbalanced parenthesis, ...
        return None, (f"{unit_text!r} is not a unit pint reads ({type(exc).__name__}); expected a number"
                      f"{_in(unit)}{_example(ureg, unit)}")
    quantity = ureg.Quantity(float(number_text), given)
    # pint counts an angle as dimensionless: 1 Hz would read as 1 rad/s (not a turn per second)
    # and 50 % as 0.5 rad; on an angle's key such units are refused
    if unit != SI_BASE and "rad" in unit:
        if "%" in unit_text or "percent" in unit_text:
            return None, f"{unit_text!r} is a fraction, not an angle; expected a number{_in(unit)}, or deg or rad"
        if given.dimensionality == ureg.parse_units("Hz").dimensionality and "rad" not in str(given) \
                and "rpm" not in unit_text and "deg" not in unit_text:
            return None, (f"{unit_text!r} is a frequency, which csim does not take as an angular velocity (1 Hz "
                          f"would read as 1 rad/s, not 2 pi rad/s); expected a number{_in(unit)}, or rpm or rad/s")
    try:
        if unit == SI_BASE:
            return _clean(quantity.to_base_units().magnitude), None
        target = ureg.parse_units(unit)
        return _clean(quantity.to(target).magnitude), None
    except pint.DimensionalityError:
        if unit == SI_BASE:
            return None, f"{unit_text!r} has no value in SI base units; expected a number{_in(unit)}"
        return None, (f"{unit_text!r} is the unit of {_dimension(given.dimensionality)}, not of "
                      f"{DIMENSIONS.get(str(target.dimensionality), str(target.dimensionality))}; expected a number"
                      f"{_in(unit)}{_example(ureg, unit)}")
    except (pint.PintError, ArithmeticError, ValueError, TypeError) as exc:
        return None, f"{value!r} cannot be converted to {unit} ({type(exc).__name__}); expected a number{_in(unit)}"


def _clean(number) -> float:
    """``number`` to 15 significant digits: ``350 mm`` is 0.35, not pint's 0.35000000000000003
    (a relative change below 5e-16, far below what any value given is known to)."""
    number = float(number)
    return float(f"{number:.15g}") if math.isfinite(number) else number


def _in(unit: str | None) -> str:
    if unit == SI_BASE:
        return " (in SI units)"
    return f" in {unit}" if unit and unit not in NO_UNIT else ""


#: names of the dimensions of csim's keys, for messages
DIMENSIONS = {
    "dimensionless": "a pure number or an angle", "[length]": "a length", "[time]": "a time", "[mass]": "a mass",
    "1 / [time]": "a rate or angular velocity", "[length] / [time]": "a velocity",
    "[length] / [time] ** 2": "an acceleration", "[mass] * [length] / [time] ** 2": "a force",
    "[mass] * [length] ** 2 / [time] ** 2": "a torque or energy", "[mass] / [time] ** 2": "a force per length",
    "[mass] * [length] ** 2": "a moment of inertia", "[mass] / [time]": "a force per velocity",
    "[mass] * [length] ** 2 / [time]": "a torque per angular velocity",
}


def _dimension(dimensionality) -> str:
    """``a time ([time])``, ``a pure number or an angle``, or the dimension alone (``[length] ** 3``)."""
    text = str(dimensionality)
    if text == "dimensionless":
        return DIMENSIONS[text]
    return f"{DIMENSIONS[text]} ({text})" if text in DIMENSIONS else text


def _example(ureg, unit: str) -> str:
    """``", or a value with a unit of dimension [time] (such as '10 ms')"`` for the key's unit."""
    if unit == SI_BASE:
        return ", or a number with a unit pint knows (such as 50 mm)"
    try:
        dimension = ureg.parse_units(unit).dimensionality
    except Exception:
        return ""
    example = EXAMPLES.get(unit, f"1 {unit}" if unit[:1].isalpha() else "")
    return f", or {_dimension(dimension)} with its unit" + (f" (such as {example})" if example else "")


#: a value with a unit, in a message, for a key's unit
EXAMPLES = {"s": "10 ms", "m": "50 mm", "rad": "30 deg", "kg": "250 g", "rad/s": "60 rpm", "m/s": "36 km/h",
            "N/m": "4.5 kN/m", "kg m^2": "1.5e-3 kg*m^2", "N m": "20 N*m", "N": "1 kN", "m/s^2": "9.81 m/s^2",
            "1/s": "10 1/s", "1": "50 %"}
