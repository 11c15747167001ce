"""A sweep's plan: the base case, the varied keys and the value of each key in each run.

Three ways to combine the varied keys (``sampling``):

``grid``
    every combination of the keys' values (the first key varies slowest);
``random``
    ``samples`` independent draws, each key from its distribution (:mod:`csim.study.values`);
``lhs``
    a Latin hypercube of ``samples`` runs: each key's range cut into ``samples`` strata of
    equal probability, one draw in each, the strata of the keys paired at random.

Both random designs are reproducible from ``seed``.
"""
from __future__ import annotations

import copy
import itertools
import json
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from csim.case import SETTABLE, Case, apply_overrides, validate_case
from csim.errors import CaseError
from csim.io.units import DIMENSIONLESS, UNKNOWN, per_time, phi_unit_text
from csim.study.values import Variation

SAMPLINGS = ("grid", "random", "lhs")


#: most runs a sweep may plan (a typo such as lin:0:1:1e9 is caught before memory runs out)
MAX_RUNS = 10_000_000


def value_text(value: Any) -> str:
    """A value as YAML flow text (JSON, but for non-finite floats, which YAML writes .inf, .nan)."""
    if isinstance(value, float) and not math.isfinite(value):
        return ".nan" if math.isnan(value) else (".inf" if value > 0 else "-.inf")
    return json.dumps(value)


def override(key: str, value: Any) -> str:
    """The ``--set`` text that gives ``key`` the value ``value``."""
    return f"{key}={value_text(value)}"


@dataclass
class SweepPlan:
    """The runs of a sweep.

    Attributes
    ----------
    case : Case
        The validated base case.
    data : dict
        The base case as read (``--set`` applied), before validation: each run is this with
        its row's values set, then validated, so that a run may change what the defaults
        depend on (``mechanism.name``).
    variations : list of Variation
        The varied keys, in the order given.
    rows : list of tuple
        One tuple of values per run, in the order of ``variations``.
    sampling : {"grid", "random", "lhs"}
    seed : int or None
    """

    case: Case
    data: dict
    variations: list[Variation]
    rows: list[tuple]
    sampling: str = "grid"
    seed: int | None = None

    @property
    def keys(self) -> list[str]:
        return [v.key for v in self.variations]

    def __len__(self) -> int:
        return len(self.rows)

    def overrides(self, i: int) -> list[str]:
        """The ``--set`` overrides of run ``i`` (on top of the base case)."""
        return [override(key, value) for key, value in zip(self.keys, self.rows[i])]

    def run_case(self, i: int) -> Case:
        """The validated case of run ``i`` (raises CaseError for a combination the case check rejects)."""
        data = apply_overrides(copy.deepcopy(self.data), self.overrides(i))
        return validate_case(data, source=f"{self.case.source} (sweep run {i})")

    def column(self, key: str) -> list:
        """The values of ``key`` in every run."""
        j = self.keys.index(key)
        return [row[j] for row in self.rows]


def _integer_key(key: str) -> bool:
    """Whether the case schema declares ``key`` an integer (``simulation.max_steps``)."""
    field = SETTABLE.get(key)
    return field is not None and field.type == "integer"


def _whole_numbers(variation: Variation, values: list) -> list:
    """A range's values, as whole numbers for an integer key (numbers drawn or spaced between whole ends)."""
    if variation.kind == "list" or not _integer_key(variation.key):
        return list(values)
    return [int(round(x)) for x in values]


def _rows(variations: list[Variation], sampling: str, samples: int | None, seed: int | None) -> list[tuple]:
    if sampling == "grid":
        return list(itertools.product(*(_whole_numbers(v, v.values) for v in variations)))
    rng = np.random.default_rng(seed)
    n, d = samples, len(variations)
    if sampling == "random":
        u = rng.random((n, d))
    else:  # Latin hypercube: one point in each of n equal strata per key, strata paired at random
        u = (np.argsort(rng.random((n, d)), axis=0) + rng.random((n, d))) / n
    columns = [_whole_numbers(v, v.sample(u[:, j])) for j, v in enumerate(variations)]
    return list(zip(*columns))


def _check_options(variations: list[Variation], sampling: str, samples: int | None,
                   seed: int | None) -> list[str]:
    problems = []
    if seed is not None and not 0 <= seed < 2**63:
        problems.append(f"--seed: got {seed}; expected a whole number from 0 to 2**63 - 1")
    if not variations:
        problems.append("--vary: nothing to vary; give at least one --vary KEY=VALUES")
    keys = [v.key for v in variations]
    for key in sorted({k for k in keys if keys.count(k) > 1}):
        problems.append(f"--vary {key}: the key is varied twice; give each key once")
    if sampling not in SAMPLINGS:
        problems.append(f"--sample: got {sampling!r}; valid: {', '.join(SAMPLINGS)}")
    elif sampling == "grid":
        if samples is not None:
            problems.append("--samples: only with --sample random or --sample lhs (a grid runs every combination)")
        if seed is not None:
            problems.append("--seed: only with --sample random or --sample lhs (a grid has nothing to draw)")
        if math.prod(len(v.values) for v in variations if v.values) > MAX_RUNS:
            problems.append(f"--vary: the grid has more than {MAX_RUNS:,} runs; vary fewer values")
        problems += [f"--vary {v.text!r}: a grid needs N values; write {v.kind}:START:STOP:N"
                     for v in variations if not v.values]
    elif samples is None or not 1 <= samples <= MAX_RUNS:
        problems.append(f"--samples: --sample {sampling} needs the number of runs, a whole number from 1 to "
                        f"{MAX_RUNS:,}; got {samples}")
    return problems


def _check_values(case: Case, data: dict, variations: list[Variation]) -> list[str]:
    """Each value of each key, set alone on the base case, must pass the case check."""
    problems = []
    for v in variations:
        probe = _whole_numbers(v, v.values or v.sample(np.array([0.0, 1.0])))
        for value in dict.fromkeys(value_text(x) for x in probe):  # each distinct value once
            try:
                validate_case(apply_overrides(copy.deepcopy(data), [f"{v.key}={value}"]), source=case.source)
            except CaseError as exc:
                problems += [f"--vary {v.key}={value}: {p.removeprefix('--set ')}" for p in exc.problems]
                break
    return problems


def key_unit(case, key: str, constraint_unit: str | list[str] = "") -> str:
    """The unit of a case key's value (what ``csim sweep`` varies), parsable; ``1`` for a
    dimensionless number or a name, ``""`` where csim does not know it.

    Parameters
    ----------
    case : Case
        The validated base case (its mechanism's parameters, coordinates and loads).
    key : str
        A dotted key, e.g. ``stabilization.w``, ``mechanism.parameters.l1``, ``initial.q.q1``,
        ``loads.torque`` or ``loads.torque.magnitude``.
    constraint_unit : str or list of str
        The constraints' unit (:func:`csim.io.units.common_unit`), for the keys in the unit of Phi.
    """
    parts = key.split(".")
    mech = case.mechanism
    spec = SETTABLE.get(key)
    if spec is not None:
        if spec.type in ("string", "boolean"):
            return DIMENSIONLESS
        if spec.unit and spec.unit != "-":  # a number, or a gain that may be one per constraint
            return phi_unit_text(spec.unit, constraint_unit)
        return DIMENSIONLESS if spec.type in ("number", "integer") else ""
    if parts[:2] == ["mechanism", "parameters"] and len(parts) == 3:
        try:  # a link-coupling parameter declares no unit: unknown, not dimensionless
            return mech.parameter(parts[2]).unit or UNKNOWN
        except KeyError:
            return ""
    if parts[0] == "initial" and len(parts) == 3 and parts[2] in mech.coordinate_names:
        unit = mech.coordinate_units[mech.coordinate_names.index(parts[2])]
        return {"q": unit, "qd": per_time(unit), "guess": unit, "q_offset": unit,
                "qd_offset": per_time(unit)}.get(parts[1], "")
    if parts[0] == "loads" and len(parts) >= 2:
        units = {ld.name: ld.unit for ld in mech.loads}
        if len(parts) == 2 or parts[2] == "magnitude":
            return units.get(parts[1], "")
    return ""


def unit_of(case: Case, key: str) -> str | None:
    """The unit a value of ``key`` written with a unit is converted to (a schema key's declared
    unit, which refuses units where it is ``""`` or the unit of Phi; a parameter's, a
    coordinate's or a load's unit; SI base units for a link-coupling parameter, as in a case
    file); None where csim does not know it, or for a text key."""
    from csim.quantities import SI_BASE

    spec = SETTABLE.get(key)
    if spec is not None:
        return None if spec.type in ("string", "boolean") else spec.unit
    parts = key.split(".")
    if parts[:2] == ["mechanism", "parameters"] and len(parts) == 3 and case.linkage is not None:
        return SI_BASE  # a link-coupling parameter: any unit, in SI base units (as in the case file)
    return key_unit(case, key) or None


def _in_units(case: Case, variations: list[Variation]) -> tuple[list[Variation], list[str]]:
    """The variations with values written with a unit converted to their keys' units."""
    converted, problems = [], []
    for v in variations:
        try:
            converted.append(v.in_unit(unit_of(case, v.key)) if v.has_units else v)
        except CaseError as exc:
            problems += exc.problems
            converted.append(v)
    return converted, problems


def make_plan(case: Case, variations: list[Variation], sampling: str = "grid", samples: int | None = None,
              seed: int | None = None, data: dict | None = None) -> SweepPlan:
    """Check the options and every key's values against the base case; list the runs.

    ``data`` is the base case as read, before validation (default: the validated data,
    whose filled-in defaults belong to the base case's mechanism).

    Values written with a unit (``170 deg``, ``lin:100 ms:2 s:20``) are converted to the
    key's unit first (:func:`unit_of`), so the plan and the sweep file hold numbers.

    Raises
    ------
    CaseError
        Listing every problem: a unit that does not fit its key, a key varied twice, a grid range without N, a value the
        case check rejects (naming the key, the value and what was expected).
    """
    data = copy.deepcopy(case.data if data is None else data)
    variations, problems = _in_units(case, variations)
    if not problems:
        problems = _check_options(variations, sampling, samples, seed)
    if not problems:
        problems = _check_values(case, data, [v for v in variations if v.values or v.bounds])
    if problems:
        raise CaseError(problems)
    if sampling != "grid" and seed is None:
        seed = int(np.random.default_rng().integers(2**31))  # recorded, so the design can be made again
    return SweepPlan(case=case, data=data, variations=list(variations), rows=_rows(variations, sampling, samples, seed),
                     sampling=sampling, seed=seed)
