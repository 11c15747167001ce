"""Batch manifests: read the YAML, validate every entry, its case and its expectations.

A manifest lists cases to run and what each run must give::

    defaults:                          # optional; applies to every entry
      set: [simulation.backend=auto]   # overrides applied before each entry's own
      expect: {wall_time: 5}           # each kind, unless the entry states that kind itself
    cases:
      - name: qr_projection            # letters, digits, _ . - (it names the result file)
        case: ../quick_return.yaml     # relative to the manifest file
        set: [stabilization.method=projection, simulation.t_end=10]   # as csim run --set
        expect:
          max_phi: 1e-10
          value: {name: q1, t: 10, expected: 106.602786309695, tol: 1e-6}

An entry without a ``status`` expectation (its own or a default) expects ``success``.
Every problem (unknown keys, bad values, unknown expectation kinds, a missing case file,
a case the validator rejects) is reported at once, as :class:`ManifestError`, each line
naming the key path (``cases[2].expect.max_phi``), the value and what was expected.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from csim.batch.expectations import Expectation, StatusExpectation, parse_expectations
from csim.case import Case, load_case, parse_yaml, read_text
from csim.errors import CaseError, ManifestError
from csim.schema import describe, unknown_key

#: the keys of a manifest, of its ``defaults`` and of an entry
TOP_KEYS = ("defaults", "cases")
DEFAULT_KEYS = ("set", "expect")
ENTRY_KEYS = ("name", "case", "set", "expect")
#: what an entry's name may be: it names a result file (``-o DIR``) and a JUnit test case
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


@dataclass
class Entry:
    """One case of a batch, validated.

    Attributes
    ----------
    name : str
        Unique within the manifest.
    case_file : Path
        The case file (resolved against the manifest's folder).
    overrides : list of str
        ``key.path=value`` overrides: the defaults' first, then the entry's own.
    case : Case
        The validated case, overrides applied.
    expectations : list of Expectation
        What the run must give, the entry's own first, then the defaults' (a ``status``
        expectation is always among them).
    """

    name: str
    case_file: Path
    overrides: list[str]
    case: Case
    expectations: list[Expectation] = field(default_factory=list)


@dataclass
class Manifest:
    """A validated manifest: its path and its entries, in file order."""

    path: Path
    entries: list[Entry]


def load_manifest(path: str | Path, only: list[str] | None = None) -> Manifest:
    """Read and validate the manifest at ``path``.

    Parameters
    ----------
    path : str or Path
        The manifest (YAML). Case paths in it are relative to its folder.
    only : list of str, optional
        Keep only the entries of these names (each must exist).

    Returns
    -------
    Manifest

    Raises
    ------
    ManifestError
        Listing every problem found.
    """
    path = Path(path)
    text = read_text(path, "manifest file", ManifestError)
    try:
        data = parse_yaml(text, str(path))
    except CaseError as exc:
        raise ManifestError(exc.problems) from None
    problems: list[str] = []
    defaults, raw_entries = _check_top(path, data, problems)
    raw_entries = _select(raw_entries, only, problems)
    entries = [entry for i, raw in raw_entries
               if (entry := _read_entry(i, raw, defaults, path.parent, problems)) is not None]
    if problems:
        raise ManifestError(problems)
    return Manifest(path=path, entries=entries)


def _check_top(path: Path, data: Any, problems: list[str]) -> tuple[dict, list[tuple[int, dict]]]:
    """The ``defaults`` (checked) and the entries that are mappings with a valid, unique name,
    with their index in ``cases``."""
    if not isinstance(data, dict):
        problems.append(f"{path}: got {describe(data)} at the top level; expected a mapping with keys "
                        f"{', '.join(TOP_KEYS)}")
        raise ManifestError(problems)
    for key in data:
        if key not in TOP_KEYS:
            problems.append(unknown_key("", str(key), list(TOP_KEYS)))
    defaults = data.get("defaults") or {}
    if not isinstance(defaults, dict):
        problems.append(f"defaults: got {describe(defaults)}; expected a mapping with keys {', '.join(DEFAULT_KEYS)}")
        defaults = {}
    for key in defaults:
        if key not in DEFAULT_KEYS:
            problems.append(unknown_key("defaults", str(key), list(DEFAULT_KEYS)))
    defaults = {"set": _overrides("defaults.set", defaults.get("set"), problems),
                "expect": _mapping("defaults.expect", defaults.get("expect"), problems)}
    cases = data.get("cases")
    if not isinstance(cases, list) or not cases:
        what = "missing" if "cases" not in data else f"got {describe(cases)}"
        problems.append(f"cases: {what}; expected a list of entries, each a mapping with keys "
                        f"{', '.join(ENTRY_KEYS)} (set and expect optional)")
        return defaults, []
    entries, seen = [], set()
    for i, raw in enumerate(cases):
        where = f"cases[{i}]"
        if not isinstance(raw, dict):
            problems.append(f"{where}: got {describe(raw)}; expected a mapping with keys {', '.join(ENTRY_KEYS)}")
            continue
        name = raw.get("name")
        if not isinstance(name, str) or not NAME_PATTERN.match(name):
            problems.append(f"{where}.name: " + ("missing" if "name" not in raw else f"got {describe(name)}")
                            + "; expected a name of letters, digits, _, . and - (it names the result file)")
            continue
        if name in seen:
            problems.append(f"{where}.name: got {name!r} again; expected a name not used by another entry")
            continue
        seen.add(name)
        entries.append((i, raw))
    return defaults, entries


def _select(entries: list[tuple[int, dict]], only: list[str] | None, problems: list[str]) -> list[tuple[int, dict]]:
    """The entries named in ``only`` (all when None); unknown names are problems."""
    if only is None:
        return entries
    names = [raw["name"] for _, raw in entries]
    for name in only:
        if name not in names:
            problems.append(f"--only {name}: no entry of that name; expected one of {', '.join(names)}")
    return [(i, raw) for i, raw in entries if raw["name"] in only]


def _read_entry(i: int, raw: dict, defaults: dict, folder: Path, problems: list[str]) -> Entry | None:
    """One entry: its keys, its case (overrides applied) and its expectations; None when bad."""
    where, n = f"cases[{i}]", len(problems)
    for key in raw:
        if key not in ENTRY_KEYS:
            problems.append(unknown_key(where, str(key), list(ENTRY_KEYS)))
    overrides = [*defaults["set"], *_overrides(f"{where}.set", raw.get("set"), problems)]
    expect = _mapping(f"{where}.expect", raw.get("expect"), problems)
    case_path = raw.get("case")
    if not isinstance(case_path, str) or not case_path:
        problems.append(f"{where}.case: " + ("missing" if "case" not in raw else f"got {describe(case_path)}")
                        + "; expected the path of a case file, relative to the manifest")
        return None
    case_file = folder / case_path
    try:
        case = load_case(case_file, overrides)
    except CaseError as exc:
        problems.extend(f"{where} ({raw['name']}): {problem}" for problem in exc.problems)
        return None
    expectations = parse_expectations(f"{where}.expect", expect, case, problems)
    inherited = {k: v for k, v in defaults["expect"].items() if k not in expect}
    expectations += parse_expectations(f"defaults.expect (for {where})", inherited, case, problems)
    if not any(isinstance(e, StatusExpectation) for e in expectations):
        expectations.insert(0, StatusExpectation("success"))
    if len(problems) > n:
        return None
    return Entry(name=raw["name"], case_file=case_file, overrides=overrides, case=case, expectations=expectations)


def _overrides(path: str, value: Any, problems: list[str]) -> list[str]:
    """A ``set:`` list of ``KEY=VALUE`` strings (empty when absent or bad)."""
    if value is None:
        return []
    if not isinstance(value, list) or not all(isinstance(v, str) and "=" in v for v in value):
        problems.append(f"{path}: got {describe(value)}; expected a list of KEY=VALUE strings as for csim run --set, "
                        f"e.g. [simulation.t_end=10, stabilization.method=projection]")
        return []
    return list(value)


def _mapping(path: str, value: Any, problems: list[str]) -> dict:
    """An ``expect:`` mapping (empty when absent or bad)."""
    if value is None:
        return {}
    if not isinstance(value, dict):
        problems.append(f"{path}: got {describe(value)}; expected a mapping of expectation kind: spec")
        return {}
    return value
