"""Mass properties of a link: read from its row, and checked to be a rigid body's.

A row may give ``mass`` [kg], ``com`` [m] (the centre of mass in the link frame) and
``inertia`` [kg m^2] (about the centre of mass, in link axes): a number J (J on every axis),
``[Ixx, Iyy, Izz]`` or a symmetric 3x3 list. The rules, at the parameter values:

- ``mass`` is a number >= 0. Left out or 0, with no inertia: a massless link (allowed).
  A link with a nonzero inertia needs mass > 0.
- ``inertia`` left out or 0: a point mass at ``com`` (allowed). Otherwise it is symmetric
  and has no negative principal moment (checked while reading the tables), and
  (:func:`check_inertia`, once the plane of motion is known):

  - in a spatial mechanism it is positive definite and its principal moments obey the
    triangle inequality I1 + I2 >= I3 (every permutation), as every rigid body's do;
  - in a planar mechanism only the moment about the plane normal enters the dynamics
    (Izz when the link's z axis is normal to the plane): it must be > 0, and the other
    moments may be 0 (``[0, 0, Izz]``).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp

from csim.linkage.expressions import Scope, evaluate
from csim.schema import describe

#: Relative round-off allowed in the comparisons of moments (of the largest moment).
RELATIVE_TOLERANCE = 1e-12


@dataclass(frozen=True)
class MassProperties:
    """Mass, centre of mass and inertia of one link.

    Attributes
    ----------
    mass : sympy expression [kg]
    com : tuple of 3 sympy expressions [m], centre of mass in the link frame
    inertia : sympy Matrix (3, 3) [kg m^2], about the centre of mass, link axes
    """

    mass: sp.Expr
    com: tuple
    inertia: sp.Matrix


def numeric_inertia(inertia: sp.Matrix, values: dict[sp.Symbol, float]) -> np.ndarray:
    """The inertia tensor at the parameter values, (3, 3) [kg m^2]."""
    return np.array([[evaluate(x, values).real for x in row] for row in inertia.tolist()], dtype=float)


def _moments(tensor: np.ndarray) -> tuple[np.ndarray, float]:
    """Principal moments, ascending (3,) [kg m^2], and the round-off allowed in comparing them."""
    moments = np.linalg.eigvalsh(tensor)
    return moments, RELATIVE_TOLERANCE * max(float(np.max(np.abs(moments))), 1e-300)


def _format(moments: np.ndarray) -> str:
    return ", ".join(f"{m:.6g}" for m in moments)


#: the unit of an inertia entry
INERTIA_UNIT = "kg m^2"


def _inertia(path: str, value: Any, scope: Scope, problems: list[str]) -> sp.Matrix | None:
    if value is None:
        return sp.zeros(3, 3)
    if not isinstance(value, list):
        j = scope.parse(path, value, problems, INERTIA_UNIT)
        return None if j is None else j * sp.eye(3)
    if len(value) == 3 and all(not isinstance(v, list) for v in value):
        diag = [scope.parse(f"{path}[{n}]", v, problems, INERTIA_UNIT) for n, v in enumerate(value)]
        return None if any(d is None for d in diag) else sp.diag(*diag)
    if len(value) == 3 and all(isinstance(row, list) and len(row) == 3 for row in value):
        rows = [[scope.parse(f"{path}[{a}][{b}]", v, problems, INERTIA_UNIT) for b, v in enumerate(row)]
                for a, row in enumerate(value)]
        if any(e is None for row in rows for e in row):
            return None
        matrix = sp.Matrix(rows)
        if matrix != matrix.T:
            problems.append(f"{path}: got {describe(value)}; expected a symmetric 3x3 inertia tensor")
            return None
        return matrix
    problems.append(f"{path}: got {describe(value)}; expected a number J (J on every axis), [Ixx, Iyy, Izz] or a "
                    f"symmetric 3x3 list [kg m^2]")
    return None


def _physical(path: str, row: dict, props: MassProperties, values: dict[sp.Symbol, float],
              problems: list[str]) -> bool:
    """The rules that hold in any mechanism: mass >= 0, no negative principal moment, and
    mass > 0 under an inertia. False (and the problems appended) when one is broken."""
    start = len(problems)
    mass = evaluate(props.mass, values).real
    if mass < 0:
        problems.append(f"{path}.mass: got {describe(row.get('mass'))}, {mass:.6g} kg at the parameter values; "
                        f"expected a mass >= 0 [kg] (0 or left out, with no inertia: a massless link)")
    tensor = numeric_inertia(props.inertia, values)
    if not tensor.any():
        return len(problems) == start
    moments, tol = _moments(tensor)
    if moments[0] < -tol:
        problems.append(f"{path}.inertia: got {describe(row.get('inertia'))}, principal moments {_format(moments)} "
                        f"kg m^2 at the parameter values; expected no negative principal moment (the inertia "
                        f"tensor of a body about its centre of mass)")
    elif mass == 0:
        given = f"got {describe(row['mass'])}" if "mass" in row else "left out"
        problems.append(f"{path}.mass: {given} with the inertia "
                        f"{describe(row.get('inertia'))}; expected mass > 0 [kg] for a link with inertia (or no "
                        f"inertia either: a massless link)")
    return len(problems) == start


def parse_mass_properties(path: str, row: dict, scope: Scope, problems: list[str]) -> MassProperties | None:
    """``mass``, ``com`` and ``inertia`` of a link row, read and checked (see the module docstring).

    Parameters
    ----------
    path : str
        Key path of the row, e.g. ``"mechanism.links[1]"``.
    row : dict
        The row.
    scope : Scope
        Parameters and their values.
    problems : list of str
        Appended to, one line per problem.

    Returns
    -------
    MassProperties, or None when a problem was found.
    """
    mass = scope.parse(f"{path}.mass", row.get("mass", 0), problems, "kg")
    com_raw = row.get("com", [0, 0, 0])
    com = None
    if not isinstance(com_raw, list) or len(com_raw) != 3:
        problems.append(f"{path}.com: got {describe(com_raw)}; expected [x, y, z] in the link frame [m]")
    else:
        com = tuple(scope.parse(f"{path}.com[{a}]", v, problems, "m") for a, v in enumerate(com_raw))
    inertia = _inertia(f"{path}.inertia", row.get("inertia"), scope, problems)
    if mass is None or com is None or any(c is None for c in com) or inertia is None:
        return None
    props = MassProperties(mass, com, inertia)
    return props if _physical(path, row, props, scope.values, problems) else None


def check_inertia(path: str, label: str, inertia: sp.Matrix, values: dict[sp.Symbol, float],
                  plane_normal: np.ndarray | None) -> list[str]:
    """The rules that depend on the plane of motion (see the module docstring).

    Parameters
    ----------
    path, label : str
        The link's row path and label, for messages.
    inertia : sympy Matrix (3, 3) [kg m^2]
    values : dict Symbol -> float
        The parameter values.
    plane_normal : ndarray (3,) or None
        The normal of the plane of motion in the link's axes; None in a spatial mechanism.

    Returns
    -------
    list of str
        The problems (empty: a valid inertia; a zero inertia, a point mass, always is).
    """
    tensor = numeric_inertia(inertia, values)
    if not tensor.any():
        return []
    moments, tol = _moments(tensor)
    where = f"{path}.inertia ({label}): principal moments {_format(moments)} kg m^2 at the parameter values"
    if plane_normal is not None:
        about_normal = float(plane_normal @ tensor @ plane_normal)
        if about_normal > tol:
            return []
        return [f"{where}, {about_normal:.6g} about the normal of the plane of motion; expected a moment > 0 "
                f"about the normal (Izz when the link's z axis is normal to the plane) in a planar mechanism"]
    if moments[0] <= tol:
        return [f"{where}; expected every principal moment > 0 (a positive definite tensor) in a spatial mechanism"]
    if moments[0] + moments[1] < moments[2] - tol:
        return [f"{where}; {moments[0]:.6g} + {moments[1]:.6g} < {moments[2]:.6g}: expected the triangle inequality "
                f"I1 + I2 >= I3 of a rigid body's principal moments in a spatial mechanism"]
    return []
