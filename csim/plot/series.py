"""Series names: how figures (declared by mechanisms, or generic) name what they plot.

A series name is ``KIND:NAME``, optionally prefixed by ``change:`` (the change since the
first sample). Kinds, with the unit of their values:

=================== ============================================ =============================
kind                NAME                                         values
=================== ============================================ =============================
``q``               a coordinate                                 q_i [rad or m]
``qd``              a coordinate                                 dq_i/dt [rad/s or m/s]
``qdd``             a coordinate                                 d2q_i/dt2 [rad/s^2 or m/s^2]
``observable``      an observable of the mechanism               s(q) [its unit]
``observable_rate`` an observable of the mechanism               ds/dt [its rate unit]
``phi``             constraint number I (from 1), or ``max``     Phi_I, or max_i |Phi_i|
``phi_dot``         constraint number I (from 1), or ``max``     (Phi_q qd)_I, or max_i |.|
``lambda``          constraint number I (from 1)                 lambda_I [J / unit of Phi_I]
``load``            a load                                       u_k [N or N m]
``work``            a load                                       work of u_k since t = 0 [J]
``energy``          ``kinetic``, ``potential``, ``balance_error`` [J]
=================== ============================================ =============================
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from csim.io.units import multiplier_unit
from csim.plot.errors import PlotError
from csim.plot.source import RunData

KINDS = ("q", "qd", "qdd", "observable", "observable_rate", "phi", "phi_dot", "lambda", "load", "work", "energy")
ENERGIES = ("kinetic", "potential", "balance_error")
CHANGE = "change:"


@dataclass
class Series:
    """A time series of one run, ready to plot.

    Attributes
    ----------
    name : str
        The series name it was resolved from.
    values : ndarray (N,)
        Values at the run's output times, in ``unit``.
    label : str
        Legend label (matplotlib mathtext allowed).
    unit : str
    """

    name: str
    values: np.ndarray
    label: str
    unit: str


def _per_second(unit: str, power: int = 1) -> str:
    """``unit`` per second (``power``: per s^power); an unknown unit (``""``) stays unknown."""
    if not unit:
        return ""
    if unit == "1":
        return "1/s" if power == 1 else f"1/s^{power}"
    return f"{unit}/s" if power == 1 else f"{unit}/s^{power}"


def series_names(run: RunData) -> list[str]:
    """Every series name valid for ``run`` (without the ``change:`` prefix)."""
    r = run.result
    names = [f"{kind}:{c}" for kind in ("q", "qd", "qdd") for c in r.coordinate_names]
    names += [f"{kind}:{o}" for kind in ("observable", "observable_rate") for o in r.observable_names]
    n_con = r.phi.shape[1]
    names += [f"{kind}:{i}" for kind in ("phi", "phi_dot", "lambda") for i in range(1, n_con + 1)]
    names += ["phi:max", "phi_dot:max"] if n_con else []
    names += [f"{kind}:{ld}" for kind in ("load", "work") for ld in r.load_names]
    names += [f"energy:{e}" for e in ENERGIES]
    return names


def _bad(name: str, run: RunData, why: str) -> PlotError:
    return PlotError(f"series {name!r}: {why}; valid series of this {run.result.mechanism} run: "
                     f"{', '.join(series_names(run))} (each may be prefixed by {CHANGE!r})")


def _index(name: str, choices: list[str], what: str, key: str, run: RunData) -> int:
    if key not in choices:
        raise _bad(name, run, f"no {what} {key!r}")
    return choices.index(key)


def _constraint(name: str, key: str, run: RunData, allow_max: bool) -> int | None:
    r = run.result.phi.shape[1]
    if allow_max and key == "max":
        if r == 0:
            raise _bad(name, run, "the mechanism has no constraints")
        return None
    try:
        i = int(key)
    except ValueError:
        i = 0
    if not 1 <= i <= r:
        raise _bad(name, run, f"constraint number {key!r} is not in 1..{r}")
    return i - 1


def resolve(name: str, run: RunData) -> Series:
    """The values, label and unit of the series ``name`` in ``run``.

    Raises
    ------
    PlotError
        For an unknown kind or name, listing the valid series of the run.
    """
    change = name.startswith(CHANGE)
    body = name[len(CHANGE):] if change else name
    kind, sep, key = body.partition(":")
    if not sep or kind not in KINDS:
        raise _bad(name, run, f"unknown kind {kind!r} (kinds: {', '.join(KINDS)})")
    res, d = run.result, run.definition
    if kind in ("q", "qd", "qdd"):
        j = _index(name, res.coordinate_names, "coordinate", key, run)
        unit = run.coordinate_units[j] if j < len(run.coordinate_units) else ""
        values = {"q": res.q, "qd": res.qd, "qdd": res.qdd}[kind][:, j]
        # plain text: a coordinate name is not necessarily valid mathtext
        label, unit = {"q": (key, unit), "qd": (f"d{key}/dt", _per_second(unit)),
                       "qdd": (f"d\u00b2{key}/dt\u00b2", _per_second(unit, 2))}[kind]
    elif kind in ("observable", "observable_rate"):
        j = _index(name, res.observable_names, "observable", key, run)
        obs = next((o for o in d.observables if o.name == key), None) if d is not None else None
        if kind == "observable":
            values, unit = res.observables[:, j], obs.unit if obs else ""
            label = obs.description if obs else key
        else:
            values, unit = res.observable_rates[:, j], obs.rate_unit if obs else ""
            label = f"rate of {obs.description}" if obs else f"d{key}/dt"
    elif kind in ("phi", "phi_dot"):
        i = _constraint(name, key, run, allow_max=True)
        data = res.phi if kind == "phi" else res.phi_dot
        units = run.constraint_units
        symbol = r"\Phi" if kind == "phi" else r"\dot{\Phi}"
        if i is None:
            values = np.max(np.abs(data), axis=1) if data.shape[0] else np.zeros(0)
            label = f"$\\mathrm{{max}}_i\\,|{symbol}_i|$"
            unit = units[0] if units and len(set(units)) == 1 else ""
        else:
            values, label = data[:, i], f"${symbol}_{{{i + 1}}}$"
            unit = units[i] if i < len(units) else ""
        unit = _per_second(unit) if kind == "phi_dot" else unit
    elif kind == "lambda":
        i = _constraint(name, key, run, allow_max=False)
        values, label = res.lam[:, i], f"$\\lambda_{{{i + 1}}}$"
        unit = multiplier_unit(run.constraint_units[i] if i < len(run.constraint_units) else "")
    elif kind in ("load", "work"):
        j = _index(name, res.load_names, "load", key, run)
        load = next((ld for ld in d.loads if ld.name == key), None) if d is not None else None
        if kind == "load":
            values, unit, label = res.loads[:, j], load.unit if load else "", key.replace("_", " ")
        else:
            values, unit, label = res.work[:, j], "J", f"work of the {key.replace('_', ' ')}"
    else:
        if key not in ENERGIES:
            raise _bad(name, run, f"no energy {key!r} (energies: {', '.join(ENERGIES)})")
        values = {"kinetic": res.kinetic, "potential": res.potential, "balance_error": res.energy_error}[key]
        label = {"kinetic": "kinetic energy T", "potential": "potential energy V",
                 "balance_error": "$T + V - T_0 - V_0 - W$"}[key]
        unit = "J"
    values = np.asarray(values, dtype=float)
    if change:
        values = values - values[0] if values.size else values
        label = f"{label} (change since t = 0)"
    return Series(name=name, values=values, label=label, unit=unit)
