"""Issue 15's sweep of malformed inputs, through the command line: every one exits 2 with a
message naming the key, never a traceback, never a silent success.

Each entry mutates a shipped case file (a registered mechanism, or a link-coupling one) or
passes a bad ``--set``: wrong types, out-of-range numbers, NaN and infinity, unknown keys,
broken link and coupling tables, bad ``--set`` paths, and files that are not case files.
Each is physically meaningless or unreadable, so a run that exits 0 is a silent success.

Run as a script for the tally through the installed ``csim`` (one process per input)::

    .venv/bin/python tests/test_malformed_inputs.py
"""
from __future__ import annotations

import copy
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
DELETE = object()  # a mutation that removes the key


@dataclass(frozen=True)
class Bad:
    """One malformed input: ``base`` config with ``path`` set to ``value`` (or the file's text
    replaced by ``text``), plus ``args``; the message must name ``key``."""

    id: str
    base: str
    key: str
    path: str = ""
    value: object = None
    args: tuple[str, ...] = ()
    text: str | None = None


QR, PEND, FOURBAR, FB_KIN, RRR = ("quick_return.yaml", "pendulum.yaml", "fourbar_gravity.yaml", "fourbar.yaml",
                                  "rrr3_planar.yaml")
LINK1 = "mechanism.links.1"
#: how messages name link row 1
ROW1 = "mechanism.links[1]"


def _registered() -> list[Bad]:
    """Wrong types, out-of-range numbers, NaN/inf and unknown keys of registered mechanisms."""
    cases = [  # wrong types
        ("t_end-string", "simulation.t_end", "ten"), ("t_end-bool", "simulation.t_end", True),
        ("t_end-list", "simulation.t_end", [1, 2]), ("rtol-string", "simulation.rtol", "tight"),
        ("integrator-number", "simulation.integrator", 5), ("events-string", "simulation.events", "yes"),
        ("max_events-float", "simulation.max_events", 1.5), ("dt-string", "output.dt", "fast"),
        ("w-string", "stabilization.w", "big"), ("q-string", "initial.q.q1", "x"),
        ("load-string", "loads.torque", "strong"), ("name-number", "mechanism.name", 3),
        ("parameter-string", "mechanism.parameters.l1", "long"), ("section-list", "simulation", [1, 2]),
        ("loads-list", "loads", [1]), ("method-list", "stabilization.method", ["none"]),
        # out of range
        ("t_end-negative", "simulation.t_end", -1.0), ("t_end-zero", "simulation.t_end", 0),
        ("rtol-above-1", "simulation.rtol", 2.0), ("rtol-zero", "simulation.rtol", 0.0),
        ("atol-zero", "simulation.atol", 0.0), ("atol-1e-300", "simulation.atol", 1e-300),
        ("step-negative", "simulation.step", -1e-3), ("chatter_events-1", "simulation.chatter_events", 1),
        ("max_events-0", "simulation.max_events", 0), ("max_steps-0", "simulation.max_steps", 0),
        ("event_samples-negative", "simulation.event_samples", -1),
        ("event_samples-huge", "simulation.event_samples", 10**9), ("max_phi-zero", "simulation.max_phi", 0.0),
        ("min_step-negative", "simulation.min_step", -1e-10), ("dt-zero", "output.dt", 0.0),
        ("dt-too-many-samples", "output.dt", 1e-12), ("w-negative", "stabilization.w", -10.0),
        ("initial-tol-zero", "initial.tol", 0.0), ("max_condition-below-1", "formulation.max_condition", 0.5),
        ("t_end-huge-integer", "simulation.t_end", 10**400), ("window-reversed", "loads.cutting_force",
                                                               {"magnitude": 1, "window": [2, 1]}),
        # NaN and infinity
        ("t_end-nan", "simulation.t_end", float("nan")), ("t_end-inf", "simulation.t_end", float("inf")),
        ("rtol-nan", "simulation.rtol", float("nan")), ("q-inf", "initial.q.q1", float("inf")),
        ("load-nan", "loads.torque", float("nan")), ("parameter-nan", "mechanism.parameters.l1", float("nan")),
        ("w-inf", "stabilization.w", float("inf")), ("dt-inf", "output.dt", float("inf")),
        # unknown keys and names
        ("section-typo", "simulaton", {"t_end": 1}), ("key-typo", "simulation.tend", 1.0),
        ("method-key-typo", "stabilization.ww", 1.0), ("coordinate-unknown", "initial.q.q9", 1.0),
        ("load-unknown", "loads.bogus", 1.0), ("parameter-unknown", "mechanism.parameters.bogus", 1.0),
        ("mechanism-typo", "mechanism.name", "quick_retrun"), ("integrator-case", "simulation.integrator", "rk4"),
        ("method-unknown", "stabilization.method", "magic"),
    ]
    key_of = {"section-typo": "simulaton", "t_end-huge-integer": "simulation.t_end",
              "window-reversed": "loads.cutting_force.window", "dt-too-many-samples": "output.dt"}
    return [Bad(i, QR, key_of.get(i, path), path, value) for i, path, value in cases] + [
        Bad("pendulum-negative-mass", PEND, "mechanism.parameters.m", "mechanism.parameters.m", -1.0),
        Bad("pendulum-zero-length", PEND, "mechanism.parameters.L", "mechanism.parameters.L", 0.0),
        Bad("max_step-below-min_step", QR, "simulation.max_step", "simulation.max_step", 1e-12),
        Bad("mechanism-missing", QR, "mechanism.name", "mechanism", DELETE),
        # physically meaningless values of registered mechanisms
        *(Bad(f"qr-{name}-{v}", QR, f"mechanism.parameters.{name}", f"mechanism.parameters.{name}", v)
          for name, v in (("m1", -1.0), ("J2", -0.1), ("l1", 0.0), ("g", float("nan")))),
        Bad("pendulum-off-the-circle", PEND, "initial", "initial.q.x", 5.0),
        Bad("qd-nan", QR, "initial.qd.q1", "initial.qd.q1", float("nan")),
        Bad("load-magnitude-inf", QR, "loads.cutting_force.magnitude", "loads.cutting_force",
            {"magnitude": float("inf")}),
        *(Bad(f"sliding_mode-{key}-{v}", QR, f"stabilization.{key}", f"stabilization.{key}", v)
          for key, v in (("K", -1.0), ("k", -1.0), ("eps", 0.0), ("Lambda", "fast"), ("switching", "smooth"))),
        Bad("projection_tol-zero", QR, "stabilization.projection_tol", "stabilization.projection_tol", 0.0),
    ]


def _tables() -> list[Bad]:
    """Broken link and coupling tables of link-coupling mechanisms."""
    return [
        Bad("negative-mass", FOURBAR, ROW1, f"{LINK1}.mass", -0.5),
        Bad("negative-mass-expression", FOURBAR, ROW1, f"{LINK1}.mass", "-m1"),
        Bad("negative-inertia", FOURBAR, ROW1, f"{LINK1}.inertia", -1.0),
        Bad("inertia-not-symmetric", FOURBAR, ROW1, f"{LINK1}.inertia", [[1, 2, 0], [0, 1, 0], [0, 0, 1]]),
        Bad("inertia-without-mass", FOURBAR, ROW1, f"{LINK1}.mass", 0),
        Bad("com-wrong-length", FOURBAR, ROW1, f"{LINK1}.com", [1, 2]),
        Bad("mass-nan", FOURBAR, ROW1, f"{LINK1}.mass", float("nan")),
        Bad("expression-acos-2", FOURBAR, ROW1, f"{LINK1}.com", ["acos(2)", 0, 0]),
        Bad("expression-unknown-symbol", FOURBAR, ROW1, f"{LINK1}.mass", "m9"),
        Bad("expression-syntax", FOURBAR, ROW1, f"{LINK1}.mass", "m1 *"),
        Bad("joint-type-unknown", FOURBAR, ROW1, f"{LINK1}.joints.0", ["Q", 0, "A"]),
        Bad("joint-frame-7-numbers", FOURBAR, ROW1, f"{LINK1}.joints.1", ["R", [1, 2, 3, 4, 5, 6, 7], "B"]),
        Bad("joints-missing", FOURBAR, ROW1, f"{LINK1}.joints", DELETE),
        Bad("link-number-gap", FOURBAR, "mechanism.links", f"{LINK1}.link", 7),
        Bad("link-number-duplicate", FOURBAR, "mechanism.links", f"{LINK1}.link", 2),
        Bad("link-number-huge", FOURBAR, "mechanism.links", f"{LINK1}.link", 10**9),
        Bad("link-0-missing", FOURBAR, "mechanism.links", "mechanism.links.0.link", 4),
        Bad("links-empty", FOURBAR, "mechanism.links", "mechanism.links", []),
        Bad("links-not-a-list", FOURBAR, "mechanism.links", "mechanism.links", {"a": 1}),
        Bad("coupling-unknown-link", FOURBAR, "mechanism.couplings", "mechanism.couplings.1.couple",
            ["crank", "B", "nolink", "B"]),
        Bad("coupling-unknown-joint", FOURBAR, "mechanism.couplings", "mechanism.couplings.1.couple",
            ["crank", "B", "coupler", "Z"]),
        Bad("coupling-wrong-arity", FOURBAR, "mechanism.couplings", "mechanism.couplings.0", [0, 1, 1]),
        Bad("coupling-index-out-of-range", FOURBAR, "mechanism.couplings", "mechanism.couplings.0", [0, 9, 1, 1]),
        Bad("couplings-not-a-list", FOURBAR, "mechanism.couplings", "mechanism.couplings", 5),
        Bad("gravity-wrong-length", FOURBAR, "mechanism.gravity", "mechanism.gravity", [0, -9.81]),
        Bad("gravity-nan", FOURBAR, "mechanism.gravity", "mechanism.gravity", [0, float("nan"), 0]),
        Bad("parameters-string", FOURBAR, "mechanism.parameters", "mechanism.parameters.a", "long"),
        Bad("table-and-name", FOURBAR, "mechanism", "mechanism.name", "pendulum"),
        Bad("geometry-does-not-close", FOURBAR, "initial", "mechanism.parameters.b", 5.0),
        Bad("initial-unknown-variable", FOURBAR, "initial.q.q_bogus", "initial.q", {"q_bogus": 1.0}),
        Bad("force-kind-unknown", FOURBAR, "mechanism.forces", "mechanism.forces",
            [{"name": "boost", "kind": "rocket", "on": "crank"}]),
        Bad("drive-unknown-joint", FB_KIN, "mechanism.drive", "mechanism.drive", {"nojoint": "2*pi*t"}),
        Bad("over-driven", FB_KIN, "mechanism.drive", "mechanism.drive", {"crank": "2*pi*t", "rocker": "t"}),
        Bad("drive-unknown-symbol", FB_KIN, "mechanism.drive", "mechanism.drive", {"crank": "2*pi*tau"}),
        Bad("drive-complex", FB_KIN, "mechanism.drive", "mechanism.drive", {"crank": "sqrt(-1)*t"}),
        Bad("rrr-link-row-typo", RRR, "mechanism.links", "mechanism.links.1.joints", "R"),
    ]


def _set_paths() -> list[Bad]:
    """Bad ``--set`` options, and files that are not case files."""
    return [
        Bad("set-no-equals", QR, "--set", args=("--set", "simulation.t_end")),
        Bad("set-empty-key", QR, "--set", args=("--set", "=1")),
        Bad("set-unknown-key", QR, "bogus.key", args=("--set", "bogus.key=1")),
        Bad("set-below-a-leaf", QR, "simulation.t_end", args=("--set", "simulation.t_end.x=1")),
        Bad("set-empty-value", QR, "simulation.t_end", args=("--set", "simulation.t_end=")),
        Bad("set-bad-yaml", QR, "simulation.t_end", args=("--set", "simulation.t_end=[1,")),
        Bad("set-section-to-number", QR, "simulation", args=("--set", "simulation=3")),
        Bad("set-typo-section", QR, "simulaton", args=("--set", "simulaton.t_end=1")),
        Bad("set-nan", QR, "simulation.step", args=("--set", "simulation.step=.nan")),
        Bad("set-link-row-out-of-range", FOURBAR, "mechanism.links", args=("--set", "mechanism.links.9.mass=1")),
        Bad("file-empty", QR, "mechanism.name", text=""),  # an empty file is an empty case: no mechanism
        Bad("file-not-yaml", QR, "case", text="mechanism: {name: quick_return\nsimulation: [\n"),
        Bad("file-a-list", QR, "case", text="- 1\n- 2\n"),
        Bad("file-a-number", QR, "case", text="42\n"),
        Bad("file-tab-indent", QR, "case", text="mechanism:\n\tname: quick_return\n"),
    ]


BAD = _registered() + _tables() + _set_paths()


def _set(doc, path: str, value) -> None:
    """Set (or with DELETE remove) the dotted ``path`` of ``doc``; list items by number."""
    *parents, last = path.split(".")
    node = doc
    for part in parents:
        node = node[int(part)] if isinstance(node, list) else node.setdefault(part, {})
    if isinstance(node, list):
        node[int(last)] = value
    elif value is DELETE:
        node.pop(last, None)
    else:
        node[last] = value


def write_case(bad: Bad, folder: Path) -> Path:
    """The malformed case file of ``bad`` in ``folder``."""
    path = folder / f"{bad.id}.yaml"
    if bad.text is not None:
        path.write_text(bad.text)
        return path
    doc = yaml.safe_load((CONFIGS / bad.base).read_text())
    doc = copy.deepcopy(doc)
    doc.setdefault("simulation", {})["t_end"] = 0.05  # a mutation that is (wrongly) accepted runs a moment
    if bad.path:
        _set(doc, bad.path, bad.value)
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


#: no compilation for a mutation that is (wrongly) accepted
SHORT = ("--set", "simulation.backend=python")


def classify(code: int, stderr: str, bad: Bad, case: Path) -> str:
    """``clear`` (exit 2 naming the key, or the file for a file that is not a case file),
    ``vague`` (exit 2 without the key), ``silent`` (exit 0), ``failed`` (exit 1), or
    ``traceback``."""
    if "Traceback" in stderr or code not in (0, 1, 2):
        return "traceback"
    if code == 0:
        return "silent"
    if code == 1:
        return "failed"
    named = bad.key in stderr or (bad.key == "case" and str(case) in stderr)
    return "clear" if named else "vague"


def test_the_inputs_are_distinct_and_many():
    assert len(BAD) >= 78 and len({b.id for b in BAD}) == len(BAD)


@pytest.mark.parametrize("bad", BAD, ids=[b.id for b in BAD])
def test_a_malformed_input_exits_2_naming_its_key(bad, tmp_path):
    from conftest import invoke

    case = write_case(bad, tmp_path)
    args = bad.args if bad.args else ()
    shorten = () if bad.text is not None or bad.args else SHORT
    result = invoke("run", case, "-o", tmp_path / "out.h5", *shorten, *args)
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exc_info
    assert classify(result.exit_code, result.stderr, bad, case) == "clear", result.output
    if (tmp_path / "out.h5").exists():  # only a registered mechanism that cannot be assembled writes one, marked
        from csim.io.hdf5 import read_result

        written = read_result(tmp_path / "out.h5")
        assert (written.status, written.failure) == ("failed", "assembly")


def main() -> int:
    """Run every input through the installed ``csim`` (one process each) and print the tally."""
    import tempfile
    from collections import Counter

    csim = Path(sys.executable).parent / "csim"
    tally, lines = Counter(), []
    with tempfile.TemporaryDirectory() as tmp:
        for bad in BAD:
            case = write_case(bad, Path(tmp))
            shorten = () if bad.text is not None or bad.args else SHORT
            proc = subprocess.run([str(csim), "run", str(case), "-o", f"{tmp}/out.h5", "-q", *shorten, *bad.args],
                                  capture_output=True, text=True, timeout=300)
            kind = classify(proc.returncode, proc.stderr, bad, case)
            tally[kind] += 1
            text = [ln.strip().removeprefix("csim: error:").strip() for ln in proc.stderr.splitlines()]
            first = next((ln for ln in text if ln and "problem(s):" not in ln), "")
            lines.append(f"{kind:<9} exit {proc.returncode}  {bad.id}: {first[:150]}")
    print("\n".join(lines))
    print(f"\n{len(BAD)} inputs: " + ", ".join(f"{n} {k}" for k, n in tally.most_common()))
    return 0 if tally["clear"] == len(BAD) else 1


if __name__ == "__main__":
    sys.exit(main())
