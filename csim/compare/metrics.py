"""Figures of merit of a run, from its arrays: constraint errors and the motion error.

Pure functions of sampled arrays (N output times, n coordinates, r constraints), so that
they can be checked without a simulation. :class:`csim.compare.runs.Run` holds what they
return, one run at a time.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NAN = float("nan")


def nanmax_abs(a) -> float:
    """max |a| over every entry, ignoring NaN; NaN when ``a`` is empty or all NaN."""
    a = np.abs(np.asarray(a, dtype=float))
    if a.size == 0 or np.all(np.isnan(a)):
        return NAN
    return float(np.nanmax(a))


def constraint_errors(phi: np.ndarray, phi_dot: np.ndarray) -> tuple[float, float, float]:
    """The constraint errors of a run.

    Parameters
    ----------
    phi : ndarray, shape (N, r)
        Phi(q) at the output times [unit of each constraint].
    phi_dot : ndarray, shape (N, r)
        Phi_q qd at the output times [unit of each constraint / s].

    Returns
    -------
    max_phi, final_phi, max_phi_dot : float
        max |Phi_i| over the run, max |Phi_i| at the last sample (NaN without samples), and
        max |(Phi_q qd)_i| over the run.
    """
    final_phi = nanmax_abs(phi[-1:]) if len(phi) else NAN
    return nanmax_abs(phi), final_phi, nanmax_abs(phi_dot)


@dataclass(frozen=True)
class MotionError:
    """A run's motion error against the reference run.

    Attributes
    ----------
    motion : float
        max over the compared output times and the coordinates of |q - q_ref| [rad or m].
    final : float
        max over the coordinates of |q(t_end) - q_ref(t_end)| [rad or m]; NaN when the run
        or the reference did not reach t_end.
    until : float
        The last output time ``motion`` covers [s].
    note : str
        Why the errors are missing or partial ("" when complete).
    """

    motion: float = NAN
    final: float = NAN
    until: float = NAN
    note: str = ""


def motion_error(t: np.ndarray, q: np.ndarray, t_ref: np.ndarray, q_ref: np.ndarray) -> MotionError:
    """The motion error of a run (t, q) against the reference run (t_ref, q_ref).

    Parameters
    ----------
    t : ndarray, shape (N,)
        The run's output times [s], at least one.
    q : ndarray, shape (N, n)
        The run's coordinates at ``t`` [rad or m].
    t_ref : ndarray, shape (N_ref,)
        The reference's output times [s], at least one.
    q_ref : ndarray, shape (N_ref, n)
        The reference's coordinates at ``t_ref``.

    Returns
    -------
    MotionError
        Over the output times both runs reached (the first min(N, N_ref)); no numbers, and a
        note, when the coordinates or the output times differ from the reference's.
    """
    n = min(t.size, t_ref.size)
    same_times = np.allclose(t[:n], t_ref[:n], rtol=0.0, atol=1e-9 * max(t_ref[-1], 1.0))
    if q.shape[1] != q_ref.shape[1] or not same_times:
        return MotionError(note="output times differ from the reference's")
    # motion error: e = max over k < n and i of |q_i(t_k) - q_ref_i(t_k)|
    motion, until = nanmax_abs(q[:n] - q_ref[:n]), float(t[n - 1])
    if n == t.size == t_ref.size:
        # final error: e_end = max over i of |q_i(t_end) - q_ref_i(t_end)|
        return MotionError(motion, nanmax_abs(q[-1] - q_ref[-1]), until)
    return MotionError(motion, NAN, until, f"motion error over t <= {until:.6g} s only (the run stopped early)")
