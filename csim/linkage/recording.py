"""What a run of a link-coupling mechanism records beyond the generic result: the drive
forces of driven dynamics (:mod:`csim.solver.driven`), the reactions of the cut joints (from
the multipliers) and those of the tree joints (Newton-Euler of the links beyond each,
:mod:`csim.linkage.reactions`), after the run."""
from __future__ import annotations

from csim.linkage.reactions import joint_reactions, tree_reactions

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
        record_drives(result, system, trajectory.t, trajectory.y, trajectory.mode, list(linkage.drive_names), units)
    if not result.t.size:
        return
    cut = joint_reactions(linkage, case.mechanism, system.par, result.q, result.lam) if linkage.plan.cut_joints \
        else []
    run = {"q": result.q, "qd": result.qd, "qdd": result.qdd, "loads": result.loads,
           "drive_forces": result.drive_forces}
    result.reactions = cut + tree_reactions(linkage, case.mechanism, case.data["mechanism"].get("forces"), system.par,
                                            run, cut)
