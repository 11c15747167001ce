"""Units of everything csim records: the one place they are documented.

csim works in SI units throughout. Coordinates are angles [rad] or lengths [m], as each
mechanism declares; the units of velocity-like and acceleration-like arrays follow from
those per column.

Every dataset of a result, comparison or sweep file carries two attributes:

``units``
    A unit that software can parse, spelled as UDUNITS and pint both read it (``s``,
    ``rad/s^2``, ``N m``, ``J/m^2``; ``1`` for a dimensionless number, a count or a text
    label). Where the columns of an array (or the terms of a maximum over columns) have
    different units, as the coordinates of a mechanism with both revolute and prismatic
    joints do, ``units`` is the list of them, one per column, each parsable. An empty
    string (:data:`UNKNOWN`), as the whole attribute or as one entry of the list, says that
    csim could not determine that unit: it is never written as ``1``, which would claim a
    dimensionless quantity.
``description``
    What the dataset holds, in words (:data:`UNITS`).

:func:`mechanism_units` finds the unit of each coordinate, constraint, load and
observable of a run; :func:`constraint_units` finds a constraint function's unit by
dimensional analysis.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

#: the ``units`` of a dimensionless number, a count or a label
DIMENSIONLESS = "1"

#: the ``units`` of a quantity whose unit csim could not determine (not ``1``: that would
#: claim it dimensionless)
UNKNOWN = ""

#: dataset path in a result file -> what it holds and in which unit (the ``description``
#: attribute; ``per coordinate`` means: see the dataset's ``units``, one entry per column
#: where the columns differ), for the datasets that are not per-sample output quantities
#: (those are records of :data:`csim.io.outputs.OUTPUTS`)
UNITS: dict[str, str] = {
    "t": "s: output time",
    "coordinate": "names of the generalized coordinates (dimension scale of q, qd, qdd)",
    "constraint": "number of each constraint, from 1 (dimension scale of lambda, phi, phi_dot)",
    "load": "names of the loads (dimension scale of forces/loads, energy/work)",
    "drive": "names of the driven joint variables (dimension scale of forces/drive, energy/drive_work)",
    "axis": "x, y, z (dimension scale of the joint reactions)",
    "forces/drive": "per drive: N m for a rotation, N for a translation; the torque or force the drive "
                    "applies along its joint variable (driven dynamics)",
    "energy/drive_work": "work of each drive since t = 0 [J]",
    "observables": "a quantity the mechanism declares",
    "observables_rate": "the rate of a quantity the mechanism declares",
    "reactions": "the force and the moment that link i exerts on link j of the joint (i, k)-(j, m), at the "
                 "origin of joint frame jm; link i receives the opposite",
    "reactions/force_global": "N, in the fixed frame's axes",
    "reactions/force_joint": "N, in the axes of joint frame ik",
    "reactions/torque_global": "N m, about the origin of joint frame jm, in the fixed frame's axes",
    "reactions/torque_joint": "N m, about the origin of joint frame jm, in the axes of joint frame ik",
    "events/times": "s: switching instants (dimension scale of events/labels)",
    "events/labels": "what switched at each event",
    "wall_time": "s",
}

#: dataset path -> its parsable unit, for the datasets whose unit does not depend on the mechanism
FIXED_UNITS: dict[str, str] = {
    "t": "s",
    "coordinate": DIMENSIONLESS,
    "constraint": DIMENSIONLESS,
    "load": DIMENSIONLESS,
    "drive": DIMENSIONLESS,
    "axis": DIMENSIONLESS,
    "energy/drive_work": "J",
    "reactions/force_global": "N",
    "reactions/force_joint": "N",
    "reactions/torque_global": "N m",
    "reactions/torque_joint": "N m",
    "events/times": "s",
    "events/labels": DIMENSIONLESS,
    "wall_time": "s",
}

#: the unit of a load's or drive's value, by the unit of the coordinate it acts along
FORCE_UNIT = {"rad": "N m", "m": "N"}


def per_time(unit: str, power: int = 1) -> str:
    """``unit`` divided by s^power, spelled as UDUNITS and pint read it (``rad/s^2``, ``1/s``);
    :data:`UNKNOWN` for an unknown ``unit``."""
    if unit == UNKNOWN:
        return UNKNOWN
    return f"{unit}/s" if power == 1 else f"{unit}/s^{power}"


def multiplier_unit(constraint_unit: str) -> str:
    """Unit of a Lagrange multiplier whose constraint has the unit ``constraint_unit``.

    Phi_q^T lambda is a generalized force, so lambda_i Phi_i has the unit of work (J): a
    force (N) for a position equation in m, a moment (N m) for a dimensionless orientation
    equation; :data:`UNKNOWN` for a constraint of unknown unit.
    """
    if constraint_unit == UNKNOWN:
        return UNKNOWN
    return {"m": "N", DIMENSIONLESS: "N m"}.get(constraint_unit, f"J/{constraint_unit}")


def common_unit(units: Sequence[str]) -> str | list[str]:
    """The ``units`` attribute of an array whose columns have ``units``: their unit when they
    share one (``1`` for an array without columns), else the list of them. An unknown unit
    (:data:`UNKNOWN`) stays unknown, never ``1``."""
    units = list(units)
    if not units:
        return DIMENSIONLESS
    return units[0] if len(set(units)) == 1 else units


def constraint_units(phi: Callable, q: np.ndarray, par: np.ndarray, length_q: np.ndarray,
                     length_par: np.ndarray, unknown_par: np.ndarray | None = None) -> list[str]:
    """Unit of each constraint function, found by dimensional analysis.

    Lengths (the parameters and coordinates in m) are doubled at a few generic
    configurations: a constraint that doubles is in m, one that does not change is
    dimensionless (``1``), one that grows by 2^k is in m^k. A constraint that scales
    otherwise, is zero at every configuration tried, or changes with a parameter of
    unknown unit (``unknown_par``: the doubling cannot know whether to double it) gets
    :data:`UNKNOWN` (``""``).

    Parameters
    ----------
    phi : callable
        ``phi(q, par)`` -> (r,), the constraint functions.
    q : ndarray (m,)
        A configuration to start from (the values tried are generic ones near it).
    par : ndarray (n_par,)
    length_q, length_par : ndarray of bool
        Which coordinates and which parameters are lengths [m].
    unknown_par : ndarray of bool, optional
        Which parameters have no declared unit (None: none).

    Returns
    -------
    list of str, length r
    """
    q = np.asarray(q, dtype=float)
    length_q, length_par = np.asarray(length_q, bool), np.asarray(length_par, bool)
    unknown = np.zeros(length_par.shape, bool) if unknown_par is None else np.asarray(unknown_par, bool)
    units: list[str | None] = []
    for trial in range(5):
        qt = 0.37 + 0.29 * np.arange(q.size) + 0.11 * trial
        try:
            base = np.asarray(phi(qt, par), dtype=float)
            scaled = np.asarray(phi(np.where(length_q, 2 * qt, qt), np.where(length_par, 2 * par, par)), dtype=float)
            # the parameters of unknown unit moved: a constraint that changes depends on them
            moved = np.asarray(phi(qt, np.where(unknown, 1.7 * par + 0.3, par)), dtype=float) if unknown.any() \
                else base
        except (ValueError, ZeroDivisionError, OverflowError, TypeError, FloatingPointError, np.linalg.LinAlgError):
            continue
        if not units:
            units = [None] * base.size
        for i in range(base.size):
            if units[i] is not None or not (math.isfinite(base[i]) and math.isfinite(scaled[i])) \
                    or abs(base[i]) < 1e-9:
                continue
            if not math.isfinite(moved[i]) or abs(moved[i] - base[i]) > 1e-9 * max(1.0, abs(base[i])):
                units[i] = UNKNOWN
                continue
            ratio = scaled[i] / base[i]
            k = math.log2(ratio) if ratio > 0 else float("nan")
            if math.isfinite(k) and abs(k - round(k)) < 1e-9:
                k = round(k)
                units[i] = DIMENSIONLESS if k == 0 else "m" if k == 1 else f"m^{k}"
        if units and all(u is not None for u in units):
            break
    return [u or UNKNOWN for u in units]


def declared_constraint_units(mechanism) -> list[str] | None:
    """The unit of each constraint row as the mechanism itself says it, or None where it
    says nothing (a registered mechanism: its units come from dimensional analysis).

    A link-coupling mechanism says it: its definition's ``recursive`` hook
    (:class:`csim.linkage.model.LinkageTerms`) keeps its kept cut-joint equations, each a
    position equation (``m``) or an orientation equation (``1``). (Its parameters carry no
    unit, so dimensional analysis could not tell its lengths.) A light definition is not
    made to build its symbolic one to answer: it keeps them as ``constraint_units`` (None: a
    registered mechanism's, which declares none).
    """
    own = getattr(mechanism, "__dict__", {})
    units = own["constraint_units"] if "constraint_units" in own else \
        getattr(own.get("recursive"), "constraint_units", None)
    return None if units is None else [str(u) for u in units]


def mechanism_units(mechanism, model=None, par: np.ndarray | None = None) -> dict[str, list[str]]:
    """The units of a run's columns, as :class:`csim.result.Result` fields.

    Parameters
    ----------
    mechanism : MechanismDefinition or LightDefinition
        The case's mechanism (its coordinates', loads' and observables' units).
    model : NumericModel, optional
        Its numeric model. The constraints' units are the mechanism's own where it says
        them (:func:`declared_constraint_units`: a link-coupling mechanism), else, with
        ``par``, found by dimensional analysis of the model's (:func:`constraint_units`),
        else left empty. A constraint whose unit cannot be determined gets :data:`UNKNOWN`.
    par : ndarray, optional

    Returns
    -------
    dict
        ``coordinate_units``, ``constraint_units``, ``load_units``, ``observable_units``,
        ``observable_rate_units``: one unit per column.
    """
    coords = list(mechanism.coordinate_units)
    c_units: list[str] = []
    declared = declared_constraint_units(mechanism)
    if declared is not None:
        c_units = declared
        if model is not None and model.n_constraints != len(declared):  # rows it does not describe: not guessed
            c_units = [UNKNOWN] * model.n_constraints
    elif model is not None and par is not None:
        length_par = np.array([p.unit == "m" for p in mechanism.parameters], dtype=bool)
        unknown_par = np.array([not p.unit for p in mechanism.parameters], dtype=bool)
        c_units = constraint_units(model.phi, np.zeros(len(coords)), np.asarray(par, float),
                                   np.array([u == "m" for u in coords], dtype=bool), length_par, unknown_par)
    return dict(
        coordinate_units=coords,
        constraint_units=c_units,
        load_units=[ld.unit for ld in mechanism.loads],
        observable_units=[o.unit for o in mechanism.observables],
        observable_rate_units=[o.rate_unit for o in mechanism.observables],
    )


def phi_unit_text(unit: str, constraint_unit: str | list[str]) -> str:
    """A schema unit that names ``unit of Phi`` (``unit of Phi/s^2``, ``s/unit of Phi``)
    with the constraints' unit put in (``""`` where the constraints' units differ)."""
    if "unit of Phi" not in unit:
        return unit
    if not isinstance(constraint_unit, str) or not constraint_unit:
        return ""
    if constraint_unit == DIMENSIONLESS:
        return unit.replace("s/unit of Phi", "s").replace("unit of Phi", DIMENSIONLESS)
    return unit.replace("unit of Phi", constraint_unit)  # m or m^k: no parentheses needed
