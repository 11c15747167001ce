"""Time integrators, by name: scipy's adaptive solvers and a classic fixed-step RK4.

The registry is plain data; each class is imported when an integrator is made (scipy's
integrate package takes a good part of a second to import, and the compiled backend and
the case validation never need it).

Each integrator is a :class:`scipy.integrate.OdeSolver`: built as
``cls(fun, t0, y0, t_bound, **options)``, advanced by ``step()`` (one accepted step, or
``status = "failed"`` with a message), with ``dense_output()`` interpolating the last step.
The simulation driver (:mod:`csim.solver.simulate`) uses nothing else, so every integrator
gets the same event location, output sampling and failure handling.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class IntegratorInfo:
    """What the registry knows of one integrator.

    ``where`` is ``"module:Class"``; :attr:`cls` imports it.
    """

    where: str
    adaptive: bool
    description: str
    #: solves a Newton iteration per step: a non-finite trial iterate only makes it shrink the step
    implicit: bool = False
    #: steps the system's own equations (it is given the system and the load conditions, not only fun)
    needs_system: bool = False

    @property
    def cls(self) -> type:
        """The :class:`scipy.integrate.OdeSolver` subclass (imported on first use)."""
        module, _, name = self.where.partition(":")
        return getattr(importlib.import_module(module), name)


#: name -> integrator (``simulation.integrator`` in a case file)
INTEGRATORS: dict[str, IntegratorInfo] = {
    "RK45": IntegratorInfo("scipy.integrate:RK45", True, "explicit Runge-Kutta 5(4), Dormand-Prince"),
    "DOP853": IntegratorInfo("scipy.integrate:DOP853", True, "explicit Runge-Kutta 8(5,3), Dormand-Prince"),
    "Tsit5": IntegratorInfo("csim.solver.tsit5:Tsit5", True, "explicit Runge-Kutta 5(4), Tsitouras"),
    "Vern7": IntegratorInfo("csim.solver.vern7:Vern7", True, "explicit Runge-Kutta 7(6), Verner"),
    "Radau": IntegratorInfo("scipy.integrate:Radau", True, "implicit Runge-Kutta Radau IIA, order 5 (stiff)",
                            implicit=True),
    "BDF": IntegratorInfo("scipy.integrate:BDF", True, "implicit multistep BDF, orders 1-5 (stiff)", implicit=True),
    "LSODA": IntegratorInfo("scipy.integrate:LSODA", True, "Adams/BDF with automatic stiffness switching"),
    "RK4": IntegratorInfo("csim.solver.rk4:RK4", False, "classic Runge-Kutta 4, fixed step `simulation.step`"),
    "trapezoidal": IntegratorInfo("csim.solver.ali3p:ALI3P", False,
                                  "trapezoidal rule of the index-3 augmented Lagrangian method (ALI3-P), fixed step "
                                  "`simulation.step`; stabilization.method augmented_lagrangian only",
                                  implicit=True, needs_system=True),
}


#: integrators that also solve DAEs ``D y' = F(t, y)`` (their DAE version)
DAE_INTEGRATORS = {"Radau": "Radau IIA for semi-explicit DAEs of index up to 2 (csim.solver.dae)"}


def _check_dae(name):
    if name not in DAE_INTEGRATORS:
        raise ValueError(f"integrator {name!r} cannot solve a DAE; DAE integrators: {', '.join(DAE_INTEGRATORS)}")


def make_integrator(name, fun, t0, y0, t_bound, *, rtol, atol, step=None, max_step=np.inf, first_step=None,
                    dae=None, system=None, mode=None):
    """Start the integrator ``name`` on ``y' = fun(t, y)`` from (t0, y0) towards ``t_bound``.

    ``rtol``, ``atol`` (scalar or (n,)), ``max_step`` and ``first_step`` apply to the
    adaptive integrators, ``step`` [s] to the fixed-step ones. ``dae`` (a dict with
    ``differential``, the bool mask of the differential rows, and solver options) makes
    ``fun`` the right-hand side F of the DAE ``D y' = F(t, y)``; only the integrators of
    :data:`DAE_INTEGRATORS` accept it. ``system`` and ``mode`` (the load conditions held, None:
    evaluated at each step) go to an integrator that steps the system's own equations
    (``needs_system``).
    """
    try:
        info = INTEGRATORS[name]
    except KeyError:
        raise KeyError(f"unknown integrator {name!r}; valid names: {', '.join(INTEGRATORS)}") from None
    if info.adaptive:
        options = dict(rtol=rtol, atol=atol, max_step=max_step)
        if first_step is not None:
            options["first_step"] = min(first_step, t_bound - t0)
        if dae is not None:
            _check_dae(name)
            from csim.solver.dae import RadauDAE

            return RadauDAE(fun, t0, y0, t_bound, **dae, **options)
        if info.implicit:  # Radau, BDF: forward differences whose steps stay finite
            from csim.solver.dae import DifferenceJacobian

            options["jac"] = DifferenceJacobian(fun, atol)
        return info.cls(fun, t0, y0, t_bound, **options)
    if dae is not None:
        _check_dae(name)
    if info.needs_system:
        return info.cls(fun, t0, y0, t_bound, step=step, system=system, mode=mode)
    return info.cls(fun, t0, y0, t_bound, step=step)

