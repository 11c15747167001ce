"""The result of one run: time series, status, counters, and the figures of merit.

Shapes: N output times, m coordinates, r constraints, k loads, o observables.
Units: see :data:`csim.io.units.UNITS`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: a kernel load longer than this [s] was a compilation, and the summary says so
COMPILE_NOTICE = 3.0


@dataclass
class Result:
    """One simulation run.

    Attributes
    ----------
    t : (N,) [s]
    q, qd, qdd : (N, m) coordinates, velocities, accelerations
    lam : (N, r) Lagrange multipliers
    phi : (N, r) constraint residuals Phi(q)
    phi_dot : (N, r) velocity-level residuals Phi_q qd
    kinetic, potential : (N,) [J]
    work : (N, k) work done by each load since t = 0 [J]
    loads : (N, k) load values u [N or N m]
    generalized_forces : (N, m) Q = B u
    observables, observable_rates : (N, o) mechanism-declared quantities and their rates
    status : {"success", "failed"}
    message : str
    wall_time : float [s], integration and post-processing
    nfev, njev, nlu, nsteps : int
    event_times : (E,) [s]; event_labels : list of str
    backend : {"python", "compiled"}
        What integrated the run: the Python driver or the compiled kernels (``csim.fast``).
    kernel_load_time : float [s]
        Time to load the compiled kernels before the run (on a cold cache: to generate and
        compile them); not part of ``wall_time``.
    run_kind : {"simulation", "kinematic"}
        A dynamic simulation, or a kinematic analysis of prescribed motion (no forces:
        lam, work, loads and generalized forces are NaN).
    """

    mechanism: str
    coordinate_names: list[str]
    load_names: list[str]
    observable_names: list[str]
    case_yaml: str
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    lam: np.ndarray
    phi: np.ndarray
    phi_dot: np.ndarray
    kinetic: np.ndarray
    potential: np.ndarray
    work: np.ndarray
    loads: np.ndarray
    generalized_forces: np.ndarray
    observables: np.ndarray
    observable_rates: np.ndarray
    status: str = "success"
    message: str = ""
    wall_time: float = 0.0
    nfev: int = 0
    njev: int = 0
    nlu: int = 0
    nsteps: int = 0
    event_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    event_labels: list[str] = field(default_factory=list)
    run_kind: str = "simulation"
    backend: str = "python"
    kernel_load_time: float = 0.0

    @property
    def ok(self) -> bool:
        return self.status == "success"

    @property
    def energy_error(self) -> np.ndarray:
        """(N,) T + V - (T0 + V0) - sum_k W_k [J]: zero for exact motion (ideal constraints)."""
        if self.t.size == 0:
            return np.zeros(0)
        return self.kinetic + self.potential - self.kinetic[0] - self.potential[0] - self.work.sum(axis=1)

    @property
    def energy_scale(self) -> float:
        """Energy scale of the run [J]: the largest of max T, max |V - V0| and max |sum W|."""
        if self.t.size == 0:
            return 1.0
        return float(max(np.max(np.abs(self.kinetic)), np.max(np.abs(self.potential - self.potential[0])),
                         np.max(np.abs(self.work.sum(axis=1))), np.finfo(float).tiny))

    @property
    def energy_error_relative(self) -> float:
        """max |energy_error| / energy_scale over the run."""
        return float(np.max(np.abs(self.energy_error)) / self.energy_scale) if self.t.size else float("nan")

    @property
    def max_phi(self) -> float:
        """max over the run of max_i |Phi_i|."""
        return float(np.max(np.abs(self.phi))) if self.phi.size else float("nan")

    @property
    def max_phi_dot(self) -> float:
        """max over the run of max_i |(Phi_q qd)_i|."""
        return float(np.max(np.abs(self.phi_dot))) if self.phi_dot.size else float("nan")

    def summary(self) -> str:
        """A short, human-readable account of the run."""
        lines = [f"status:            {self.status} ({self.message})"]
        if self.t.size:
            names = self.coordinate_names
            lines.append(f"final time:        {self.t[-1]:.6g} s")
            lines.append("final q:           " + ", ".join(f"{n} = {v:.8g}" for n, v in zip(names, self.q[-1])))
            lines.append("final qd:          " + ", ".join(f"{n} = {v:.8g}" for n, v in zip(names, self.qd[-1])))
            lines.append(f"max |Phi|:         {self.max_phi:.3e}")
            lines.append(f"max |Phi_q qd|:    {self.max_phi_dot:.3e}")
            if self.run_kind == "kinematic":
                lines.append("energy balance:    - (a kinematic analysis of prescribed motion: no forces)")
            else:
                lines.append(f"energy balance:    {self.energy_error_relative:.3e} (max |T + V - T0 - V0 - W|"
                             f" / {self.energy_scale:.4g} J)")
        lines.append(f"events:            {len(self.event_times)}")
        lines.append(f"wall time:         {self.wall_time:.3f} s ({self.backend} backend)")
        if self.backend == "compiled" and self.kernel_load_time > COMPILE_NOTICE:
            lines.append(f"compilation:       {self.kernel_load_time:.1f} s before the run (the first run of this "
                         f"mechanism; later runs load the kernels from the cache)")
        lines.append(f"RHS evaluations:   {self.nfev} ({self.nsteps} steps)")
        return "\n".join(lines)
