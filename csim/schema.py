"""A small declarative schema for case files: types, defaults, bounds, documentation.

Validation collects every problem at once, each naming the key path, the value found and
what was expected, e.g. ``simulation.t_end: got -1 (number); expected a number > 0``.
The same declarations give the JSON Schema that editors validate case files with
(:func:`section_json_schema`, ``csim schema``).
"""
from __future__ import annotations

import difflib
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, make_dataclass
from dataclasses import field as dataclass_field
from typing import Any

from csim.quantities import JSON_QUANTITY, convert, convertible, is_quantity

REQUIRED = object()

TYPE_NAMES = {
    "number": "a number",
    "integer": "an integer",
    "string": "a string",
    "boolean": "true or false",
    "mapping": "a mapping (key: value lines)",
    "list": "a list",
}


@dataclass(frozen=True)
class Field:
    """One leaf of the schema.

    Parameters
    ----------
    type : {"number", "integer", "string", "boolean", "mapping", "list", "any"}
    default : object
        Value used when the key is absent; ``REQUIRED`` makes the key mandatory.
    doc : str
        One line for a person (shown by ``csim`` help and in the README).
    unit : str
    choices : tuple or callable or None
        Allowed values (a callable returns them, for registries).
    gt, ge, le : float or None
        Bounds for numbers: > gt, >= ge, <= le.
    nullable : bool
        ``null`` is allowed.
    check : callable or None
        Extra check ``check(value) -> str or None`` returning what was expected.
    json : dict or None
        JSON Schema keywords saying what ``check`` tests (for ``type: "any"``, the whole
        schema of the value), added to what the other attributes give.
    """

    type: str
    default: Any = REQUIRED
    doc: str = ""
    unit: str = ""
    choices: Any = None
    gt: float | None = None
    ge: float | None = None
    le: float | None = None
    nullable: bool = False
    check: Callable[[Any], str | None] | None = None
    json: dict | None = None

    def expected(self) -> str:
        """What a valid value looks like, for error messages."""
        text = TYPE_NAMES.get(self.type, "a value")
        bounds = []
        if self.gt is not None:
            bounds.append(f"> {self.gt:g}")
        if self.ge is not None:
            bounds.append(f">= {self.ge:g}")
        if self.le is not None:
            bounds.append(f"<= {self.le:g}")
        if bounds:
            text += " " + " and ".join(bounds)
        choices = self.valid_choices()
        if choices is not None:
            text = "one of " + ", ".join(str(c) for c in choices)
        if self.nullable:
            text += " (or null)"
        return text

    def valid_choices(self):
        return self.choices() if callable(self.choices) else self.choices


#: how many characters of a value a message shows (:func:`short_repr`)
SHOWN_CHARS = 60


def describe(value: Any) -> str:
    """``value`` as it reads in a message, with its YAML type (``null`` for None)."""
    if value is None:
        return "null"
    kind = {bool: "boolean", int: "integer", float: "number", str: "string",
            dict: "mapping", list: "list"}.get(type(value), type(value).__name__)
    return f"{short_repr(value)} ({kind})"


def short_repr(value: Any, limit: int = SHOWN_CHARS) -> str:
    """``repr(value)`` cut to ``limit`` characters (ending in ``...``), built piece by piece so
    that only what is shown is ever formatted: a list of a billion entries, a string of a
    megabyte, an integer of a million digits or a list that contains itself costs no more
    than a short one."""
    out, length = [], 0
    for piece in _repr_pieces(value, set(), 0):
        out.append(piece)
        length += len(piece)
        if length > limit:
            break
    text = "".join(out)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _repr_pieces(value: Any, open_: set[int], depth: int):
    """The text of ``repr(value)`` in pieces, lazily (for :func:`short_repr`)."""
    if isinstance(value, (list, tuple, dict)):
        if id(value) in open_ or depth > 20:
            yield "[...]" if isinstance(value, list) else "{...}" if isinstance(value, dict) else "(...)"
            return
        open_.add(id(value))
        left, right = {list: "[]", tuple: "()", dict: "{}"}.get(type(value), "[]")
        yield left
        items = value.items() if isinstance(value, dict) else value
        for n, item in enumerate(items):
            if n:
                yield ", "
            if isinstance(value, dict):
                yield from _repr_pieces(item[0], open_, depth + 1)
                yield ": "
                yield from _repr_pieces(item[1], open_, depth + 1)
            else:
                yield from _repr_pieces(item, open_, depth + 1)
        yield right
        open_.discard(id(value))
    elif isinstance(value, str):  # a longer string is cut (its closing quote dropped)
        yield repr(value) if len(value) <= SHOWN_CHARS * 4 else repr(value[:SHOWN_CHARS * 4])[:-1]
    elif isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 10_000:
        # repr() refuses an integer beyond 4300 digits, and is slow long before
        yield f"{'-' if value < 0 else ''}<an integer of {int(value.bit_length() * math.log10(2)) + 1:,} digits>"
    else:
        yield repr(value)[:SHOWN_CHARS * 4]


def cut(text: str, limit: int = SHOWN_CHARS) -> str:
    """``text`` cut to ``limit`` characters (ending in ``...``), for a message."""
    return text if len(text) <= limit else text[:limit - 3] + "..."


def closest(word: str, candidates) -> str | None:
    """The candidate most similar to ``word``, ignoring case (``rk4`` finds ``RK4``), or None."""
    by_lower = {str(c).lower(): str(c) for c in candidates}
    match = difflib.get_close_matches(str(word).lower(), list(by_lower), n=1)
    return by_lower[match[0]] if match else None


def finite_number(value: Any) -> bool:
    """A YAML number (not a boolean) that is finite as a float: not .nan, .inf, nor an
    integer beyond the float range (10**400)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def check_value(path: str, value: Any, spec: Field, problems: list[str]) -> Any:
    """Validate one value against ``spec``; append problems; return the normalized value."""
    if value is None:
        if spec.nullable:
            return None
        problems.append(f"{path}: got null; expected {spec.expected()}")
        return None
    ok = True
    shown = None  # a value written with a unit, as given and converted (for messages)
    if spec.type in ("number", "any") and (is_quantity(value) or (spec.type == "any" and isinstance(value, list))):
        converted = _with_units(path, value, spec.unit, problems)
        if converted is None:
            return None
        if converted is not value:
            shown = f"{describe(value)} = {short_repr(converted)} {spec.unit}"
        value = converted
    if spec.type == "number":
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok:
            try:
                number = float(value)
            except OverflowError:  # an integer beyond the float range
                number = math.inf
            if not math.isfinite(number):
                problems.append(f"{path}: got {shown or describe(value)}; expected {spec.expected()} "
                                f"(.inf, .nan and numbers beyond the float range are not allowed)")
                return None
            value = number
    elif spec.type == "integer":
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif spec.type == "string":
        ok = isinstance(value, str)
    elif spec.type == "boolean":
        ok = isinstance(value, bool)
    elif spec.type == "mapping":
        ok = isinstance(value, dict)
    elif spec.type == "list":
        ok = isinstance(value, list)
    if not ok:
        problems.append(f"{path}: got {describe(value)}; expected {spec.expected()}")
        return None
    out_of_bounds = (spec.gt is not None and not value > spec.gt) or (spec.ge is not None and not value >= spec.ge) \
        or (spec.le is not None and not value <= spec.le)
    if spec.type in ("number", "integer") and out_of_bounds:
        problems.append(f"{path}: got {shown or describe(value)}; expected {spec.expected()}")
        return None
    choices = spec.valid_choices()
    if choices is not None and value not in choices:
        hint = closest(str(value), choices)
        extra = f" (did you mean {hint!r}?)" if hint else ""
        problems.append(f"{path}: got {describe(value)}; expected one of {', '.join(map(str, choices))}{extra}")
        return None
    if spec.check is not None:
        expectation = spec.check(value)
        if expectation:
            problems.append(f"{path}: got {shown or describe(value)}; expected {expectation}")
            return None
    return value


def _with_units(path: str, value: Any, unit: str, problems: list[str]) -> Any:
    """``value`` with a number written with a unit (``10 ms``), or each such entry of a list
    (a gain per constraint), converted to ``unit`` (:func:`csim.quantities.convert`); the
    value itself when nothing has a unit; None when a conversion fails (appended to ``problems``)."""
    if isinstance(value, list):
        if not any(is_quantity(v) for v in value):
            return value
        before = len(problems)
        entries = [_with_units(f"{path}[{n}]", v, unit, problems) if is_quantity(v) else v
                   for n, v in enumerate(value)]
        return None if len(problems) > before else entries
    number, problem = convert(value, unit)
    if problem is not None:
        problems.append(f"{path}: got {describe(value)}; {problem}")
    return number


@dataclass
class Section:
    """A mapping of named fields and subsections."""

    fields: dict[str, Field | Section]
    doc: str = ""


def unknown_key(path: str, key: str, valid: list[str]) -> str:
    """Message for a key that the schema does not know, with the closest valid key."""
    where = f"{path}.{key}" if path else key
    hint = closest(key, valid)
    extra = f" (did you mean {hint!r}?)" if hint else ""
    return f"{where}: unknown key{extra}; valid keys here: {', '.join(valid) or '(none)'}"


def validate_section(path: str, data: Any, section: Section, problems: list[str]) -> dict:
    """Validate a mapping against ``section``; returns it with defaults filled in."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        problems.append(f"{path or 'case file'}: got {describe(data)}; expected a mapping (key: value lines)")
        data = {}  # reported; go on with the defaults, so that later checks find every key
    out = {}
    for key in data:
        if key not in section.fields:
            problems.append(unknown_key(path, str(key), list(section.fields)))
    for key, spec in section.fields.items():
        sub = f"{path}.{key}" if path else key
        if isinstance(spec, Section):
            out[key] = validate_section(sub, data.get(key), spec, problems)
        elif key in data:
            out[key] = check_value(sub, data[key], spec, problems)
        elif spec.default is REQUIRED:
            problems.append(f"{sub}: missing; expected {spec.expected()}")
        else:
            out[key] = spec.default
    return out


#: field type -> the Python type of its validated value (a typed section's annotations)
PY_TYPES = {"number": float, "integer": int, "string": str, "boolean": bool, "mapping": dict, "list": list,
            "any": Any}


@functools.cache
def _section_class(name: str, fields: tuple[tuple[str, str, bool, str], ...]) -> type:
    """A frozen dataclass named ``name`` with one attribute per (key, type, nullable, doc)."""
    annotations = [(key, PY_TYPES[kind] | None if nullable else PY_TYPES[kind], dataclass_field(metadata={"doc": doc}))
                   for key, kind, nullable, doc in fields]
    cls = make_dataclass(name, annotations, frozen=True)
    cls.__doc__ = f"The validated ``{name.lower()}`` section of a case (attributes typed from the case schema)."
    return cls


def typed_section(name: str, section: Section, data: dict) -> Any:
    """``data``, a validated section of ``section``, as a frozen dataclass with one typed
    attribute per leaf key (``case.simulation.t_end`` instead of ``data["simulation"]["t_end"]``)."""
    leaves = tuple((key, spec.type, spec.nullable, spec.doc) for key, spec in section.fields.items()
                   if isinstance(spec, Field))
    return _section_class(name.capitalize(), leaves)(**{key: data[key] for key, *_ in leaves})


def field_paths(section: Section, prefix: str = "") -> dict[str, Field]:
    """Every leaf of ``section`` by dotted path."""
    paths = {}
    for key, spec in section.fields.items():
        path = f"{prefix}.{key}" if prefix else key
        if isinstance(spec, Section):
            paths.update(field_paths(spec, path))
        else:
            paths[path] = spec
    return paths


#: field type -> JSON Schema type
JSON_TYPES = {"number": "number", "integer": "integer", "string": "string", "boolean": "boolean",
              "mapping": "object", "list": "array"}


def described(doc: str, unit: str = "") -> str:
    """A JSON Schema description: the documentation line, then the unit in brackets."""
    return f"{doc} [{unit}]" if unit and unit != "-" else doc


def field_json_schema(spec: Field) -> dict:
    """The JSON Schema (draft-07) of one field: type, bounds, choices, default, description.

    Non-finite numbers, which :func:`check_value` rejects, cannot be told apart in JSON
    Schema; everything else a field declares can, but the bounds of a number written with
    its unit (``10 ms``: a string matching :data:`csim.quantities.JSON_PATTERN`).
    """
    out: dict[str, Any] = {}
    if spec.type in JSON_TYPES:
        out["type"] = JSON_TYPES[spec.type]
    for key, bound in (("exclusiveMinimum", spec.gt), ("minimum", spec.ge), ("maximum", spec.le)):
        if bound is not None:
            out[key] = bound
    choices = spec.valid_choices()
    if choices is not None:
        out["enum"] = list(choices)
    out.update(spec.json or {})
    if spec.type in ("number", "any") and convertible(spec.unit):  # or written with its unit: 10 ms
        out = {"anyOf": [*(out["anyOf"] if list(out) == ["anyOf"] else [out]), JSON_QUANTITY]}
    if spec.nullable and list(out) == ["anyOf"]:
        out = {"anyOf": [*out["anyOf"], {"type": "null"}]}
    elif spec.nullable:
        if "type" in out and "enum" not in out:
            out["type"] = [out["type"], "null"]
        else:
            out = {"anyOf": [out, {"type": "null"}]}
    if spec.doc or spec.unit:
        out["description"] = described(spec.doc, spec.unit)
    if spec.default is not REQUIRED and (spec.default is not None or spec.nullable):
        out["default"] = spec.default
    return out


def section_json_schema(section: Section) -> dict:
    """The JSON Schema of a section: an object (or null, read as empty) of its fields, no other keys."""
    out: dict[str, Any] = {"type": ["object", "null"]}
    if section.doc:
        out["description"] = section.doc
    out["properties"] = {key: section_json_schema(spec) if isinstance(spec, Section) else field_json_schema(spec)
                         for key, spec in section.fields.items()}
    required = [key for key, spec in section.fields.items() if isinstance(spec, Field) and spec.default is REQUIRED]
    if required:
        out["required"] = required
    out["additionalProperties"] = False
    return out
