"""Property-based fuzzing of case files: every mutated document is valid, or rejected with a
message naming the key, never a traceback, and never a success on meaningless input.

Documents are the shipped configs (registered mechanisms and link-coupling tables),
mutated one place at a time by hypothesis: a value replaced by a wrong type, NaN, +-inf,
a negative, zero, a huge or an empty value; a key deleted; an unknown key added; a table
row corrupted; and random ``--set KEY=VALUE`` overrides, nonexistent keys included. Most
examples go through :func:`csim.case.validate_case` directly; fewer through the command
line (in process, with a very short ``t_end``). What must be rejected is judged by the
mutation and the key, independently of csim's schema: NaN anywhere, +-inf except at an
open load window, a wrong type for a number, a non-positive value of a quantity that is
positive by its physics (times, tolerances, steps, gains, masses, lengths), an unknown
key in a section or table row.

The default run keeps to a fixed, derandomized set of examples (well under 60 s); the
``slow`` profile runs many more, Bricard's spatial linkage included.
"""
from __future__ import annotations

import copy
import math
import re

import pytest
import yaml
from conftest import CONFIGS, invoke
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from csim.case import SETTABLE, CaseLoader, apply_overrides, validate_case
from csim.errors import CaseError
from csim.mechanisms import light_mechanism

#: nonsense geometry is evaluated on its way to a message (nan in sin, overflow): expected here
pytestmark = pytest.mark.filterwarnings("ignore::RuntimeWarning")

REGISTERED = ["quick_return.yaml", "pendulum.yaml", "andrews.yaml", "quick_return_compare.yaml"]
LINKAGE = ["fourbar.yaml", "fourbar_gravity.yaml", "slider_crank.yaml", "rrr3_planar.yaml", "rsur_spatial.yaml"]
SLOW_LINKAGE = ["bricard.yaml"]  # about 5 s to derive per example

FAST = dict(deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))


def examples(default: int, slow: int):
    """Hypothesis settings: ``default`` examples in the default run, ``slow`` under ``-m slow``."""
    return settings(max_examples=default, **FAST), settings(max_examples=slow, **FAST)


def read(name: str) -> dict:
    return yaml.load((CONFIGS / name).read_text(), Loader=CaseLoader)


DOCUMENTS = {name: read(name) for name in REGISTERED + LINKAGE + SLOW_LINKAGE}

# --------------------------------------------------------------------------- paths


def path_text(path: tuple) -> str:
    """("mechanism", "links", 1, "mass") -> "mechanism.links[1].mass"."""
    text = ""
    for key in path:
        text += f"[{key}]" if isinstance(key, int) else (f".{key}" if text else str(key))
    return text


def nodes(doc, path: tuple = ()) -> list[tuple]:
    """Every path in a document, containers and leaves."""
    out = [path] if path else []
    if isinstance(doc, dict):
        for key, value in doc.items():
            out += nodes(value, path + (key,))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            out += nodes(value, path + (i,))
    return out


def get(doc, path: tuple):
    for key in path:
        doc = doc[key]
    return doc


def put(doc, path: tuple, value) -> None:
    get(doc, path[:-1])[path[-1]] = value


# --------------------------------------------------------------------------- what must be rejected

#: quantities that are positive by their physics or numerics (a regex on the path text)
POSITIVE = re.compile(
    r"^(simulation\.(t_end|rtol|atol|step|max_step|first_step|max_phi|min_step|max_events|max_steps)"
    r"|output\.dt|initial\.(tol|max_iter)|formulation\.max_condition"
    r"|stabilization\.(d|w|Lambda|K|k|eps|c|projection_tol|projection_max_iter|ggl_tol|minimal_\w+)(\[\d+\])?)$")

#: quantities that may be zero but not negative (a massless link)
NONNEGATIVE = re.compile(r"^mechanism\.links\[\d+\]\.mass$")

#: gains: a positive number, or a list of them, one per constraint
GAINS = re.compile(r"^stabilization\.(d|w|Lambda|K|k)$")

#: keys in s, which take a time written with its unit ("1e-3 s" is 0.001 s)
TIMES = re.compile(r"^(simulation\.(t_end|step|max_step|first_step|min_step)|output\.dt)$")

#: keys whose mapping takes names the case chooses (a new name is not an unknown key)
FREE_NAMES = re.compile(r"^mechanism\.parameters$")


def sign_parameters(doc: dict) -> tuple[set[str], set[str]]:
    """Parameter paths that must be > 0 (a registered mechanism's strictly positive ones)
    and >= 0 (a linkage parameter that is some link's mass: zero is a massless link)."""
    mech = doc["mechanism"]
    if "name" in mech:
        return {f"mechanism.parameters.{p.name}" for p in light_mechanism(mech["name"]).parameters
                if p.strictly_positive}, set()
    masses = {str(row.get("mass")) for row in mech.get("links") or [] if isinstance(row, dict)}
    return set(), {f"mechanism.parameters.{name}" for name in (mech.get("parameters") or {}) if name in masses}


def must_reject(doc: dict, kind: str, path: tuple, value) -> bool:
    """Whether the mutation ``kind`` of ``path`` (to ``value``) makes the case meaningless."""
    text = path_text(path)
    linkage = "name" not in doc["mechanism"]
    number = isinstance(value, float)
    if kind == "unknown key":
        return not (linkage and FREE_NAMES.match(path_text(path[:-1])))
    if number and math.isnan(value):
        return True
    if number and math.isinf(value):
        return not re.match(r"^loads\.\w+\.window\[\d\]$", text)
    positive_names, nonnegative_names = sign_parameters(doc)
    positive = POSITIVE.match(text) or text in positive_names
    nonnegative = NONNEGATIVE.match(text) or text in nonnegative_names
    if (kind in ("negative", "zero") and positive) or (kind == "negative" and nonnegative):
        return True
    if kind == "wrong type" and value == "1e-3 s" and TIMES.match(text):
        return False  # a time written with its unit
    if kind == "wrong type" and GAINS.match(text) and value == [1, 2]:
        return False  # one gain per constraint (valid where there are two)
    return kind == "wrong type" and positive


def names_the_key(problems: list[str], path: tuple, kind: str) -> bool:
    """Some problem names the mutated key, or (for a table row, a parameter of a linkage
    used in its expressions, or a deleted list entry) the table or section it belongs to."""
    text = " ".join(problems)
    prefixes = [path_text(path[:n]) for n in range(len(path), 0, -1)]
    if len(path) > 1:
        prefixes = prefixes[:-1]  # more than the section
    if any(re.search(re.escape(p) + r"(?![\w])", text) for p in prefixes):
        return True
    if path[0] in ("mechanism", "initial") and any(p.startswith("mechanism: cannot be assembled") for p in problems):
        return True  # geometry that does not close: the message gives the residual of every cut joint
    if path[:2] == ("mechanism", "parameters"):
        # a linkage's parameter is used in its tables; one that breaks the geometry is
        # reported where it is used, or as the mechanism that cannot be assembled
        return re.search(rf"\b{path[0]}[.:\[]", text) is not None
    if path[:2] in (("mechanism", "links"), ("mechanism", "couplings")) and \
            re.search(r"\b(initial\.\w+|mechanism\.drive)", text):
        return True  # a renamed or retyped joint has other joint variables than the keys that name the old ones
    if kind == "delete" and path[0] in ("mechanism", "initial"):
        # a deleted link, coupling or drive changes the joint variables: the keys that name
        # the old ones are reported
        return re.search(r"\b(mechanism|initial)[.:\[]", text) is not None
    return False


# --------------------------------------------------------------------------- mutations

BAD_VALUES = {
    "wrong type": st.sampled_from(["text", True, [1, 2], {"a": 1}, "1e-3 s"]),
    "nan": st.just(math.nan),
    "inf": st.sampled_from([math.inf, -math.inf]),
    "negative": st.sampled_from([-1.0, -1e-300, -1e6]),
    "zero": st.sampled_from([0, 0.0]),
    "huge": st.sampled_from([1e308, 10**400, 1e30]),
    "empty": st.sampled_from(["", [], {}, None]),
}


#: overrides that make each CLI example quick (python backend: no kernel compilation)
QUICK = ["simulation.t_end=0.02", "output.dt=0.01", "simulation.backend=python"]


@st.composite
def mutated(draw, names: list[str], quick: bool = False):
    """(document, kind, path, value): one shipped config (``quick``: made quick to run) with
    one place mutated."""
    name = draw(st.sampled_from(names))
    doc = copy.deepcopy(DOCUMENTS[name])
    if quick:
        apply_overrides(doc, QUICK)
    paths = nodes(doc)
    kind = draw(st.sampled_from([*BAD_VALUES, "delete", "unknown key", "row"]))
    if kind == "unknown key":
        mappings = [()] + [p for p in paths if isinstance(get(doc, p), dict)]
        path = draw(st.sampled_from(mappings))
        get(doc, path)["zz_unknown"] = 1.0
        return doc, kind, path + ("zz_unknown",), 1.0
    if kind == "row":
        rows = [p for p in paths if len(p) == 3 and p[:2] in (("mechanism", "links"), ("mechanism", "couplings"))]
        if not rows:
            kind = "wrong type"
        else:
            path = draw(st.sampled_from(rows))
            row = get(doc, path)
            broken = draw(st.sampled_from(["truncate", "duplicate", "scramble", "string"]))
            if broken == "truncate":
                put(doc, path, row[:-1] if isinstance(row, list) else {k: v for k, v in row.items()
                                                                       if k not in ("joints", "couple")})
            elif broken == "duplicate":
                get(doc, path[:-1]).append(copy.deepcopy(row))
                path = path[:-1] + (len(get(doc, path[:-1])) - 1,)
            elif broken == "scramble":
                put(doc, path, list(reversed(row)) if isinstance(row, list) else [row])
            else:
                put(doc, path, "R R R")
            return doc, f"row {broken}", path, None
    if kind == "delete":
        path = draw(st.sampled_from(paths))
        parent = get(doc, path[:-1])
        del parent[path[-1]]
        return doc, kind, path, None
    leaves = [p for p in paths if not isinstance(get(doc, p), (dict, list)) or kind == "empty"]
    path = draw(st.sampled_from(leaves))
    value = draw(BAD_VALUES[kind])
    put(doc, path, copy.deepcopy(value))
    return doc, kind, path, value


def check_validation(doc: dict, kind: str, path: tuple, value) -> None:
    """The property: valid (and not meaningless), or a CaseError naming the key."""
    before = copy.deepcopy(doc)
    try:
        validate_case(doc)
    except CaseError as exc:
        assert exc.problems, (kind, path_text(path))
        assert names_the_key(exc.problems, path, kind), (kind, path_text(path), value, exc.problems)
        return
    assert not must_reject(before, kind, path, value), \
        f"accepted: {kind} at {path_text(path)} = {value!r}"


default_profile, slow_profile = examples(default=300, slow=5000)


@default_profile
@given(mutated(REGISTERED))
def test_mutated_registered_cases_are_valid_or_name_the_key(case):
    check_validation(*case)


@settings(max_examples=100, **FAST)
@given(mutated(LINKAGE))
def test_mutated_link_coupling_cases_are_valid_or_name_the_key(case):
    check_validation(*case)


@pytest.mark.slow
@slow_profile
@given(mutated(REGISTERED + LINKAGE))
def test_mutated_cases_long_profile(case):
    check_validation(*case)


@pytest.mark.slow
@settings(max_examples=40, **FAST)
@given(mutated(SLOW_LINKAGE))
def test_mutated_bricard_cases(case):
    check_validation(*case)


# --------------------------------------------------------------------------- --set

SET_PATHS = st.one_of(
    st.sampled_from(sorted(SETTABLE)),
    st.sampled_from(["simulation.tend", "simulaton.t_end", "stabilization", "mechanism.parameters.zz",
                     "loads.zz", "initial.q.zz", "initial.q", "output", "simulation.t_end.x", "", ".", "a..b",
                     "mechanism.name.x", "mechanism.links.0"]),
    st.text(alphabet="abcdefghijklmnopqrstuvwxyz_.", min_size=1, max_size=20),
)
SET_VALUES = st.one_of(
    st.sampled_from(["", "-1", "0", ".nan", ".inf", "-.inf", "1e999", "abc", "[1, 2]", "{a: 1}", "null", "true",
                     "[", "{", "'", "1e-300", "RK4", "baumgarte", "10", "0.5"]),
    st.text(max_size=10),
)


@settings(max_examples=150, **FAST)
@given(st.sampled_from(REGISTERED + LINKAGE[:3]), st.lists(st.tuples(SET_PATHS, SET_VALUES), min_size=1, max_size=3),
       st.booleans())
def test_random_set_overrides_are_valid_or_name_the_key(name, pairs, with_equals):
    doc = copy.deepcopy(DOCUMENTS[name])
    items = [f"{p}={v}" if with_equals else p for p, v in pairs]
    try:
        validate_case(apply_overrides(doc, items))
    except CaseError as exc:
        text = "\n".join(exc.problems)
        assert any(f"--set {p.strip()}" in text or f"--set {i!r}" in text
                   or names_the_key(exc.problems, tuple(p.strip().split(".")), "set")
                   for p, i in zip((p for p, _ in pairs), items)), (items, exc.problems)
        return
    for path, value in pairs:
        if value in (".nan", ".inf", "-.inf", "1e999") and path in SETTABLE and with_equals:
            pytest.fail(f"accepted --set {path}={value}")


# --------------------------------------------------------------------------- the command line

def run_cli(tmp_path, doc: dict) -> object:
    path = tmp_path / "case.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return invoke("run", path, "-o", tmp_path / "out.h5", "--quiet")


@settings(max_examples=25, **FAST)
@given(mutated(["pendulum.yaml", "quick_return.yaml", "fourbar.yaml", "fourbar_gravity.yaml"], quick=True))
def test_mutated_cases_through_the_cli_run_or_exit_2_naming_the_key(tmp_path_factory, case):
    check_cli(tmp_path_factory, *case)


@pytest.mark.slow
@settings(max_examples=400, **FAST)
@given(mutated(REGISTERED + LINKAGE, quick=True))
def test_mutated_cases_through_the_cli_long_profile(tmp_path_factory, case):
    check_cli(tmp_path_factory, *case)


def check_cli(tmp_path_factory, doc: dict, kind: str, path: tuple, value) -> None:
    """The property through ``csim run``: exit 0 or 1 with its message, or exit 2 naming the key."""
    before = copy.deepcopy(doc)
    try:
        yaml.safe_dump(doc)
    except yaml.YAMLError:
        return  # not writable as YAML (nothing a user could type)
    result = run_cli(tmp_path_factory.mktemp("fuzz"), doc)
    assert result.exception is None or isinstance(result.exception, SystemExit), (kind, path, result.exc_info)
    assert "Traceback" not in result.output
    if result.exit_code == 2:
        assert "csim: error" in result.output
        problems = [line.strip() for line in result.output.splitlines()]
        assert names_the_key(problems, path, kind) or "--set" in result.output, (kind, path_text(path), result.output)
    else:
        assert result.exit_code in (0, 1), result.output
        assert not must_reject(before, kind, path, value), f"ran: {kind} at {path_text(path)} = {value!r}"
        if result.exit_code == 1:
            assert "csim: simulation failed:" in result.output


# --------------------------------------------------------------------------- issue 24: bounded work
# Every input below returns within BOUND_S with a value or csim's own error (exit 0/1/2 at
# the command line), whatever hypothesis draws: the size bounds are properties.

import time  # noqa: E402

from csim.errors import ResultFileError  # noqa: E402
from csim.linkage.expressions import parse_expression  # noqa: E402
from csim.linkage.forces import FORCE_KINDS  # noqa: E402

#: the longest one validation may take on a loaded machine (a hang is minutes)
BOUND_S = 5.0

#: pieces of expressions: names of the four-bar's parameters, functions, huge and tiny numbers
TOKENS = st.sampled_from(["9", "99", "999999999", "0", "0.5", "1e308", "1e-308", "a", "b", "m1", "t", "x", "pi",
                          "deg", "sin(", "exp(", "sqrt(", "atan2(", ",", "(", ")", "^", "*", "/", "+", "-", "^-",
                          "q_crank", "q_crank_dot", " "])
EXPRESSIONS = st.one_of(st.lists(TOKENS, min_size=1, max_size=40).map("".join),
                        st.integers(1, 6).map(lambda n: "(" * n + "9" + "^99)" * n),
                        st.text(max_size=30))


def _timed(call):
    start = time.monotonic()
    value = call()
    assert time.monotonic() - start < BOUND_S, f"took {time.monotonic() - start:.1f} s"
    return value


@settings(max_examples=300, **FAST)
@given(EXPRESSIONS)
def test_any_expression_is_parsed_or_refused_within_the_bound(text):
    import sympy as sp

    symbols = {name: sp.Symbol(name, real=True) for name in ("a", "b", "m1")}
    problems: list[str] = []
    expr = _timed(lambda: parse_expression("k", text, symbols, problems, {s: 0.3 for s in symbols.values()}))
    assert (expr is None) == bool(problems), (text, problems)
    assert all(p.startswith("k: got ") for p in problems)


def _element_values():
    point = st.one_of(st.sampled_from(["A", "B", "C", "D", "Z"]), st.lists(EXPRESSIONS, min_size=3, max_size=3))
    link = st.sampled_from(["ground", "crank", "coupler", "rocker", 0, 1, 2, 9, "nolink", ["crank"], None])
    return st.one_of(EXPRESSIONS, point, link, st.lists(st.tuples(link, point).map(list), max_size=3),
                     st.sampled_from([None, True, [], {}, float("nan"), 10**400, "crank", "q_B", "C_x", "global",
                                      "link", "positive", [0, 0, 1], [1, 0, 0], [0, 0, 0], [-1, 1]]))


@st.composite
def force_elements(draw):
    """A list of force-element rows: known and unknown types, each key of the type (and others)
    with a value drawn from names, points, directions, expressions and junk."""
    rows = []
    for n in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from([*FORCE_KINDS, "damper", ["actuator"], None, 3]))
        keys = FORCE_KINDS[kind].keys if isinstance(kind, str) and kind in FORCE_KINDS else ("joint", "value")
        row = {"name": draw(st.sampled_from([f"e{n}", "e0", "1x", "", None])), "type": kind}
        for key in draw(st.lists(st.sampled_from([*keys, "bogus"]), max_size=5, unique=True)):
            row[key] = draw(_element_values())
        rows.append(row)
    return rows


@settings(max_examples=60, **FAST)
@given(force_elements())
def test_any_force_element_is_built_or_refused_naming_its_row(rows):
    doc = copy.deepcopy(DOCUMENTS["fourbar_gravity.yaml"])
    doc["mechanism"]["forces"] = rows
    try:
        _timed(lambda: validate_case(doc))
    except CaseError as exc:
        assert all(p.startswith(("mechanism.forces", "mechanism.parameters", "initial", "mechanism.links"))
                   for p in exc.problems), exc.problems


SWEEP_SPECS = st.one_of(
    st.tuples(st.sampled_from(["lin", "log", "x"]), st.lists(st.sampled_from(["0", "1", "-1", "1e-4", "1e999", "nan",
                                                                             "10", "10000000", "a", ""]),
                                                            max_size=4)).map(lambda t: t[0] + ":" + ":".join(t[1])),
    st.lists(st.sampled_from(["1", "2.5", "none", "[1, 2]", "{a: 1}", "", "&a [*a]", "*b", "1e999"]), min_size=1,
             max_size=5).map(",".join),
    st.text(max_size=30),
)


@settings(max_examples=200, **FAST)
@given(st.sampled_from(["stabilization.w", "simulation.step", "", "a.b", "x"]), SWEEP_SPECS, st.booleans())
def test_any_sweep_values_are_read_or_refused_naming_the_option(key, spec, with_equals):
    from csim.study import parse_variation

    text = f"{key}={spec}" if with_equals else spec
    try:
        variation = _timed(lambda: parse_variation(text))
    except CaseError as exc:
        assert all(p.startswith("--vary") for p in exc.problems), exc.problems
        return
    assert variation.values or variation.bounds


MANIFEST_VALUES = st.one_of(st.sampled_from([None, 0, -1, 1e-9, 5, "success", "failed", "compiled", [], {}, [1, 2],
                                             {"min": 1, "max": 0}, {"max": -1}, {"min": 1e9}, {"name": "x", "t": 1},
                                             float("nan"), True]),
                            st.text(max_size=8))


@st.composite
def manifests(draw):
    """A batch manifest of a few entries on the pendulum: keys and expectations drawn."""
    from csim.batch.expectations import EXPECTATIONS

    cases = []
    for n in range(draw(st.integers(0, 2))):
        entry = {"name": draw(st.sampled_from([f"c{n}", "c0", "", None, 3])),
                 "case": draw(st.sampled_from([str(CONFIGS / "pendulum.yaml"), "missing.yaml", None, 1]))}
        if draw(st.booleans()):
            entry["set"] = draw(st.sampled_from([["simulation.t_end=0.01"], "x", [1], ["bogus=1"]]))
        entry["expect"] = {k: draw(MANIFEST_VALUES) for k in draw(st.lists(st.sampled_from([*EXPECTATIONS, "bogus"]),
                                                                            max_size=3, unique=True))}
        if draw(st.booleans()):
            entry[draw(st.sampled_from(["bogus", "only"]))] = draw(MANIFEST_VALUES)
        cases.append(entry)
    return draw(st.sampled_from([{"cases": cases}, {"cases": cases, "defaults": {"expect": {"wall_time": -1}}},
                                 {"cases": cases, "bogus": 1}, cases, {"cases": "x"}]))


@settings(max_examples=60, **FAST)
@given(manifests())
def test_any_manifest_is_loaded_or_refused_naming_the_key(tmp_path_factory, doc):
    from csim.batch import load_manifest

    path = tmp_path_factory.mktemp("manifest") / "m.yaml"
    path.write_text(yaml.safe_dump(doc))
    try:
        loaded = _timed(lambda: load_manifest(path))
    except CaseError as exc:
        assert exc.problems and all(p for p in exc.problems)
        return
    assert all(entry.name for entry in loaded.entries)


@pytest.fixture(scope="module")
def stored_result(tmp_path_factory):
    """A small result file of the pendulum (Python path), to corrupt."""
    out = tmp_path_factory.mktemp("stored") / "r.h5"
    result = invoke("run", CONFIGS / "pendulum.yaml", "-o", out, "-q", "--set", "simulation.t_end=0.05",
                    "--set", "simulation.backend=python")
    assert result.exit_code == 0, result.output
    return out.read_bytes()


CORRUPTIONS = st.sampled_from(["delete", "string", "number", "empty", "matrix", "huge case", "bomb case",
                               "kind sweep", "kind comparison"])


@settings(max_examples=60, **FAST)
@given(st.sampled_from(["t", "q", "qd", "phi", "coordinate_names", "case", "status", "mechanism", "kind",
                        "load_names", "event_times", "energy"]), CORRUPTIONS)
def test_any_corrupted_result_file_is_read_or_refused(tmp_path_factory, stored_result, name, how):
    import h5py
    import numpy as np

    from csim.io.hdf5 import read_result
    from csim.plot.source import run_data

    path = tmp_path_factory.mktemp("corrupt") / "r.h5"
    path.write_bytes(stored_result)
    with h5py.File(path, "r+") as fh:
        where = fh.attrs if name in fh.attrs or name in ("kind", "case") else fh
        if name in where:
            del where[name]
        if how != "delete":
            value = {"string": "x", "number": 3.5, "empty": np.zeros(0), "matrix": np.ones((2, 2)),
                     "huge case": "mechanism: {name: pendulum, parameters: {m: '9^999999999'}}",
                     "bomb case": "a: &a [1,1,1,1,1,1,1,1,1]\nb: &b [" + ",".join(["*a"] * 9) + "]\nc: &c ["
                     + ",".join(["*b"] * 9) + "]\nd: &d [" + ",".join(["*c"] * 9) + "]\ne: [" + ",".join(["*d"] * 9)
                     + "]\n", "kind sweep": "sweep", "kind comparison": "comparison"}[how]
            if how.startswith("kind"):
                fh.attrs["kind"] = value
            elif where is fh:
                fh.create_dataset(name, data=value)
            else:
                where[name] = value
    try:
        result = _timed(lambda: read_result(path))
        _timed(lambda: run_data(result, path))
    except (ResultFileError, CaseError):
        return
