"""The result of one run: time series, status, counters, and the figures of merit.

Shapes: N output times, m coordinates, r constraints, k loads, o observables.
Units: see :data:`csim.io.outputs.OUTPUTS` (the per-sample quantities) and
:data:`csim.io.units.UNITS`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: column where the values of :meth:`Result.summary` start
SUMMARY_WIDTH = 19

#: a kernel load longer than this [s] was a compilation, and the summary says so
COMPILE_NOTICE = 3.0

#: the energy scale counts as zero (a run at rest) when it is below this fraction of the largest
#: energy the run records: the relative energy balance is then round-off over round-off
TINY_ENERGY_SCALE = 1e-9

#: why a failed run failed (:attr:`Result.failure`), read from a message that came without its
#: kind (a run raises SimulationFailure with its kind, and a status code has its own,
#: csim.physics.status.KINDS; tests check both file every code's message alike): the first
#: kind whose phrases the message starts with, in this order (a phrase with ``{t}`` also
#: needs its tail in the message)
FAILURE_KINDS = (
    ("invalid", ("case: ",)),
    ("assembly", ("initial conditions", "the mechanism cannot be assembled")),
    ("interrupted", ("interrupted",)),
    ("blow-up", ("blow-up",)),
    ("drift", ("constraint violation",)),
    ("step", ("integrator rk4 failed",)),
    ("step collapse", ("step-size collapse", "integrator ")),
    ("max steps", ("more than simulation.max_steps",)),
    ("chatter", ("more than simulation.max_events", "chattering load law")),
    ("projection", ("projection: gauss-newton",)),
    ("singular", ("singular", "projection at t = {t}: the constraint jacobian has lost rank",
                  "projection at t = {t}: the mass matrix is singular", "numerical error after t = {t}: linalgerror",
                  "minimal: the dependent block phi_v is singular", "the dependent block phi_v",
                  "phi_v is singular", "ggl: singular", "ggl: the mass matrix is singular", "no dependent block phi_v",
                  "minimal: r^t m r is singular")),
    ("newton", ("minimal: newton-raphson",)),
    ("branch", ("minimal: the assembly branch",)),
    ("event location", ("numerical error",)),
    ("drive", ("mechanism.drive",)),
    ("backend", ("simulation.backend 'compiled'", "simulation.backend 'interpreted'")),
)

#: values of :attr:`Result.failure`: "" for a success, a kind of :data:`FAILURE_KINDS`, or
#: ``"other"`` for a failure no kind names
FAILURES = ("", *(kind for kind, _ in FAILURE_KINDS), "other")

#: the prefix of a kinematic analysis's failure messages (csim.linkage.kinematics.KINEMATIC_RUN)
_KINEMATIC_PREFIX = "kinematic analysis: "


def failure_kind(message: str) -> str:
    """The kind of a failure (:data:`FAILURES`) from its message; ``"other"`` where none fits.

    Examples
    --------
    >>> failure_kind("chattering load law: ...")
    'chatter'
    """
    text = message.lower().strip().removeprefix(_KINEMATIC_PREFIX)
    for kind, starts in FAILURE_KINDS:
        if any(text.startswith(s.split("{t}")[0]) and s.split("{t}")[-1] in text for s in starts):
            return kind
    return "other"


@dataclass
class JointReaction:
    """The reaction of one joint of a link-coupling mechanism over a run (N samples).

    The force F and moment M that link i exerts on link j (coupling row (i, k, j, m)) at
    the origin of joint frame jm; link i receives -F and -M there. Derived from the
    multipliers (a cut joint) or by Newton-Euler of the links beyond it (a tree joint) by
    :mod:`csim.linkage.reactions`.

    Attributes
    ----------
    name : str
        The coupling's name, or its number.
    label : str
        ``"joint C (R, link 2 'coupler' on link 3 'rocker')"``.
    force_global, torque_global : ndarray (N, 3)
        F [N] and M [N m] in the fixed frame's axes.
    force_joint, torque_joint : ndarray (N, 3)
        The same in the axes of joint frame ik (A_ik^T F, A_ik^T M) [N], [N m].
    undetermined : list of str
        Reaction unknowns whose equations were removed, each with why (reported as 0).
    """

    name: str
    label: str
    force_global: np.ndarray
    torque_global: np.ndarray
    force_joint: np.ndarray
    torque_joint: np.ndarray
    undetermined: list[str] = field(default_factory=list)


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
    backend : {"python", "compiled", "interpreted"}
        What integrated the run: the Python driver, the compiled kernels (``csim.fast``) or their source run
        by Python.
    kernel_load_time : float [s]
        Time to load the compiled kernels before the run (on a cold cache: to generate and
        compile them); not part of ``wall_time``.
    run_kind : {"simulation", "kinematic"}
        A dynamic simulation, or a kinematic analysis of prescribed motion (no forces:
        lam, work, loads and generalized forces are NaN).
    failure : str
        What kind of failure a failed run is (:data:`FAILURES`), ``""`` for a success: e.g.
        ``"assembly"`` the initial state cannot be assembled (Newton-Raphson on Phi(q) = 0
        failed: bad input), ``"interrupted"`` stopped by the user (Ctrl-C), ``"chatter"``,
        ``"blow-up"``, ``"drift"``. Given, or else set from the message
        (:func:`failure_kind`) when the run is made; written to HDF5 as the ``failure``
        attribute.
    backend_reason : str
        Why a run under ``simulation.backend: auto`` (or ``compiled``) was not compiled: on the
        Python path, the combination has no compiled path or the kernels could not be loaded;
        interpreted, numba is missing or ``CSIM_PURE_PYTHON=1`` rules it out. ``""`` when it ran
        compiled or on the backend asked for.
    reactions : list of JointReaction
        The reactions of the joints of a link-coupling mechanism, the cut joints' first
        (empty otherwise, and for a kinematic analysis).
    drive_names, drive_units : list of str
        The driven joint variables of a driven-dynamics run and the unit of each drive's
        force (``"N m"`` for a rotation, ``"N"`` for a translation); empty otherwise.
    drive_forces : ndarray (N, d) or None
        The torque or force each drive applies along its joint variable [N m or N].
    drive_work : ndarray (N, d) or None
        The work of each drive since t = 0 [J], part of the energy balance.
    warnings : list of str
        What a person should know about a run that may still be a success: singular
        configurations crossed, kept equations that lost rank (:mod:`csim.solver.integrity`).
    singular_times : ndarray (S,) [s]
        Where Phi_q of the full set of equations fell below its generic rank.
    removed_names, removed_units : list of str; removed_phi : ndarray (N, d) or None
        The constraint equations removed as dependent at the start, their units, and their
        residuals at the samples (a correct motion keeps them at the kept ones' level).
    coordinate_units, constraint_units, load_units, observable_units, observable_rate_units : list of str
        The unit of each column of q, of phi, of the loads, of the observables and of their
        rates (:func:`csim.io.units.mechanism_units`); empty where not known (a run read
        from a file of an earlier version). A constraint's unit is ``""`` where dimensional
        analysis cannot find it.
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
    failure: str = ""
    backend_reason: str = ""
    reactions: list[JointReaction] = field(default_factory=list)
    drive_names: list[str] = field(default_factory=list)
    drive_units: list[str] = field(default_factory=list)
    drive_forces: np.ndarray | None = None
    drive_work: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    singular_times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    removed_names: list[str] = field(default_factory=list)
    removed_phi: np.ndarray | None = None
    removed_units: list[str] = field(default_factory=list)
    coordinate_units: list[str] = field(default_factory=list)
    constraint_units: list[str] = field(default_factory=list)
    load_units: list[str] = field(default_factory=list)
    observable_units: list[str] = field(default_factory=list)
    observable_rate_units: list[str] = field(default_factory=list)

    def __post_init__(self):
        if self.status != "success" and not self.failure:
            self.failure = failure_kind(self.message)

    @classmethod
    def empty(cls, mechanism: str, coordinate_names: list[str], load_names: list[str],
              observable_names: list[str], n_constraints: int, case_yaml: str, status: str = "failed",
              message: str = "", **fields) -> Result:
        """A run with no samples (N = 0), e.g. one interrupted before its first step.

        Parameters
        ----------
        mechanism, coordinate_names, load_names, observable_names, case_yaml
            As the attributes of the same names.
        n_constraints : int
            r, the number of constraint equations (the width of ``lam``, ``phi``, ``phi_dot``).
        status, message : str
            The run's status and why.
        **fields
            Any other attribute (``failure``, ``run_kind``, ...).
        """
        m, r, k, o = len(coordinate_names), int(n_constraints), len(load_names), len(observable_names)
        zeros = {name: np.zeros((0, width)) for name, width in dict(
            q=m, qd=m, qdd=m, lam=r, phi=r, phi_dot=r, work=k, loads=k, generalized_forces=m, observables=o,
            observable_rates=o).items()}
        return cls(mechanism=mechanism, coordinate_names=list(coordinate_names), load_names=list(load_names),
                   observable_names=list(observable_names), case_yaml=case_yaml, t=np.zeros(0),
                   kinetic=np.zeros(0), potential=np.zeros(0), status=status, message=message, **zeros, **fields)

    @property
    def ok(self) -> bool:
        return self.status == "success"

    @property
    def total_work(self) -> np.ndarray:
        """(N,) the work of every load and every drive since t = 0 [J]."""
        work = self.work.sum(axis=1)
        return work if self.drive_work is None else work + self.drive_work.sum(axis=1)

    @property
    def energy_error(self) -> np.ndarray:
        """(N,) T + V - (T0 + V0) - sum_k W_k [J] (the drives' work included): zero for exact
        motion (ideal constraints)."""
        if self.t.size == 0:
            return np.zeros(0)
        return self.kinetic + self.potential - self.kinetic[0] - self.potential[0] - self.total_work

    @property
    def energy_scale(self) -> float:
        """Energy scale of the run [J]: the largest of max T, max |V - V0| and max |sum W|."""
        if self.t.size == 0:
            return 1.0
        return float(max(np.max(np.abs(self.kinetic)), np.max(np.abs(self.potential - self.potential[0])),
                         np.max(np.abs(self.total_work)), np.finfo(float).tiny))

    @property
    def energy_scale_is_zero(self) -> bool:
        """Whether the energy scale is zero or round-off (below :data:`TINY_ENERGY_SCALE` times
        the largest of max T, max |V| and max |sum W|): a run that stays at rest, or whose moving
        links have no mass, or whose energies barely change against a large V (:attr:`stays_at_rest`,
        :attr:`energy_is_zero`), and whose balance is best read in J, not relative to the scale.
        False for non-finite energies (a blow-up)."""
        if self.t.size == 0:
            return False
        work = np.abs(self.total_work)
        moved = max(np.max(np.abs(self.kinetic)), np.max(np.abs(self.potential - self.potential[0])), np.max(work))
        magnitude = max(np.max(np.abs(self.kinetic)), np.max(np.abs(self.potential)), np.max(work))
        return bool(np.isfinite(magnitude) and moved <= TINY_ENERGY_SCALE * magnitude)  # False for NaN or inf

    @property
    def energy_is_zero(self) -> bool:
        """Whether T, V - V0 and the loads' work are exactly zero at every sample (no mass moves)."""
        return bool(self.t.size and not np.any(self.kinetic) and not np.any(self.potential - self.potential[0])
                    and not np.any(self.total_work))

    @property
    def stays_at_rest(self) -> bool:
        """Whether no coordinate moved by more than 1e-9 (1 + the largest |q| at the start) over the run."""
        if self.t.size == 0:
            return True
        moved = np.max(np.abs(self.q - self.q[0]), initial=0.0)
        return bool(moved <= 1e-9 * (1.0 + np.max(np.abs(self.q[0]), initial=0.0)))

    @property
    def energy_error_max(self) -> float:
        """max |energy_error| over the run [J] (NaN without samples)."""
        return float(np.max(np.abs(self.energy_error))) if self.t.size else float("nan")

    @property
    def energy_error_relative(self) -> float:
        """max |energy_error| / energy_scale over the run."""
        return float(np.max(np.abs(self.energy_error)) / self.energy_scale) if self.t.size else float("nan")

    @property
    def energy_balance(self) -> tuple[float, str]:
        """The energy-balance error as the run summary reports it, and its unit.

        Returns
        -------
        value : float
            max |T + V - T0 - V0 - W| over the run, divided by :attr:`energy_scale`
            (dimensionless); in J when the energy scale is zero (a mechanism at rest, see
            :attr:`energy_scale_is_zero`). NaN without samples.
        unit : {"", "J"}
            ``""`` for the relative error, ``"J"`` for the absolute one.
        """
        if self.energy_scale_is_zero:
            return self.energy_error_max, "J"
        return self.energy_error_relative, ""

    @property
    def max_phi(self) -> float:
        """max over the run of max_i |Phi_i|."""
        return float(np.max(np.abs(self.phi), initial=0.0)) if self.t.size else float("nan")  # a tree: 0

    @property
    def max_phi_dot(self) -> float:
        """max over the run of max_i |(Phi_q qd)_i|."""
        return float(np.max(np.abs(self.phi_dot), initial=0.0)) if self.t.size else float("nan")

    def summary(self) -> str:
        """A short, human-readable account of the run (the plain text of :meth:`summary_items`)."""
        from csim.report import Fields

        return "\n".join(Fields(self.summary_items(), width=SUMMARY_WIDTH).plain())

    def summary_items(self) -> list[tuple[str, str]]:
        """The run's summary as (key, value) pairs: status, final state, constraint errors,
        energy balance, drives, events, cost."""
        items = [("status", f"{self.status} ({self.message})")]
        if self.t.size:
            names = self.coordinate_names
            # a failed run's last sample is the last good one: the failing step is not recorded
            items.append(("final time" if self.ok else "last sample", f"{self.t[-1]:.6g} s"))
            items.append(("final q", ", ".join(f"{n} = {v:.8g}" for n, v in zip(names, self.q[-1]))))
            items.append(("final qd", ", ".join(f"{n} = {v:.8g}" for n, v in zip(names, self.qd[-1]))))
            items.append(("max |Phi|", f"{self.max_phi:.3e}"))
            items.append(("max |Phi_q qd|", f"{self.max_phi_dot:.3e}"))
            if self.run_kind == "kinematic":
                items.append(("energy balance", "- (a kinematic analysis of prescribed motion: no forces)"))
            elif self.energy_balance[1] == "J":
                why = ("the mechanism stays at rest" if self.stays_at_rest else
                       "the mechanism moves without kinetic or potential energy: its moving links have no mass"
                       if self.energy_is_zero else
                       "the mechanism moves, but its energies change by less than 1e-9 of the largest it records")
                items.append(("energy balance", f"{self.energy_balance[0]:.3e} J (max |T + V - T0 - V0 - W|, in J: "
                                                f"the energy scale is zero, {why})"))
            else:
                items.append(("energy balance", f"{self.energy_balance[0]:.3e} (max |T + V - T0 - V0 - W|"
                                                f" / {self.energy_scale:.4g} J)"))
            if self.removed_names and self.removed_phi is not None:
                worst = np.nanmax(np.abs(self.removed_phi), axis=0, initial=0.0)
                items.append(("removed equations", ", ".join(
                    f"{n}: max |Phi| = {w:.3e}" for n, w in zip(self.removed_names, worst))))
        for text in self.warnings:
            items.append(("warning", text))
        if self.drive_forces is not None and self.t.size:
            items.append(("drives", ", ".join(
                f"{n}: max |force| = {np.nanmax(np.abs(self.drive_forces[:, j])):.6g} {u}"
                for j, (n, u) in enumerate(zip(self.drive_names, self.drive_units)))))
        items.append(("events", f"{len(self.event_times)}"))
        items.append(("wall time", f"{self.wall_time:.3f} s ({self.backend} backend)"))
        if self.backend_reason:
            items.append((f"{self.backend} backend", f"not compiled because {self.backend_reason}"))
        if self.backend == "compiled" and self.kernel_load_time > COMPILE_NOTICE:
            items.append(("compilation", f"{self.kernel_load_time:.1f} s before the run (the first run of this "
                                         f"mechanism, or of this csim installation: the kernels are compiled once; "
                                         f"later runs load them from the cache)"))
        items.append(("RHS evaluations", f"{self.nfev} ({self.nsteps} steps)"))
        return items
