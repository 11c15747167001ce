"""One run of a comparison (a method at a tolerance) and its figures of merit.

A :class:`Run` starts as a failed row whose message says that an interrupt kept it from
finishing (:data:`INTERRUPTED`); :meth:`Run.set_result` fills in its result once it ran, and
:meth:`Run.measure_against` its motion errors against the reference run
(:mod:`csim.compare.metrics` computes the numbers).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from csim.compare.metrics import NAN, MotionError, constraint_errors, motion_error
from csim.compare.specs import tol_text
from csim.result import Result

#: message of the runs that an interrupt (Ctrl-C) kept from running or finishing
INTERRUPTED = "interrupted by the user (Ctrl-C) before this run finished"


@dataclass
class Run:
    """One run of a comparison: a method at a tolerance, and its figures of merit.

    Attributes
    ----------
    method : str
        Stabilization method (``METHOD:INTEGRATOR`` when it names its own integrator).
    tolerance : float
        rtol (= atol) of the run, or its step [s] for a fixed-step integrator; see
        ``tolerance_kind``.
    tolerance_kind : {"rtol=atol", "rtol", "step"}
        What ``tolerance`` is for this run's integrator (``"rtol"``: atol differs, see the
        run's case).
    result : Result or None
        The full run (None when it raised before producing one, or never ran).
    status : {"success", "failed"}
    message : str
        The run's message (the cause of a failure).
    wall_time : float
        Wall time of the run [s], measured in the process that ran it.
    nfev, nsteps : int
        Right-hand-side evaluations and accepted steps.
    max_phi, final_phi : float
        max |Phi_i| over the run, and at its last sample [unit of Phi]; NaN without samples.
    max_phi_dot : float
        max |(Phi_q qd)_i| over the run [unit of Phi / s].
    motion_error : float
        max over output times and coordinates of |q - q_ref| [rad or m]; NaN without a
        reference.
    final_error : float
        max over coordinates of |q(t_end) - q_ref(t_end)| [rad or m]; NaN when the run or
        the reference did not reach t_end.
    error_until : float
        Last output time that ``motion_error`` covers [s] (t_end unless a run stopped early).
    error_note : str
        Why the errors are missing or partial ("" when complete).
    case_yaml : str
        The run's case, validated (what its group's ``case`` attribute holds).
    """

    method: str
    tolerance: float
    tolerance_kind: str = "rtol=atol"
    result: Result | None = None
    status: str = "failed"
    message: str = INTERRUPTED
    wall_time: float = NAN
    nfev: int = 0
    nsteps: int = 0
    max_phi: float = NAN
    final_phi: float = NAN
    max_phi_dot: float = NAN
    motion_error: float = NAN
    final_error: float = NAN
    error_until: float = NAN
    error_note: str = ""
    case_yaml: str = field(default="", repr=False)

    @property
    def ok(self) -> bool:
        """Whether the run succeeded."""
        return self.status == "success"

    def set_result(self, result: Result | None, message: str = "") -> None:
        """Take the figures of merit of ``result`` (None: the run raised ``message``)."""
        self.result = result
        if result is None:
            self.status, self.message = "failed", message
            return
        self.status, self.message = result.status, result.message
        self.wall_time, self.nfev, self.nsteps = float(result.wall_time), int(result.nfev), int(result.nsteps)
        self.max_phi, self.final_phi, self.max_phi_dot = constraint_errors(result.phi, result.phi_dot)

    def measure_against(self, ref: Run) -> None:
        """Set the motion errors against the reference run ``ref`` (see :func:`motion_error`)."""
        r = self.result
        if ref.result is None or not ref.ok:
            error = MotionError(note=f"no reference: the reference run failed ({shorten(ref.message)})")
        elif r is None or r.t.size == 0:
            error = MotionError(note="no samples to measure")
        else:
            error = motion_error(r.t, r.q, ref.result.t, ref.result.q)
        self.motion_error, self.final_error, self.error_until = error.motion, error.final, error.until
        self.error_note = error.note


def run_setting(run: Run) -> str:
    """A run's setting as short text: ``rtol=atol 1e-08``, ``step 1e-03``."""
    return f"{run.tolerance_kind} {tol_text(run.tolerance)}"


def shorten(message: str, n: int = 120) -> str:
    """``message`` on one line, cut to ``n`` characters (ending in ``...`` where cut)."""
    message = " ".join(str(message).split())
    return message if len(message) <= n else message[:n - 3] + "..."
