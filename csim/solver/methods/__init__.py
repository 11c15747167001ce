"""Stabilization methods, one file each, registered by name.

Every module of this package (but :mod:`~csim.solver.methods.base`) is imported and each
:class:`~csim.solver.methods.base.Method` subclass it defines is registered under its
``name``, in ``rank`` order. A method defined elsewhere (a plug-in, a test) joins with
:func:`register`. The case schema's ``stabilization`` section (:func:`schema_fields`) and
the table of settings in docs/how-it-works.md (:func:`settings_table`) are generated from the methods'
``Options``.
"""
from __future__ import annotations

import dataclasses
import importlib
import pkgutil

from csim.schema import Field
from csim.solver.methods.base import Method, positive_gains

#: name -> method class, in rank order
STABILIZERS: dict[str, type[Method]] = {}


def register(cls: type[Method]) -> type[Method]:
    """Add a method class to the registry (its ``name`` must be new); returns it (a decorator)."""
    if cls.name in STABILIZERS and STABILIZERS[cls.name] is not cls:
        raise ValueError(f"a stabilization method named {cls.name!r} is registered already")
    items = [*((n, c) for n, c in STABILIZERS.items() if n != cls.name), (cls.name, cls)]
    STABILIZERS.clear()
    STABILIZERS.update(sorted(items, key=lambda item: item[1].rank))  # sorted() keeps equal ranks in order
    return cls


def _discover() -> None:
    for info in pkgutil.iter_modules(__path__):
        if info.name == "base":
            continue
        module = importlib.import_module(f"{__name__}.{info.name}")
        for value in vars(module).values():
            if isinstance(value, type) and issubclass(value, Method) and value is not Method \
                    and value.__module__ == module.__name__:
                register(value)


_discover()


def make_stabilizer(name: str, settings: dict | None = None) -> Method:
    """Build the method registered as ``name`` from its case-file ``settings``.

    ``settings`` may hold the settings of every method; each method takes only its own.
    """
    try:
        cls = STABILIZERS[name]
    except KeyError:
        raise KeyError(f"unknown stabilization method {name!r}; valid names: {', '.join(STABILIZERS)}") from None
    own = {f.name for f in cls.option_fields()}
    return cls(**{k: v for k, v in (settings or {}).items() if k in own})


def stabilizer_from(section) -> Method:
    """The method a case's typed ``stabilization`` section names (:attr:`csim.case.Case.stabilization`),
    built from its own settings only (the section's attributes of the same names)."""
    cls = STABILIZERS.get(section.method)
    if cls is None:
        raise KeyError(f"unknown stabilization method {section.method!r}; valid names: {', '.join(STABILIZERS)}")
    return cls(**{f.name: getattr(section, f.name) for f in cls.option_fields()})


_TYPES = {float: "number", int: "integer", str: "string", bool: "boolean"}

#: what :func:`~csim.solver.methods.base.positive_gains` accepts, as JSON Schema
GAIN_JSON = {"anyOf": [{"type": "number", "exclusiveMinimum": 0},
                       {"type": "array", "items": {"type": "number", "exclusiveMinimum": 0}, "minItems": 1}]}


def option_field(method: type[Method], f: dataclasses.Field) -> Field:
    """The case-schema field of one method setting (``stabilization.<name>``)."""
    meta = f.metadata
    doc = f"{method.name}: {meta['doc']}"
    if meta["gain"]:
        return Field("any", f.default, doc, meta["unit"], check=positive_gains, json=GAIN_JSON)
    return Field(_TYPES[type(f.default)], f.default, doc, meta["unit"], choices=meta["choices"], gt=meta["gt"],
                 ge=meta["ge"], le=meta["le"])


def schema_fields() -> dict[str, Field]:
    """Every method's settings as case-schema fields, by key (a key shared by two methods must agree)."""
    fields: dict[str, Field] = {}
    for cls in STABILIZERS.values():
        for f in cls.option_fields():
            spec = option_field(cls, f)
            if f.name in fields and fields[f.name].default != spec.default:
                raise ValueError(f"stabilization.{f.name} is declared by two methods with different defaults")
            fields.setdefault(f.name, spec)
    return fields


def settings_table() -> str:
    """The table of ``stabilization`` settings in docs/how-it-works.md (Markdown), generated from the methods."""
    rows = ["| key | method | default | unit | meaning |", "|---|---|---|---|---|"]
    for cls in STABILIZERS.values():
        for f in cls.option_fields():
            meta = f.metadata
            kind = "gain: a number or one per constraint" if meta["gain"] else ""
            choices = f"one of {', '.join(meta['choices'])}" if meta["choices"] else ""
            extra = "; ".join(x for x in (kind, choices) if x)
            default = f"{f.default:g}" if isinstance(f.default, float) else f"{f.default}"
            doc = f"{meta['doc']}{f' ({extra})' if extra else ''}".replace("|", "\\|")
            rows.append(f"| `stabilization.{f.name}` | `{cls.name}` | `{default}` | {meta['unit'] or '-'} | {doc} |")
    return "\n".join(rows)


__all__ = ["STABILIZERS", "Method", "make_stabilizer", "register", "schema_fields", "settings_table", "stabilizer_from"]
