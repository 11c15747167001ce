"""What a batch entry expects of its run: one class per kind, registered by name.

A kind reads its spec from the manifest (:meth:`Expectation.parse`, which appends a problem
naming the key path, the value and what was expected, and returns None when the spec is
bad) and checks a finished run (:meth:`Expectation.check`, which returns an
:class:`Outcome`: passed or not, the measured value and the bound). The registry
:data:`EXPECTATIONS` maps each name to its class; :func:`parse_expectations` reads a whole
``expect:`` mapping.

Kinds (the README's "CI batch runs" lists them with examples):

``status``
    ``success`` or ``failed``, or ``{expected: failed, message: TEXT}``: the run's status,
    and a text its message contains.
``max_phi``, ``max_phi_dot``
    max |Phi_i| and max |(Phi_q qd)_i| over the output samples [unit of Phi, per s];
    a number is an upper bound; ``{max: B, min: A, window: [t0, t1]}``.
``energy_error``
    the relative energy-balance error of the run summary
    (:attr:`csim.result.Result.energy_balance`; in J for a mechanism at rest).
``value``
    ``{name: q1, t: 10, expected: 106.6, tol: 1e-6, rate: false}``: a coordinate or
    observable (or its rate) at time t, within ``tol``.
``wall_time``, ``final_time``
    the run's wall time [s] and its last sample time [s].
``events``, ``nfev``
    counts: an integer is the exact count, ``{min: A, max: B}`` a range.
``backend``
    ``compiled`` or ``python``: what integrated the run.

Every bounded kind accepts a list of specs (``max_phi: [{max: 1e-5, window: [0, 10]},
{min: 1e-4, window: [90, 100]}]``).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from csim.schema import closest, describe

if TYPE_CHECKING:
    from csim.case import Case
    from csim.result import Result

#: the two statuses of a run
STATUSES = ("success", "failed")
#: the backends that integrate a run
BACKENDS = ("compiled", "interpreted", "python")
#: how close t must lie to an output time [s, relative to max(1, |t|)] to take that sample
SAMPLE_MATCH = 1e-9


@dataclass(frozen=True)
class Outcome:
    """The check of one expectation on one run.

    Attributes
    ----------
    kind : str
        The expectation's name (``"max_phi"``).
    passed : bool
    measured : str
        What the run gave, as text (``"1.21e-07"``).
    expected : str
        The bound, as text (``"<= 1e-10"``).
    note : str
        Where it was measured or why nothing was (``"over t in [0, 10] s"``), or ``""``.
    label : str
        How a report names this expectation: the kind, with a distinguishing detail for
        kinds that may repeat (``"value q1 at t = 10 s"``).
    """

    kind: str
    passed: bool
    measured: str
    expected: str
    note: str = ""
    label: str = ""

    @property
    def message(self) -> str:
        """One line: ``max_phi: measured 1.21e-07, expected <= 1e-10``."""
        text = f"{self.label or self.kind}: measured {self.measured}, expected {self.expected}"
        return f"{text} ({self.note})" if self.note else text


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(float(value))


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


@dataclass(frozen=True)
class Range:
    """Bounds lo <= x <= hi (either may be None: open)."""

    lo: float | None = None
    hi: float | None = None

    def contains(self, x: float) -> bool:
        """Whether x lies within the bounds (False for NaN)."""
        if not math.isfinite(x):
            return False
        return (self.lo is None or x >= self.lo) and (self.hi is None or x <= self.hi)

    def text(self, fmt: str = "g") -> str:
        """``<= 1e-10``, ``>= 3``, ``== 67`` or ``in [a, b]``."""
        lo, hi = (None if v is None else format(v, fmt) for v in (self.lo, self.hi))
        if lo is not None and lo == hi:
            return f"== {lo}"
        if lo is None:
            return f"<= {hi}"
        return f">= {lo}" if hi is None else f"in [{lo}, {hi}]"


class Expectation:
    """One kind of expectation. Subclasses set ``name`` and ``doc`` and implement
    :meth:`parse` and :meth:`check`."""

    name: ClassVar[str]
    doc: ClassVar[str]
    #: whether several specs of this kind may be given as a list
    repeatable: ClassVar[bool] = True

    @classmethod
    def parse(cls, path: str, spec: Any, case: Case, problems: list[str]) -> Expectation | None:
        """Read a spec from the manifest; append a problem and return None when it is bad.

        Parameters
        ----------
        path : str
            The spec's key path in the manifest, for messages (``cases[2].expect.max_phi``).
        spec : object
            The spec as read from YAML.
        case : Case
            The entry's validated case (its mechanism's names, its t_end).
        problems : list of str
            Where problems go.
        """
        raise NotImplementedError

    def check(self, result: Result) -> Outcome:
        """Check a finished run (failed runs included: a run that raised comes as a
        sampleless failed Result)."""
        raise NotImplementedError


#: name -> class of every expectation kind, in the order the README lists them
EXPECTATIONS: dict[str, type[Expectation]] = {}


def register(cls: type[Expectation]) -> type[Expectation]:
    """Class decorator: add an expectation kind to :data:`EXPECTATIONS` under its ``name``."""
    EXPECTATIONS[cls.name] = cls
    return cls


def parse_expectations(path: str, expect: Any, case: Case, problems: list[str]) -> list[Expectation]:
    """Read an ``expect:`` mapping: kind -> spec (or a list of specs).

    Parameters
    ----------
    path : str
        Key path of the mapping (``cases[0].expect``).
    expect : dict
        The mapping, as read from YAML (already checked to be a mapping).
    case : Case
        The entry's validated case.
    problems : list of str
        Where problems go: unknown kinds (listing the valid names) and bad specs.

    Returns
    -------
    list of Expectation
        The valid ones, in the order given.
    """
    found: list[Expectation] = []
    for key, spec in expect.items():
        cls = EXPECTATIONS.get(key)
        if cls is None:
            hint = closest(str(key), EXPECTATIONS)
            extra = f" (did you mean {hint!r}?)" if hint else ""
            problems.append(f"{path}.{key}: unknown expectation{extra}; expected one of {', '.join(EXPECTATIONS)}")
            continue
        specs = spec if isinstance(spec, list) and cls.repeatable else [spec]
        if isinstance(spec, list) and cls.repeatable and not spec:
            problems.append(f"{path}.{key}: got an empty list; expected a spec or a list of specs")
        for j, item in enumerate(specs):
            where = f"{path}.{key}[{j}]" if specs is spec else f"{path}.{key}"
            parsed = cls.parse(where, item, case, problems)
            if parsed is not None:
                found.append(parsed)
    return found


# --------------------------------------------------------------------------- status, backend


@register
class StatusExpectation(Expectation):
    """The run's status, and optionally a text in its message."""

    name = "status"
    doc = "success or failed, or {expected: failed, message: TEXT} (TEXT in the run's message)"
    repeatable = False

    def __init__(self, expected: str, message: str = ""):
        self.expected, self.message = expected, message

    @classmethod
    def parse(cls, path, spec, case, problems):
        what = f"one of {', '.join(STATUSES)}, or a mapping {{expected: failed, message: TEXT}}"
        if isinstance(spec, str):
            spec = {"expected": spec}
        if not isinstance(spec, dict) or set(spec) - {"expected", "message"} or "expected" not in spec:
            problems.append(f"{path}: got {describe(spec)}; expected {what}")
            return None
        if spec["expected"] not in STATUSES:
            problems.append(f"{path}: got {describe(spec['expected'])}; expected {what}")
            return None
        message = spec.get("message", "")
        if not isinstance(message, str):
            problems.append(f"{path}.message: got {describe(message)}; expected a string (text in the run's message)")
            return None
        return cls(spec["expected"], message)

    def check(self, result):
        message = " ".join(result.message.split())
        measured = f"{result.status} ({message[:157] + '...' if len(message) > 160 else message})"
        expected = self.expected + (f", message containing {self.message!r}" if self.message else "")
        passed = result.status == self.expected and self.message in result.message
        return Outcome(self.name, passed, measured, expected)


@register
class BackendExpectation(Expectation):
    """What integrated the run: the compiled kernels or the Python path."""

    name = "backend"
    doc = "compiled or python: what integrated the run (catches a silent fall-back to the Python path)"
    repeatable = False

    def __init__(self, expected: str):
        self.expected = expected

    @classmethod
    def parse(cls, path, spec, case, problems):
        if spec not in BACKENDS:
            problems.append(f"{path}: got {describe(spec)}; expected one of {', '.join(BACKENDS)}")
            return None
        return cls(spec)

    def check(self, result):
        note = f"not compiled because {result.backend_reason}" if result.backend_reason else ""
        return Outcome(self.name, result.backend == self.expected, result.backend, self.expected, note)


# --------------------------------------------------------------------------- bounded quantities


class Bounded(Expectation):
    """A number measured on the run, within bounds: a plain number (``shorthand``: an upper
    bound, or for counts the exact value), or ``{min: A, max: B}`` (and ``window: [t0, t1]``
    where ``windowed``)."""

    #: "max": a plain number is an upper bound; "exact": the exact value (counts)
    shorthand: ClassVar[str] = "max"
    #: whether the values are counts (integers)
    counts: ClassVar[bool] = False
    #: whether ``window: [t0, t1]`` restricts the samples measured
    windowed: ClassVar[bool] = False
    unit: ClassVar[str] = ""
    #: the least value the quantity takes (every bounded kind measures a size, a time or a count)
    least: ClassVar[float] = 0.0

    def __init__(self, bounds: Range, window: tuple[float, float] | None = None):
        self.bounds, self.window = bounds, window

    @classmethod
    def greatest(cls, case: Case) -> float | None:
        """The greatest value the quantity takes in a run of ``case`` (None: no such bound)."""
        return None

    @classmethod
    def reachable(cls, path: str, bounds: Range, case: Case, problems: list[str]) -> bool:
        """Whether some value of the quantity lies within ``bounds``; a problem saying why
        not otherwise (``max_phi: -1``: no run could pass, so the manifest is wrong)."""
        unit = f" {cls.unit}" if cls.unit else ""
        if bounds.hi is not None and bounds.hi < cls.least:
            problems.append(f"{path}: got an upper bound {bounds.hi:g}{unit}; {cls.name} is never below "
                            f"{cls.least:g}{unit}, so no run could pass; expected a bound >= {cls.least:g}")
            return False
        top = cls.greatest(case)
        if top is not None and bounds.lo is not None and bounds.lo > top:
            problems.append(f"{path}: got a lower bound {bounds.lo:g}{unit}; {cls.name} is never above "
                            f"{top:g}{unit} in this case, so no run could pass; expected a bound <= {top:g}")
            return False
        return True

    @classmethod
    def parse(cls, path, spec, case, problems):
        valid = _integer if cls.counts else _number
        kind = "an integer >= 0" if cls.counts else "a number"
        plain = "the exact count" if cls.shorthand == "exact" else "an upper bound"
        keys = ("min", "max", "window") if cls.windowed else ("min", "max")
        what = f"{kind} ({plain}), or a mapping with keys {', '.join(keys)}"
        if valid(spec) and not (cls.counts and spec < 0):
            value = float(spec)
            bounds = Range(value if cls.shorthand == "exact" else None, value)
            return cls(bounds) if cls.reachable(path, bounds, case, problems) else None
        if not isinstance(spec, dict) or not spec or set(spec) - set(keys) or not ({"min", "max"} & set(spec)):
            problems.append(f"{path}: got {describe(spec)}; expected {what}")
            return None
        bad = [k for k in ("min", "max") if k in spec and not valid(spec[k])]
        for k in bad:
            problems.append(f"{path}.{k}: got {describe(spec[k])}; expected {kind}")
        lo, hi = spec.get("min"), spec.get("max")
        if not bad and lo is not None and hi is not None and lo > hi:
            problems.append(f"{path}: got min {lo:g} > max {hi:g}; expected min <= max")
            return None
        window = cls._window(f"{path}.window", spec.get("window"), case, problems) if "window" in spec else None
        if bad or ("window" in spec and window is None):
            return None
        bounds = Range(None if lo is None else float(lo), None if hi is None else float(hi))
        return cls(bounds, window) if cls.reachable(path, bounds, case, problems) else None

    @staticmethod
    def _window(path: str, window: Any, case: Case, problems: list[str]) -> tuple[float, float] | None:
        t_end = case.simulation.t_end
        if not (isinstance(window, list) and len(window) == 2 and all(map(_number, window))
                and 0 <= window[0] < window[1] and window[0] <= t_end):
            problems.append(f"{path}: got {describe(window)}; expected [t0, t1] in s with 0 <= t0 < t1 and "
                            f"t0 <= t_end = {t_end:g} s")
            return None
        return float(window[0]), float(window[1])

    def measure(self, result: Result) -> tuple[float, str]:
        """The measured value, and a note on it (or why it is NaN)."""
        raise NotImplementedError

    def check(self, result):
        value, note = self.measure(result)
        fmt = "d" if self.counts else ".3g"
        measured = "-" if math.isnan(value) else format(int(value) if self.counts else value, fmt)
        unit = f" {self.unit}" if self.unit else ""
        expected = self.bounds.text("g") + unit
        return Outcome(self.name, self.bounds.contains(value), measured + ("" if math.isnan(value) else unit),
                       expected, note, label=self._label())

    def _label(self) -> str:
        return f"{self.name} over t in [{self.window[0]:g}, {self.window[1]:g}] s" if self.window else self.name


class _SampleMaximum(Bounded):
    """max over the output samples (in ``window``) of max_i |x_i|, for an (N, r) series."""

    windowed = True
    series: ClassVar[Callable[[Result], np.ndarray]]

    def measure(self, result):
        values, t = type(self).series(result), result.t
        if self.window is not None:
            values = values[(t >= self.window[0]) & (t <= self.window[1])]
        if values.size == 0:
            return math.nan, "no output samples" + (" in the window" if self.window else "")
        return float(np.max(np.abs(values))), ""


@register
class MaxPhi(_SampleMaximum):
    name = "max_phi"
    doc = "max |Phi_i| over the output samples [unit of Phi]"
    series = staticmethod(lambda r: r.phi)


@register
class MaxPhiDot(_SampleMaximum):
    name = "max_phi_dot"
    doc = "max |(Phi_q qd)_i| over the output samples [unit of Phi / s]"
    series = staticmethod(lambda r: r.phi_dot)


@register
class EnergyError(Bounded):
    name = "energy_error"
    doc = ("max |T + V - T0 - V0 - W| / energy scale, as the run summary reports it (in J when the energy scale "
           "is zero: a mechanism at rest)")

    @classmethod
    def parse(cls, path, spec, case, problems):
        if case.kinematic:
            problems.append(f"{path}: the case is a kinematic analysis (mechanism.drive), which has no forces and "
                            f"no energy balance; expected no energy_error expectation")
            return None
        return super().parse(path, spec, case, problems)

    def measure(self, result):
        value, unit = result.energy_balance
        return value, ("in J: the energy scale is zero" if unit == "J" else "") if result.t.size else "no samples"


@register
class WallTime(Bounded):
    name = "wall_time"
    doc = "the run's wall time [s] (integration and post-processing; parallel runs share the CPU)"
    unit = "s"

    def measure(self, result):
        return float(result.wall_time), f"{result.backend} backend"


@register
class FinalTime(Bounded):
    name = "final_time"
    doc = "the last output time [s]: where a failed run stopped"
    unit = "s"

    @classmethod
    def greatest(cls, case):
        return case.simulation.t_end

    def measure(self, result):
        return (float(result.t[-1]), "") if result.t.size else (math.nan, "no samples")


@register
class Events(Bounded):
    name = "events"
    doc = "the number of located switching events"
    shorthand, counts = "exact", True

    def measure(self, result):
        return float(len(result.event_times)), ""


@register
class Evaluations(Bounded):
    name = "nfev"
    doc = "the number of right-hand-side evaluations"
    shorthand, counts = "exact", True

    def measure(self, result):
        return float(result.nfev), ""


# --------------------------------------------------------------------------- a value at a time


@register
class Value(Expectation):
    """A coordinate or an observable (or its rate) at a time, within a tolerance."""

    name = "value"
    doc = ("{name: q1, t: 10, expected: X, tol: E, rate: false}: a coordinate or observable (rate: true, its rate) "
           "at time t [s], |measured - X| <= E; t between output samples is interpolated (cubic Hermite)")
    _KEYS = ("name", "t", "expected", "tol", "rate")

    def __init__(self, quantity: str, t: float, expected: float, tol: float, rate: bool = False):
        self.quantity, self.t, self.expected, self.tol, self.rate = quantity, t, expected, tol, rate

    @classmethod
    def parse(cls, path, spec, case, problems):
        if not isinstance(spec, dict):
            problems.append(f"{path}: got {describe(spec)}; expected a mapping with keys {', '.join(cls._KEYS)} "
                            f"(rate optional), e.g. {{name: q1, t: 10, expected: 106.6, tol: 1e-6}}")
            return None
        n = len(problems)
        for key in spec:
            if key not in cls._KEYS:
                hint = closest(str(key), cls._KEYS)
                extra = f" (did you mean {hint!r}?)" if hint else ""
                problems.append(f"{path}.{key}: unknown key{extra}; valid keys here: {', '.join(cls._KEYS)}")
        names = [*case.mechanism.coordinate_names, *(ob.name for ob in case.mechanism.observables)]
        name, t, expected, tol = (spec.get(k) for k in ("name", "t", "expected", "tol"))
        t_end = case.simulation.t_end
        checks = [("name", name in names, f"a coordinate or observable of {case.mechanism.name}: {', '.join(names)}"),
                  ("t", _number(t) and 0 <= t <= t_end, f"a time in s with 0 <= t <= t_end = {t_end:g}"),
                  ("expected", _number(expected), "a number"),
                  ("tol", _number(tol) and tol > 0, "a number > 0")]
        for key, ok, what in checks:
            if key not in spec:
                problems.append(f"{path}.{key}: missing; expected {what}")
            elif not ok:
                problems.append(f"{path}.{key}: got {describe(spec[key])}; expected {what}")
        rate = spec.get("rate", False)
        if not isinstance(rate, bool):
            problems.append(f"{path}.rate: got {describe(rate)}; expected true or false")
        if len(problems) > n:
            return None
        return cls(name, float(t), float(expected), float(tol), rate)

    def check(self, result):
        label = f"value {self.quantity}{' rate' if self.rate else ''} at t = {self.t:g} s"
        expected = f"{self.expected:.12g} +- {self.tol:g}"
        if result.t.size == 0 or self.t > result.t[-1] * (1 + SAMPLE_MATCH) + SAMPLE_MATCH:
            reached = f"t = {result.t[-1]:g} s" if result.t.size else "no samples"
            return Outcome(self.name, False, "-", expected, f"the run stopped before t ({reached})", label)
        value, how = self.sample(result)
        error = abs(value - self.expected)
        note = f"|error| = {error:.3g}" + (f", {how}" if how else "")
        return Outcome(self.name, bool(error <= self.tol), f"{value:.12g}", expected, note, label)

    def sample(self, result: Result) -> tuple[float, str]:
        """The quantity at ``t``: the output sample there, or interpolated between the two
        around it (cubic Hermite from the values and their rates; linear for the rate of
        an observable, whose own rate is not recorded). Returns (value, how)."""
        coordinates = result.coordinate_names
        if self.quantity in coordinates:
            i = coordinates.index(self.quantity)
            values, slopes = (result.qd[:, i], result.qdd[:, i]) if self.rate else (result.q[:, i], result.qd[:, i])
        else:
            i = result.observable_names.index(self.quantity)
            values = (result.observable_rates if self.rate else result.observables)[:, i]
            slopes = None if self.rate else result.observable_rates[:, i]
        return interpolate(result.t, values, slopes, self.t)


def interpolate(t: np.ndarray, values: np.ndarray, slopes: np.ndarray | None, at: float) -> tuple[float, str]:
    """A sampled series at time ``at``.

    Parameters
    ----------
    t : (N,) array [s]
        Output times, increasing.
    values, slopes : (N,) arrays
        The series and its time derivative (None: interpolate linearly).
    at : float [s]
        Within [t[0], t[-1]] (to round-off).

    Returns
    -------
    value : float
    how : str
        ``""`` for an output sample, else how it was interpolated.
    """
    if t.size == 1:
        return float(values[0]), ""
    b = int(np.clip(np.searchsorted(t, at), 1, t.size - 1))
    a = b - 1
    near = a if abs(t[a] - at) <= abs(t[b] - at) else b
    if abs(t[near] - at) <= SAMPLE_MATCH * max(1.0, abs(at)):
        return float(values[near]), ""
    h = t[b] - t[a]
    s = (at - t[a]) / h
    if slopes is None:
        return float((1 - s) * values[a] + s * values[b]), f"linear between t = {t[a]:g} and {t[b]:g} s"
    h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
    value = h00 * values[a] + h10 * h * slopes[a] + h01 * values[b] + h11 * h * slopes[b]
    return float(value), f"cubic Hermite between t = {t[a]:g} and {t[b]:g} s"
