"""What a run of a link-coupling mechanism records beyond the generic result: the drive
forces of driven dynamics (:mod:`csim.solver.driven`) and the reactions of the cut joints
(:mod:`csim.linkage.reactions`), both from the multipliers after the run."""
from __future__ import annotations

from csim.linkage.reactions import joint_reactions

#: unit of a drive's force, by the unit of its joint variable
DRIVE_UNITS = {"rad": "N m", "m": "N"}


def linkage_outputs(case, system, trajectory, result) -> None:
    """Add the drive forces (driven dynamics) and the cut-joint reactions to ``result``.

    Parameters
    ----------
    case : csim.case.Case
        A link-coupling case (``case.linkage`` set).
    system : ConstrainedSystem or DrivenSystem
        What integrated the run (its parameter vector ``par``).
    trajectory : csim.solver.settings.Trajectory
        The run's samples (t (N,), y (N, n_state), mode (N, n_switches)).
    result : csim.result.Result
        The assembled result, changed in place.
    """
    linkage = case.linkage
    if case.driven:
        from csim.solver.driven import record_drives

        units = [DRIVE_UNITS.get(case.mechanism.coordinate_units[i], "") for i in linkage.driven_indices]
        record_drives(result, system, trajectory.t, trajectory.y, trajectory.mode, list(linkage.drive), units)
    if linkage.topology.cut_joints and result.t.size:
        result.reactions = joint_reactions(linkage, case.mechanism, system.par, result.q, result.lam)
