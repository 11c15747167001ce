"""The link-coupling tables as JSON Schema, for editors (``csim schema``).

The shapes :mod:`csim.linkage.tables` and :mod:`csim.linkage.inertia` read, with the
registered joint types (:data:`csim.linkage.joints.JOINT_TYPES`) and the row keys
(:data:`csim.linkage.tables.LINK_KEYS`). Expressions of the parameters are strings; what
they must evaluate to (finite, real, physical mass properties) is checked by csim only.
"""
from __future__ import annotations

from csim.linkage.joints import JOINT_TYPES
from csim.linkage.tables import LINK_KEYS
from csim.quantities import JSON_QUANTITY

#: a number, an expression of the parameters (``l1/2``, ``90*deg``) or a number with a unit (``50 mm``)
EXPRESSION = {"type": ["number", "string"]}


def _vector(length: int | tuple[int, int], doc: str) -> dict:
    low, high = (length, length) if isinstance(length, int) else length
    return {"type": "array", "items": EXPRESSION, "minItems": low, "maxItems": high, "description": doc}


def joint_frame() -> dict:
    """One joint frame: a type letter, ``[TYPE, p]``, ``[TYPE, p, POINT]`` or ``{type, p, point}``."""
    kind = {"enum": list(JOINT_TYPES), "description": "joint type"}
    p = {"anyOf": [{"const": 0}, _vector((3, 6), "[x, y, z] [m], then the z-x'-z'' Euler angles [rad]")],
         "description": "origin in the link frame [m] and Euler angles [rad]; 0: at the link frame"}
    point = {"type": "string", "description": "name of the joint's point"}
    return {"anyOf": [
        kind,
        {"type": "array", "items": [kind, p, point], "additionalItems": False, "minItems": 1},
        {"type": "object", "properties": {"type": kind, "p": p, "point": point}, "required": ["type"],
         "additionalProperties": False},
    ]}


def link_row() -> dict:
    """One row of ``mechanism.links``."""
    properties = {
        "link": {"type": "integer", "minimum": 0, "description": "link number (0: the fixed link)"},
        "name": {"type": "string", "description": "link name, usable in the couplings table"},
        "joints": {"type": "array", "items": joint_frame(), "minItems": 1,
                   "description": "joint frames k = 1, 2, ... of the link"},
        "mass": {**EXPRESSION, "description": "mass [kg]"},
        "com": _vector(3, "centre of mass in the link frame [m]"),
        "inertia": {"anyOf": [EXPRESSION, _vector(3, "[Ixx, Iyy, Izz]"),
                              {"type": "array", "items": _vector(3, "row"), "minItems": 3, "maxItems": 3}],
                    "description": "inertia about the centre of mass, link axes [kg m^2]: a number, "
                                   "[Ixx, Iyy, Izz] or a symmetric 3x3 list"},
    }
    return {"type": "object", "properties": {key: properties[key] for key in LINK_KEYS}, "required": ["joints"],
            "additionalProperties": False}


def coupling_row() -> dict:
    """One row of ``mechanism.couplings``: ``[i, k, j, m]`` or ``{name, couple: [i, k, j, m]}``;
    a joint shared by three or more links is ``{name, couple: [[i, k], [j, m], [l, n], ...]}``."""
    end = {"type": ["integer", "string"]}
    couple = {"type": "array", "items": end, "minItems": 4, "maxItems": 4,
              "description": "[i, k, j, m]: joint k of link i with joint m of link j (numbers or names)"}
    shared = {"type": "array", "minItems": 2,
              "items": {"type": "array", "items": end, "minItems": 2, "maxItems": 2},
              "description": "[[i, k], [j, m], [l, n], ...]: one pin shared by three or more links"}
    return {"anyOf": [couple, {"type": "object", "properties": {
        "name": {"type": "string", "description": "joint name (names its joint variables)"},
        "couple": {"anyOf": [couple, shared]}},
        "required": ["couple"], "additionalProperties": False}]}


def tables_json_schema() -> dict:
    """``properties`` of the ``mechanism`` section for the link-coupling keys."""
    return {
        "parameters": {"additionalProperties": {"anyOf": [{"type": "number"}, JSON_QUANTITY],
                                                "description": "a parameter: a number in SI units, or a number "
                                                               "with a unit (50 mm), converted to SI base units"}},
        "links": {"items": link_row(), "minItems": 1},
        "couplings": {"items": coupling_row(), "minItems": 1},
        "gravity": {"items": EXPRESSION, "minItems": 3, "maxItems": 3},
        "drive": {"additionalProperties": {"anyOf": [EXPRESSION, {"type": "array", "items": {
            "type": ["number", "string", "null"]}}]}},
    }
