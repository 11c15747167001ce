"""What a comparison is asked for: method specs and tolerance values, checked, and as text.

Pure functions of names and numbers, with no case: the registries
(:data:`csim.solver.stabilizers.STABILIZERS`, :data:`csim.solver.integrators.INTEGRATORS`)
say which names exist and whether an integrator is adaptive. A method spec is ``METHOD`` or
``METHOD:INTEGRATOR``; a tolerance value is rtol = atol of an adaptive integrator, or the
step [s] of a fixed-step one. :mod:`csim.compare.plan` turns them into validated cases.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from csim.errors import CaseError
from csim.io.hdf5 import COMPARISON_RESERVED
from csim.solver.integrators import INTEGRATORS
from csim.solver.stabilizers import STABILIZERS

NAN = float("nan")

#: tolerance kind -> how text names it
TOLERANCE_LABELS = {"rtol=atol": "rtol = atol", "rtol": "rtol", "step": "step"}

#: what a bad tolerance (or step) value gets told
_POSITIVE_NUMBERS = "expected positive numbers separated by commas, e.g. 1e-4,1e-6"


# --------------------------------------------------------------------------- methods


def split_method(spec: str) -> tuple[str, str | None]:
    """``"ggl:Radau"`` -> ``("ggl", "Radau")``; ``"none"`` -> ``("none", None)``.

    A method may name its own integrator, for methods that the case's integrator cannot
    run (GGL, an index-2 DAE, needs Radau) or to compare integrators side by side.
    """
    name, _, integrator = spec.partition(":")
    return name.strip(), integrator.strip() or None


def check_methods(methods: Sequence[str], option: str = "methods") -> list[str]:
    """Validate method specs against the registries.

    Parameters
    ----------
    methods : sequence of str
        Specs ``METHOD`` or ``METHOD:INTEGRATOR``.
    option : str
        How messages name the option (``"--methods"`` on the command line).

    Returns
    -------
    list of str
        The specs, stripped of surrounding white space, in the order given.

    Raises
    ------
    CaseError
        For an empty list, a duplicate, an unknown name (listing the valid ones), or a name
        reserved for the comparison file's own groups; every problem at once.
    """
    names = [str(m).strip() for m in methods]
    problems = []
    if not names or any(not n for n in names):
        problems.append(f"{option}: got {','.join(names)!r}; expected method names separated by commas, "
                        f"e.g. {','.join(list(STABILIZERS)[:2])}")
    seen = set()
    for spec in filter(None, names):
        if spec in seen:
            problems.append(f"{option}: method {spec!r} given twice")
        seen.add(spec)
        problems += _spec_problems(spec, option)
    if problems:
        raise CaseError(list(dict.fromkeys(problems)))
    return names


def _spec_problems(spec: str, option: str) -> list[str]:
    """What is wrong with one (non-empty) method spec: its method's name, its integrator's."""
    problems = []
    name, integrator = split_method(spec)
    if name not in STABILIZERS:
        problems.append(f"{option}: unknown method {name!r}; valid names: {', '.join(STABILIZERS)} "
                        f"(each optionally as METHOD:INTEGRATOR)")
    elif name in COMPARISON_RESERVED:
        problems.append(f"{option}: method {name!r} has the name of a group of the comparison file")
    if integrator is not None and integrator not in INTEGRATORS:
        problems.append(f"{option}: unknown integrator {integrator!r} in {spec!r}; valid names: "
                        f"{', '.join(INTEGRATORS)}")
    return problems


def parse_methods(text: str, option: str = "--methods") -> list[str]:
    """``"none,baumgarte"`` -> ``["none", "baumgarte"]``, checked by :func:`check_methods`."""
    return check_methods([] if not text.strip() else text.split(","), option)


def default_methods(integrator: str) -> list[str]:
    """Every registered method; one that ``integrator`` cannot run gets its own, as ``METHOD:INTEGRATOR``."""
    return [name if cls.integrators is None or integrator in cls.integrators else f"{name}:{cls.integrators[0]}"
            for name, cls in STABILIZERS.items()]


def method_sets(spec: str) -> list[str]:
    """``--set`` overrides that select the method (and its integrator) of ``spec``."""
    name, integrator = split_method(spec)
    return [f"stabilization.method={name}", *([f"simulation.integrator={integrator}"] if integrator else [])]


# --------------------------------------------------------------------------- tolerances


def check_tolerances(values: Sequence[float], option: str = "tolerances") -> list[float]:
    """Validate tolerances (or steps [s]): positive finite numbers, none given twice.

    Returns
    -------
    list of float
        The values, loosest (largest) first.

    Raises
    ------
    CaseError
        Naming each bad value, or for an empty list.
    """
    problems, out = [], []
    if not len(values):
        problems.append(f"{option}: expected at least one value, e.g. 1e-4,1e-6,1e-8")
    for v in values:
        ok = isinstance(v, (int, float, np.floating)) and not isinstance(v, bool) and math.isfinite(v) and v > 0
        if not ok:
            problems.append(f"{option}: got {v!r}; {_POSITIVE_NUMBERS}")
        elif float(v) in out:
            problems.append(f"{option}: {float(v):g} given twice")
        else:
            out.append(float(v))
    if problems:
        raise CaseError(problems)
    return sorted(out, reverse=True)


def parse_tolerances(text: str, option: str = "--tolerances") -> list[float]:
    """``"1e-4,1e-6"`` -> ``[1e-4, 1e-6]`` (loosest first), naming any bad value as given."""
    problems, values = [], []
    for item in text.split(","):
        item = item.strip()
        try:
            value = float(item)
        except ValueError:
            value = NAN
        if not (math.isfinite(value) and value > 0):
            problems.append(f"{option}: got {item!r}; {_POSITIVE_NUMBERS}")
            continue
        values.append(value)
    if problems:
        raise CaseError(problems)
    return check_tolerances(values, option)


def tolerance_kind(integrator: str) -> str:
    """What a study's tolerance sets for ``integrator``: ``"rtol=atol"`` or ``"step"`` [s]."""
    return "rtol=atol" if INTEGRATORS[integrator].adaptive else "step"


def tolerance_label(integrator: str) -> str:
    """How text names what a tolerance sets for ``integrator``: ``"rtol = atol"`` or ``"step"``."""
    return TOLERANCE_LABELS[tolerance_kind(integrator)]


def tolerance_sets(integrator: str, value: float) -> list[str]:
    """``--set`` overrides that give a run of ``integrator`` the tolerance (or step [s]) ``value``."""
    if INTEGRATORS[integrator].adaptive:
        return [f"simulation.rtol={value!r}", f"simulation.atol={value!r}"]
    return [f"simulation.step={value!r}"]


def tol_text(value: float) -> str:
    """A tolerance or step as short text: ``1e-06``, or ``2.5e-07`` where one digit is not enough."""
    short = f"{value:.0e}"
    return short if float(short) == value else f"{value:.6g}"
