"""The example cases (``csim examples DIR``): where they are, and copying them out.

The cases of ``configs/`` in the source tree ship in the distribution as the package data
``csim.examples`` (and ``csim.examples.batch``, the batch manifest). A copy gets the case
schema as ``csim-case.schema.json`` beside the cases, and each case's yaml-language-server
modeline points to it.
"""
from __future__ import annotations

import json
from pathlib import Path

from csim.errors import ResultFileError
from csim.io.atomic import write_atomically

#: the modeline of a shipped case, and of its copy
MODELINE = "# yaml-language-server: $schema=../csim-case.schema.json"
COPY_MODELINE = "# yaml-language-server: $schema=csim-case.schema.json"


def examples_dir() -> Path:
    """The folder of the example cases: the installed package data, else the source tree's ``configs/``."""
    import importlib.util

    try:  # the package's folder, a regular or a namespace package (configs/ has no __init__.py)
        spec = importlib.util.find_spec("csim.examples")
    except (ModuleNotFoundError, ValueError):
        spec = None
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        root = Path(location)
        if any(root.glob("*.yaml")):
            return root
    return Path(__file__).resolve().parents[2] / "configs"


def example_files() -> list[Path]:
    """The example files, relative to :func:`examples_dir` (cases, then ``batch/``)."""
    root = examples_dir()
    return sorted(p.relative_to(root) for p in root.rglob("*.yaml"))


def copy_examples(dest: str | Path, schema: dict) -> list[Path]:
    """Copy the example cases into ``dest`` (created), with the case schema ``schema``
    (:func:`csim.case.json_schema`) beside them as ``csim-case.schema.json``.

    Raises
    ------
    ResultFileError
        When a file of the same name is already in ``dest`` (nothing is written then), or
        ``dest`` cannot be written. Each file goes through a temporary file beside it
        (:func:`csim.io.atomic.write_atomically`): none is left partial, and a dangling
        symbolic link at a file's name is replaced by the file, never written through.

    Returns
    -------
    list of Path
        The files written.
    """
    dest, root = Path(dest), examples_dir()
    names = example_files()
    if not names:
        raise ResultFileError(f"no example cases found in {root}")
    targets = [dest / n for n in names] + [dest / "csim-case.schema.json"]
    present = [str(t) for t in targets if t.exists()]
    if present:
        raise ResultFileError(f"{dest}: would replace {', '.join(present)}; expected a folder without them")
    try:
        for name in names:  # each through a temporary file: none left partial, no symbolic link written through
            text = (root / name).read_text()
            if name.parent == Path("."):
                text = text.replace(MODELINE, COPY_MODELINE, 1)
            write_atomically(dest / name, text.encode())
        write_atomically(dest / "csim-case.schema.json", (json.dumps(schema, indent=2) + "\n").encode())
    except OSError as exc:
        raise ResultFileError(f"{dest}: cannot write there ({exc.strerror or exc})") from None
    return targets
