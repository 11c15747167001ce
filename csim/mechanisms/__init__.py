"""Registry of the mechanisms csim knows by name (``mechanism.name`` in a case file)."""
from __future__ import annotations

from collections.abc import Callable

from csim.mechanisms import pendulum, quick_return
from csim.model.definition import MechanismDefinition

#: name -> function returning a fresh MechanismDefinition
MECHANISMS: dict[str, Callable[[], MechanismDefinition]] = {
    "quick_return": quick_return.definition,
    "pendulum": pendulum.definition,
}


def get_mechanism(name: str) -> MechanismDefinition:
    """The definition of the mechanism registered as ``name``.

    Raises
    ------
    KeyError
        With a message listing the valid names.
    """
    try:
        factory = MECHANISMS[name]
    except KeyError:
        raise KeyError(f"unknown mechanism {name!r}; valid names: {', '.join(sorted(MECHANISMS))}") from None
    return factory()
