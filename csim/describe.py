"""``csim describe CASE.yaml``: read a case file's link-coupling description, derive its
kinematics and write what csim derived (:mod:`csim.linkage.describe` formats it)."""
from __future__ import annotations

from pathlib import Path

from csim.case import SCHEMA, read_case_file
from csim.errors import CaseError
from csim.linkage.describe import describe_case, drive_mode
from csim.linkage.model import Linkage, build_linkage
from csim.schema import describe as describe_value
from csim.schema import validate_section


def read_mechanism(path: str | Path, overrides: list[str] | None = None) -> tuple[dict, dict]:
    """The validated ``mechanism`` and ``initial`` sections of a case file with a link-coupling
    description (no run settings needed).

    Raises
    ------
    CaseError
        The file is missing or not valid YAML, or its mechanism is not a link-coupling
        description.
    """
    data = read_case_file(path, overrides)
    problems: list[str] = []
    mechanism = validate_section("mechanism", data.get("mechanism"), SCHEMA.fields["mechanism"], problems)
    initial = validate_section("initial", data.get("initial"), SCHEMA.fields["initial"], problems)
    if not problems and mechanism.get("links") is None:
        problems.append(f"mechanism.links: missing; csim describe works on link-coupling descriptions; expected "
                        f"mechanism.links and mechanism.couplings (mechanism.name is "
                        f"{describe_value(mechanism.get('name'))})")
    if problems:
        raise CaseError(problems)
    return mechanism, initial


def load_linkage(path: str | Path, overrides: list[str] | None = None) -> Linkage:
    """Read a case file and derive its link-coupling model (no run settings needed).

    Raises
    ------
    CaseError
        As :func:`read_mechanism`, or the description is invalid (the message names the
        table row).
    """
    mechanism, initial = read_mechanism(path, overrides)
    return build_linkage(mechanism, initial, tol=initial["tol"], max_iter=initial["max_iter"])


def describe_main(path: str | Path, latex: bool = False, json: bool = False, links: list[int] | None = None,
                  overrides: list[str] | None = None) -> str:
    """``csim describe CASE.yaml [--latex] [--json] [--link N ...] [--set KEY=VALUE ...]``.

    Raises
    ------
    CaseError
        Bad input (see :func:`load_linkage`), naming the table row.
    """
    from csim.progress import status

    mechanism, initial = read_mechanism(path, overrides)
    with status(f"deriving the kinematics of {Path(path).name}", delay=1.0):
        linkage = build_linkage(mechanism, initial, tol=initial["tol"], max_iter=initial["max_iter"],
                                definition=False)
    with status(f"writing the description of {Path(path).name}", delay=1.0):
        return describe_case(linkage, latex=latex, as_json=json, links=links, mode=drive_mode(linkage, mechanism))
