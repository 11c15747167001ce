"""What ``--vary KEY=VALUES`` means: the values one case key takes in a sweep.

VALUES is one of

``1,2,5``
    a list (each item parsed as a case-file value: numbers, names, ``[20, 30]`` lists when
    the whole list is written in YAML flow style, e.g. ``[[20, 30], [40, 60]]``);
``lin:START:STOP:N``
    N values evenly spaced from START to STOP (both included; whole numbers when START and
    STOP are written as whole numbers and every value is one, for integer keys);
``log:START:STOP:N``
    N values evenly spaced in log10 from START to STOP (both positive, both included);
``@FILE``
    the values in a text file: one per line, or a YAML list (``#`` comments allowed).

A value, or a range's START and STOP, may be written with its unit (``170 deg,172 deg``,
``lin:100 ms:2 s:20``); :meth:`Variation.in_unit` converts them to the key's unit once the
base case is known (:func:`csim.study.plan.make_plan`), so the sweep file holds numbers.

For random and Latin-hypercube sampling (:mod:`csim.study.plan`) a range is a
distribution: ``lin:A:B`` uniform on [A, B], ``log:A:B`` log-uniform; N may then be left
out. A list is sampled uniformly among its items.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from csim.case import MAX_YAML_CHARS, CaseLoader, YamlTooLarge
from csim.errors import CaseError
from csim.quantities import convert, is_quantity
from csim.schema import short_repr

#: range kinds
RANGES = ("lin", "log")
#: most values one range may give
MAX_VALUES = 10_000_000


@dataclass(frozen=True)
class Variation:
    """One varied case key.

    Attributes
    ----------
    key : str
        The case-file key path, as for ``--set`` (``stabilization.w``).
    values : tuple
        The grid values (for a range given without N: empty; sampling only).
    kind : {"list", "lin", "log"}
        How the values were given.
    bounds : tuple of float or None
        (START, STOP) of a range.
    text : str
        The option as given (for messages and the result file).
    ends : tuple of str or None
        START and STOP of a range as written, when one carries a unit (``100 ms``): then
        ``values`` and ``bounds`` wait for :meth:`in_unit`.
    count : int or None
        N of such a range (None: sampling only).
    """

    key: str
    values: tuple
    kind: str = "list"
    bounds: tuple[float, float] | None = None
    text: str = ""
    ends: tuple[str, str] | None = None
    count: int | None = None

    @property
    def has_units(self) -> bool:
        """Whether a value (or a range end) is written with a unit, to be converted by :meth:`in_unit`."""
        return self.ends is not None or any(is_quantity(v) for v in self.values)

    def in_unit(self, unit: str | None) -> Variation:
        """This variation with every value written with a unit converted to ``unit`` (the
        key's; see :mod:`csim.quantities`). A key csim knows no unit for (``None``) keeps a
        list's values as written, for the case check to convert run by run.

        Raises
        ------
        CaseError
            Naming the option and the value, when a unit does not fit the key.
        """
        if not self.has_units:
            return self
        option = f"--vary {short_repr(self.text)}"
        if unit is None and self.ends is None:
            return self
        if unit is None:
            raise CaseError([f"{option}: csim does not know the unit of {self.key}; write START and STOP as plain "
                             f"numbers"])

        def number(value: Any, what: str) -> Any:
            if not is_quantity(value):
                return value
            converted, problem = convert(value, unit)
            if problem is not None:
                raise CaseError([f"{option}: {what} {value!r}: {problem}"])
            return converted

        if self.ends is None:
            return dataclasses.replace(self, values=tuple(number(v, "the value") for v in self.values))
        a, b = (_number(option, number(end, what), what) for end, what in zip(self.ends, ("START", "STOP")))
        _check_ends(option, self.kind, a, b, *self.ends)
        values = () if self.count is None else _grid(self.kind, a, b, self.count, whole=False)
        return dataclasses.replace(self, values=values, bounds=(a, b), ends=None)

    @property
    def numeric(self) -> bool:
        """Whether every value is a real number (not a name, a list or a bool)."""
        return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in self.values) or (
            self.kind in RANGES)

    def sample(self, u: np.ndarray) -> list:
        """Values at the unit-interval numbers ``u`` (n,): the inverse of this key's distribution."""
        if self.kind == "lin":
            a, b = self.bounds
            return [float(a + (b - a) * x) for x in u]
        if self.kind == "log":
            a, b = (math.log10(x) for x in self.bounds)
            return [float(10.0 ** (a + (b - a) * x)) for x in u]
        n = len(self.values)
        return [self.values[min(int(x * n), n - 1)] for x in u]


def _scalar(text: str, option: str) -> Any:
    """One value as a case file would read it (``1e-3`` a float, ``none`` a name); a value
    beyond the YAML bounds is a CaseError naming ``option``."""
    text = text.strip()
    try:
        return yaml.load(text, Loader=CaseLoader) if text else None
    except YamlTooLarge as exc:
        raise CaseError([f"{option}: the value {short_repr(text)} is {exc}"]) from None
    except (yaml.YAMLError, ValueError):
        return text


def _number(option: str, part: Any, what: str) -> float:
    try:
        x = float(part)
    except (TypeError, ValueError):
        raise CaseError([f"{option}: {what} {part!r} is not a number (nor a number with its unit, such as "
                         f"10 ms)"]) from None
    if not math.isfinite(x):
        raise CaseError([f"{option}: {what} {part!r} is not a finite number"])
    return x


def _check_ends(option: str, kind: str, a: float, b: float, start: str, stop: str) -> None:
    if kind == "log" and (a <= 0 or b <= 0):
        raise CaseError([f"{option}: a log range needs positive START and STOP; got {start} and {stop}"])


def _range(option: str, kind: str, parts: list[str]) -> dict:
    """The fields of a :class:`Variation` for ``lin:A:B[:N]`` or ``log:A:B[:N]``: the values
    and bounds, or, when an end carries a unit, the ends as written and N."""
    example = f"{kind}:1e-4:1e-1:13" if kind == "log" else f"{kind}:0:1:11"
    if len(parts) not in (2, 3):
        raise CaseError([f"{option}: expected {kind}:START:STOP:N (N may be left out for --sample), "
                         f"e.g. {example}"])
    n = None
    if len(parts) == 3:
        try:
            n = int(parts[2])
        except ValueError:
            raise CaseError([f"{option}: N {parts[2]!r} is not a whole number"]) from None
        if not 1 <= n <= MAX_VALUES:
            raise CaseError([f"{option}: N must be from 1 to {MAX_VALUES:,}; got {n}"])
    start, stop = parts[0].strip(), parts[1].strip()
    if is_quantity(start) or is_quantity(stop):  # converted by Variation.in_unit, once the key's unit is known
        return {"values": (), "ends": (start, stop), "count": n}
    a, b = _number(option, start, "START"), _number(option, stop, "STOP")
    _check_ends(option, kind, a, b, start, stop)
    values = () if n is None else _grid(kind, a, b, n, whole=_whole(start) and _whole(stop))
    return {"values": values, "bounds": (a, b)}


def _grid(kind: str, a: float, b: float, n: int, whole: bool) -> tuple:
    """N values from ``a`` to ``b``, evenly spaced (``lin``) or evenly in log10 (``log``);
    whole numbers when ``whole`` (both ends written whole) and every value is one."""
    grid = np.linspace(a, b, n) if kind == "lin" else np.logspace(math.log10(a), math.log10(b), n)
    if n > 1:  # the ends exactly as written, not as exp(log(x)) gives them back
        grid[0], grid[-1] = a, b
    if whole and np.all(grid == np.round(grid)):  # an integer key's range
        return tuple(int(x) for x in grid)
    return tuple(float(x) for x in grid)


def _whole(text: str) -> bool:
    """Whether a range end is written as a whole number (``100000``, not ``1e5`` or ``1.0``)."""
    return text.strip().lstrip("+-").isdigit()


def _from_file(option: str, name: str, base: Path) -> tuple:
    path = Path(name) if Path(name).is_absolute() else base / name
    try:
        text = path.read_text()
    except OSError as exc:
        raise CaseError([f"{option}: cannot read the values file {str(path)!r}: {exc.strerror or exc}"]) from None
    if len(text) > MAX_YAML_CHARS:
        raise CaseError([f"{option}: the values file {str(path)!r} is {len(text):,} characters long; expected at "
                         f"most {MAX_YAML_CHARS:,}"])
    try:
        data = yaml.load(text, Loader=CaseLoader)
    except YamlTooLarge as exc:
        raise CaseError([f"{option}: the values file {str(path)!r} is {exc}"]) from None
    except (yaml.YAMLError, ValueError):
        data = None
    if not isinstance(data, list):  # one value per line
        data = [_scalar(line.split("#", 1)[0], option) for line in text.splitlines()
                if line.split("#", 1)[0].strip()]
    return tuple(data)


def parse_variation(text: str, base: Path = Path(".")) -> Variation:
    """A ``--vary KEY=VALUES`` option (``base``: the folder ``@FILE`` names are relative to).

    Raises
    ------
    CaseError
        Naming the option, when it is malformed or gives no values.
    """
    option = f"--vary {short_repr(text)}"
    if "=" not in text:
        raise CaseError([f"{option}: expected KEY=VALUES, e.g. --vary stabilization.w=lin:1:40:20"])
    key, spec = (part.strip() for part in text.split("=", 1))
    if not key:
        raise CaseError([f"{option}: the key is empty; expected KEY=VALUES"])
    head, _, rest = spec.partition(":")
    if head in RANGES and rest:
        return Variation(key=key, kind=head, text=text, **_range(option, head, rest.split(":")))
    if spec.startswith("@"):
        values = _from_file(option, spec[1:], base)
    elif spec.startswith("[") and spec.endswith("]") and isinstance(_scalar(spec, option), list):
        values = tuple(_scalar(spec, option))
    else:
        values = tuple(_scalar(item, option) for item in spec.split(","))
    if not values or any(v is None for v in values):
        raise CaseError([f"{option}: no value, or an empty one; expected e.g. {key}=1,2,5 or {key}=lin:0:1:11"])
    return Variation(key=key, values=values, text=text)
