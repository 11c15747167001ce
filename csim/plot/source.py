"""What a figure needs from a result file: the run, its mechanism, parameters and units.

A result file (``csim run``) holds one run; a comparison file (``csim compare``) one run
per method plus a reference run. Each run stores its validated case as YAML, from which
the mechanism definition (drawing, declared figures, units) and the parameter values are
rebuilt here; no model code is generated.

The stored case is read like a case file (its size, its YAML and its expressions bounded
by :mod:`csim.case`), and the rebuild of its mechanism is bounded in time: a file gets
:data:`REBUILD_LIMIT_S` seconds for all its runs together (runs of one mechanism share one
rebuild). Past that, the runs are plotted from their samples without the mechanism (no
drawing, no animation), and the figures left out say why: a file cannot hold ``csim plot``
or ``csim animate`` longer, however it was made.
"""
from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import h5py
import numpy as np
import sympy as sp
import yaml

from csim.case import parse_yaml, validate_case
from csim.errors import CacheError, CsimError, ResultFileError
from csim.io.hdf5 import COMPARISON_KIND, ComparisonFile, read_comparison, read_result
from csim.mechanisms import MECHANISMS, get_mechanism
from csim.model.definition import MechanismDefinition
from csim.model.light import full_definition
from csim.result import Result
from csim.study.sweep_file import SWEEP_KIND

#: kinds of result file
RUN, COMPARISON, SWEEP = "run", "comparison", "sweep"

#: the longest the mechanisms of one file's stored cases may take to rebuild [s]: a shipped
#: link-coupling case takes up to about 6 s (configs/iftomm/a02_n_four_bar_40.yaml), a
#: crafted table of 99 links more than ten minutes
REBUILD_LIMIT_S = 30.0


class _Deadline(BaseException):
    """The rebuild of a stored case ran out of time (a BaseException: no ``except Exception``
    on the way takes it for the case's own error)."""


@contextmanager
def _deadline(seconds: float) -> Iterator[None]:
    """Raise :class:`_Deadline` in the block after ``seconds`` (and every 0.5 s after that,
    should one be swallowed); in the main thread with SIGALRM only (elsewhere: unbounded).

    One raised where Python cannot pass it on (in a weakref callback or a ``__del__``) is
    swallowed quietly: Python would print it as "Exception ignored in ..." with a traceback
    (seen in a test session, 2026-11-27), and the next one ends the block all the same."""
    if seconds <= 0:
        raise _Deadline
    if not hasattr(signal, "setitimer") or threading.current_thread() is not threading.main_thread():
        yield
        return

    # False once the block is left: a tick that lands in the cleanup below raises nothing (a _Deadline
    # raised there skipped the rest of it and left this handler, its 0.5 s timer and the hook for good)
    armed = [True]

    def expired(signum, frame):
        if armed[0]:
            raise _Deadline

    hook = sys.unraisablehook

    def quiet(unraisable):
        if not isinstance(unraisable.exc_value, _Deadline):
            hook(unraisable)

    previous, outer = None, (0.0, 0.0)
    start = time.monotonic()
    try:
        previous = signal.signal(signal.SIGALRM, expired)
        sys.unraisablehook = quiet
        outer = signal.setitimer(signal.ITIMER_REAL, seconds, 0.5)  # a caller's own timer, restored after
        yield
    finally:
        armed[0] = False  # no _Deadline from here on
        signal.setitimer(signal.ITIMER_REAL, 0)
        if previous is not None:
            signal.signal(signal.SIGALRM, previous)
        sys.unraisablehook = hook
        if outer[0] > 0:  # what was left of it, less the time spent here (at least a moment)
            signal.setitimer(signal.ITIMER_REAL, max(outer[0] - (time.monotonic() - start), 1e-3), outer[1])


@dataclass
class Rebuilds:
    """The mechanisms rebuilt from one file's stored cases, and the time left for more.

    Attributes
    ----------
    left : float
        Seconds left for rebuilding (:data:`REBUILD_LIMIT_S` at first).
    done : dict
        YAML of a case's ``mechanism`` and ``initial`` sections -> (definition, parameters).
    expired : str
        Why no further case is rebuilt ("" while there is time).
    """

    left: float = field(default_factory=lambda: REBUILD_LIMIT_S)
    done: dict = field(default_factory=dict)
    expired: str = ""


def file_kind(path: str | Path) -> str:
    """``"run"`` for a ``csim run`` file, ``"comparison"`` for a ``csim compare`` file,
    ``"sweep"`` for a ``csim sweep`` file.

    Raises
    ------
    ResultFileError
        When ``path`` is missing or not a readable HDF5 file.
    """
    path = Path(path)
    if not path.is_file():
        raise ResultFileError(f"{path}: no such result file")
    try:
        with h5py.File(path, "r") as fh:
            kind = fh.attrs.get("kind", "")
    except OSError as exc:
        raise ResultFileError(f"{path}: not a readable HDF5 file ({exc})") from None
    kind = kind.decode() if isinstance(kind, bytes) else str(kind)
    if kind == SWEEP_KIND:
        return SWEEP
    return COMPARISON if kind == COMPARISON_KIND else RUN


@dataclass
class RunData:
    """One run and what is needed to label and draw it.

    Attributes
    ----------
    result : Result
    path : Path
        The file it was read from.
    group : str
        Its group in a comparison file (``""`` for a single-run file).
    definition : MechanismDefinition or None
        The mechanism (None when the file names a mechanism this csim does not know).
    parameters : dict of str -> float
        Parameter values of the run (SI units).
    case : dict
        The run's case as stored in the file (empty when it cannot be read).
    unavailable : str
        Why ``definition`` is None although the file names a mechanism ("" otherwise).
    coordinate_units : list of str, length m
    constraint_units : list of str, length r
        Unit of each constraint function (``""`` for a dimensionless one).
    """

    result: Result
    path: Path
    group: str = ""
    definition: MechanismDefinition | None = None
    parameters: dict[str, float] = field(default_factory=dict)
    case: dict = field(default_factory=dict)
    unavailable: str = ""
    coordinate_units: list[str] = field(default_factory=list)
    constraint_units: list[str] = field(default_factory=list)

    @property
    def method(self) -> str:
        """The stabilization method of the run (``""`` when unknown)."""
        return str(self.case.get("stabilization", {}).get("method", ""))

    def describe(self) -> str:
        """One line naming the run: mechanism, method, integrator and tolerance, status."""
        parts = [self.result.mechanism]
        sim = self.case.get("simulation", {})
        if self.result.run_kind == "kinematic":  # prescribed motion: no integrator, no stabilizer
            parts.append("kinematic analysis of the prescribed motion")
            sim = {}
        elif self.method:
            parts.append(f"stabilization: {self.method}")
        if sim.get("integrator"):
            integ = sim["integrator"]
            if integ == "RK4":
                parts.append(f"RK4, h = {sim.get('step', float('nan')):g} s")
            elif sim.get("rtol") == sim.get("atol"):
                parts.append(f"{integ}, rtol = atol = {sim.get('rtol', float('nan')):g}")
            else:
                parts.append(f"{integ}, rtol = {sim.get('rtol', float('nan')):g}, "
                             f"atol = {sim.get('atol', float('nan')):g}")
        text = ", ".join(parts)
        if not self.result.ok:
            message = self.result.message
            text += f" (failed: {message[:60] + '...' if len(message) > 60 else message})"
        return text


def _coordinate_units(path: Path, group: str, m: int, definition: MechanismDefinition | None) -> list[str]:
    try:
        with h5py.File(path, "r") as fh:
            units = fh[group or "/"]["q"].attrs.get("units")
        if units is not None and np.ndim(units) == 1 and len(units) == m:
            return [u.decode() if isinstance(u, bytes) else str(u) for u in units]
    except (OSError, KeyError):
        pass
    if definition is not None and len(definition.coordinate_units) == m:
        return list(definition.coordinate_units)
    return [""] * m


def constraint_units(definition: MechanismDefinition, parameters: dict[str, float]) -> list[str]:
    """Unit of each constraint function, found by dimensional analysis.

    For a file without the constraints' units (written before format version 2). Lengths
    (parameters and coordinates in m) are doubled at a generic configuration: a constraint
    that doubles is in m, one that does not change is dimensionless (``1``), one that grows
    by 2^k is in m^k. A constraint that scales otherwise gets ``""`` (unknown).

    Returns
    -------
    list of str, length r
    """
    q_syms, p_syms = definition.coordinates, definition.parameter_symbols
    try:
        f = sp.lambdify([q_syms, p_syms], list(definition.constraints), modules="math")
    except Exception:  # an expression lambdify cannot print: no units rather than no figures
        return [""] * len(definition.constraints)
    par = np.array([float(parameters.get(p.name, p.default)) for p in definition.parameters])
    is_length_par = np.array([p.unit == "m" for p in definition.parameters], dtype=bool)
    is_length_q = np.array([u == "m" for u in definition.coordinate_units], dtype=bool)
    units = []
    for i in range(len(definition.constraints)):
        unit = ""
        for trial in range(3):
            q = 0.37 + 0.29 * np.arange(len(q_syms)) + 0.11 * trial
            try:
                base = f(list(q), list(par))[i]
                scaled = f(list(np.where(is_length_q, 2 * q, q)), list(np.where(is_length_par, 2 * par, par)))[i]
            except (ValueError, ZeroDivisionError, OverflowError, TypeError):
                continue
            if not (math.isfinite(base) and math.isfinite(scaled)) or abs(base) < 1e-9:
                continue
            ratio = scaled / base
            k = math.log2(ratio) if ratio > 0 else float("nan")
            if math.isfinite(k) and abs(k - round(k)) < 1e-9:
                k = round(k)
                unit = "1" if k == 0 else "m" if k == 1 else f"m^{k}"
            break
        units.append(unit)
    return units


def _rebuild(case: dict, rebuilds: Rebuilds) -> tuple[MechanismDefinition, dict[str, float], dict]:
    """Validate a stored case and build its symbolic definition, within the time left.

    Raises
    ------
    CsimError
        The case is not valid for this csim.
    _Deadline
        The time of ``rebuilds`` ran out.
    """
    try:
        key = yaml.safe_dump([case.get("mechanism"), case.get("initial")], sort_keys=True)
    except yaml.YAMLError:
        key = None
    if key is not None and key in rebuilds.done:  # another run of the same mechanism
        definition, parameters = rebuilds.done[key]
        return definition, parameters, case
    start = time.monotonic()
    try:
        with _deadline(rebuilds.left):
            validated = validate_case(case, source="case stored in the result file")
            # figures evaluate the drawing and the constraints: the symbolic definition
            definition = full_definition(validated.mechanism)
    finally:
        rebuilds.left -= time.monotonic() - start
    if key is not None:
        rebuilds.done[key] = (definition, validated.parameters)
    return definition, validated.parameters, validated.data


def _definition(result: Result, rebuilds: Rebuilds) -> tuple[MechanismDefinition | None, dict[str, float], dict,
                                                             str]:
    """The run's mechanism and parameters, from the case stored in the file, and why there
    is no mechanism when the time for rebuilding ran out."""
    case: dict = {}
    try:
        data = parse_yaml(result.case_yaml, "case") if result.case_yaml else None
        case = data if isinstance(data, dict) else {}
    except CsimError:
        case = {}
    if rebuilds.expired:
        return None, {}, case, rebuilds.expired
    try:  # a registered mechanism, or a link-coupling description (rebuilt from its tables)
        try:
            return (*_rebuild(case, rebuilds), "")
        except CacheError:  # a cached linkage disagreed with its plan, which is removed: built again once
            return (*_rebuild(case, rebuilds), "")
    except _Deadline:
        rebuilds.expired = (f"rebuilding the mechanism from the case stored in the file took over "
                            f"{REBUILD_LIMIT_S:g} s, the limit of csim plot and csim animate (a link-coupling "
                            f"table too large, or a crafted file)")
        return None, {}, case, rebuilds.expired
    except CsimError:  # a case from another csim version: the mechanism's defaults
        if result.mechanism not in MECHANISMS:
            return None, {}, case, ""
        definition = get_mechanism(result.mechanism)
        given = (case.get("mechanism") or {}).get("parameters") or {}
        params = {p.name: float(given.get(p.name, p.default)) if isinstance(given.get(p.name, p.default),
                                                                           (int, float)) else p.default
                  for p in definition.parameters}
        return definition, params, case, ""


def run_data(result: Result, path: str | Path, group: str = "", rebuilds: Rebuilds | None = None) -> RunData:
    """Wrap a run read from ``path`` (group ``group`` of a comparison file); ``rebuilds``:
    the rebuilds of the file's other runs and the time left (a new :class:`Rebuilds`)."""
    path = Path(path)
    definition, parameters, case, unavailable = _definition(result, rebuilds or Rebuilds())
    m, r = result.q.shape[1], result.phi.shape[1]
    c_units = list(result.constraint_units)  # the file's (a link-coupling mechanism's from its equations)
    if len(c_units) != r or not any(c_units):
        c_units = [""] * r
        if definition is not None and len(definition.constraints) == r:
            c_units = constraint_units(definition, parameters)
    return RunData(result=result, path=path, group=group, definition=definition, parameters=parameters, case=case,
                   unavailable=unavailable, coordinate_units=_coordinate_units(path, group, m, definition),
                   constraint_units=c_units)


def load_run(path: str | Path, group: str | None = None) -> RunData:
    """Read one run: a single-run file, or the group ``group`` of a comparison file.

    Raises
    ------
    ResultFileError
        Missing or unreadable file, missing group, or a comparison file without ``group``.
    """
    group = group or ""
    result = read_result(path, group=group or "/")
    return run_data(result, path, group.strip("/"))


@dataclass
class ComparisonData:
    """A comparison file: its tables and settings, and every run in it.

    Attributes
    ----------
    file : ComparisonFile
        Tables (``summary``, ``work_precision``) and root attributes.
    runs : dict of str -> RunData
        Method -> its run (the file's method groups, in the order compared).
    reference : RunData or None
    """

    file: ComparisonFile
    runs: dict[str, RunData]
    reference: RunData | None = None

    @property
    def path(self) -> Path:
        return self.file.path

    @property
    def tolerances(self) -> list[float]:
        """The tolerances of the study (empty without one)."""
        return [float(t) for t in np.atleast_1d(self.file.attrs.get("tolerances", []))]

    def describe(self) -> str:
        """One line: mechanism, integrator, and the setting of the runs in the method groups
        (the case's own, or the tightest of a tolerance study)."""
        a = self.file.attrs
        parts = [str(a.get("mechanism", "")), str(a.get("integrator", ""))]
        if self.tolerances:
            kind = str(a.get("tolerance_kind", "rtol=atol")).replace("=", " = ")
            parts.append(f"{kind} = {min(self.tolerances):g}")
        elif a.get("setting"):
            parts.append(str(a["setting"]))
        return ", ".join(p for p in parts if p)


def load_comparison(path: str | Path) -> ComparisonData:
    """Read a comparison file: its tables and the run of every method and the reference.

    Raises
    ------
    ResultFileError
        Missing or unreadable file, or not a comparison file.
    """
    cmp = read_comparison(path)
    rebuilds = Rebuilds()  # one time limit for the file's runs; one rebuild per mechanism
    runs = {m: run_data(read_result(cmp.path, group=m), cmp.path, m, rebuilds) for m in cmp.methods}
    reference = None
    if cmp.has_reference:
        reference = run_data(read_result(cmp.path, group="reference"), cmp.path, "reference", rebuilds)
    return ComparisonData(file=cmp, runs=runs, reference=reference)
