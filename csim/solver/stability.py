"""Whether a fixed step keeps a stabilizer's constraint-error dynamics stable.

One step of an explicit Runge-Kutta method with Butcher tableau (A, b) multiplies the
solution of y' = lambda y by its stability function

    R(z) = 1 + z b^T (I - z A)^-1 1,   z = h lambda,

(for classic RK4: 1 + z + z^2/2 + z^3/6 + z^4/24), so a mode with eigenvalue lambda decays
from step to step only while |R(h lambda)| <= 1: h lambda must lie in the stability region.
A stabilizer imposes linear constraint-error dynamics whose eigenvalues are its gains
(:meth:`csim.solver.methods.base.Method.error_modes`: -w for Baumgarte with d = 1;
-Lambda and -(K + k sw'(0)) for sliding mode). A gain times the step beyond the region
makes the stabilizer itself drive the constraint error up; this module says so before a
run (:func:`stability_warnings`) and names the product when such a run fails
(:func:`stability_cause`). Nonlinear constraints lose stability somewhat before the
bound (the pendulum with Baumgarte diverges from w h = 2.6 on, the bound being 2.785),
so a product above :data:`MARGIN` of the bound is reported too.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: fixed-step integrators by name: Butcher tableau (A, b) of the scheme they step with
#: (``RK4``: the classic one of :mod:`csim.solver.rk4`)
TABLEAUS: dict[str, tuple[tuple, tuple]] = {
    "RK4": (((0.0, 0.0, 0.0, 0.0), (0.5, 0.0, 0.0, 0.0), (0.0, 0.5, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0)),
            (1 / 6, 1 / 3, 1 / 3, 1 / 6)),
}

#: a product above this fraction of the stability bound is reported (nonlinear constraints
#: diverge below the linear bound: measured on the pendulum from 0.93 of it)
MARGIN = 0.9


def stability_function(integrator: str, z: complex) -> complex:
    """R(z) = 1 + z b^T (I - z A)^-1 1 of the fixed-step ``integrator`` (a key of :data:`TABLEAUS`)."""
    A, b = (np.asarray(x, dtype=float) for x in TABLEAUS[integrator])
    stages = np.linalg.solve(np.eye(b.size) - z * A, np.ones(b.size, dtype=complex))
    return complex(1.0 + z * (b @ stages))


def inside(integrator: str, z: complex) -> bool:
    """Whether z = h lambda lies in the stability region |R(z)| <= 1 (to round-off)."""
    return abs(stability_function(integrator, z)) <= 1.0 + 1e-12


def ray_bound(integrator: str, shape: complex) -> float:
    """The largest x with h lambda = t shape in the stability region for every 0 <= t <= x.

    Parameters
    ----------
    integrator : str
        A key of :data:`TABLEAUS`.
    shape : complex
        The direction of h lambda (``-1``: the negative real axis).

    Returns
    -------
    float
        Where the ray first leaves the region (2.7853 for RK4 on the negative real axis),
        found by a scan in steps of 0.01 / |shape| and bisection; inf if it never does.
    """
    dt = 0.01 / abs(shape)
    lo = 0.0
    for k in range(1, 5001):  # |z| up to 50, far beyond any explicit method's region
        if not inside(integrator, k * dt * shape):
            hi = k * dt
            break
        lo = k * dt
    else:
        return np.inf
    while hi - lo > 1e-13 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if inside(integrator, mid * shape) else (lo, mid)
    return lo


def real_axis_bound(integrator: str) -> float:
    """Where the stability region ends on the negative real axis (2.7853 for RK4)."""
    return ray_bound(integrator, -1.0)


@dataclass(frozen=True)
class StepCheck:
    """One mode of a method checked against a fixed step.

    Attributes
    ----------
    mode : csim.solver.methods.base.ErrorMode
    integrator : str
    step : float
        h [s].
    bound : float
        The largest gain * h on the mode's ray (:func:`ray_bound`).
    """

    mode: object
    integrator: str
    step: float
    bound: float

    @property
    def product(self) -> float:
        """gain * h."""
        return self.mode.gain * self.step

    @property
    def outside(self) -> bool:
        """h lambda lies outside the stability region."""
        return not inside(self.integrator, self.product * self.mode.shape)

    @property
    def reported(self) -> bool:
        """Outside, or (for a mode that would grow) above :data:`MARGIN` of the bound."""
        return self.outside or (not self.mode.saturates and self.product > MARGIN * self.bound)

    def cause(self) -> str:
        """The product and where it lies, e.g. ``stabilization.w * simulation.step = 3 lies
        outside RK4's stability interval (2.785)``."""
        mode, shape = self.mode, complex(self.mode.shape)
        which = "" if mode.constraint is None else f" (constraint {mode.constraint + 1})"
        real = shape.imag == 0 and shape.real < 0
        where = "stability interval" if real else "stability region"
        of = f" for {mode.note}" if mode.note and shape != -1 else ""
        verb = "lies outside" if self.outside else "is close to the edge of"
        return (f"{mode.keys} * simulation.step = {self.product:.4g}{which} {verb} {self.integrator}'s {where} "
                f"({self.bound:.4g}{of})")

    def advice(self) -> str:
        """What to do: the step that keeps the product below :data:`MARGIN` of the bound."""
        if self.mode.saturates:
            growth = self.mode.saturates
        elif self.outside:
            growth = "the constraint error will grow"
        else:
            growth = "nonlinear constraints diverge already slightly below the bound"
        return f"{growth}; choose simulation.step <= {MARGIN * self.bound / self.mode.gain:.3g} s or a smaller gain"


def step_checks(method, integrator: str, step: float) -> list[StepCheck]:
    """The method's error modes that a fixed ``step`` of ``integrator`` puts at or beyond the
    edge of its stability region, worst first (empty for an adaptive integrator)."""
    if integrator not in TABLEAUS:
        return []
    checks = [StepCheck(mode, integrator, step, ray_bound(integrator, mode.shape))
              for mode in method.error_modes() if mode.gain > 0]
    reported = [c for c in checks if c.reported]
    growing = {c.mode.constraint for c in reported if not c.mode.saturates}
    reported = [c for c in reported if not (c.mode.saturates and c.mode.constraint in growing)]
    # growing errors first (a saturating mode only chatters), then the furthest beyond its bound
    return sorted(reported, key=lambda c: (bool(c.mode.saturates), -c.product / c.bound))


def stability_warnings(method, integrator: str, step: float) -> list[str]:
    """One warning per mode :func:`step_checks` reports, naming the keys, the product and the bound."""
    # a complex pair of eigenvalues gives the same line twice (the region is symmetric about the real axis)
    return list(dict.fromkeys(f"{c.cause()}: {c.advice()}" for c in step_checks(method, integrator, step)))


def stability_cause(method, settings) -> str | None:
    """The worst product beyond the edge of the stability region, for a failure message; or None.

    Parameters
    ----------
    method : csim.solver.methods.base.Method or None
    settings : csim.solver.settings.IntegrationSettings or None
    """
    if method is None or settings is None or not hasattr(method, "error_modes"):
        return None
    checks = step_checks(method, settings.integrator, settings.step)
    return checks[0].cause() if checks else None
