"""Registry of the mechanisms csim knows by name (``mechanism.name`` in a case file).

Each mechanism is a module with a ``definition()`` function that builds it symbolically.
The modules are imported on first use: a warm run reads a mechanism's plain data from its
snapshot (:func:`light_mechanism`) and never imports sympy.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable

from csim.model.definition import MechanismDefinition
from csim.model.light import LightDefinition, light_definition

#: name -> module whose ``definition()`` builds the mechanism
MODULES: dict[str, str] = {
    "quick_return": "csim.mechanisms.quick_return",
    "pendulum": "csim.mechanisms.pendulum",
    "andrews": "csim.mechanisms.andrews",
}


def _factory(name: str) -> Callable[[], MechanismDefinition]:
    return lambda: importlib.import_module(MODULES[name]).definition()


#: name -> function returning a fresh MechanismDefinition
MECHANISMS: dict[str, Callable[[], MechanismDefinition]] = {name: _factory(name) for name in MODULES}


def _check(name: str) -> None:
    if name not in MODULES:
        raise KeyError(f"unknown mechanism {name!r}; valid names: {', '.join(sorted(MODULES))}")


def get_mechanism(name: str) -> MechanismDefinition:
    """The (symbolic) definition of the mechanism registered as ``name``.

    Raises
    ------
    KeyError
        With a message listing the valid names.
    """
    _check(name)
    return MECHANISMS[name]()


def light_mechanism(name: str) -> LightDefinition:
    """The mechanism ``name`` as plain data from its snapshot; symbolic parts on demand."""
    _check(name)
    return light_definition(name, MODULES[name], MECHANISMS[name])
