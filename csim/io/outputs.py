"""The per-sample output quantities of a run, one record each: name, unit, how a sample's
value is computed, where it goes in a result file, and which figure shows it.

A run records, at every output time, the states it integrated (q, qd, the work of the loads)
and what one evaluation of the equations of motion gives at that state (qdd, the
multipliers, the residuals, the loads, the generalized forces, the energies).
:data:`OUTPUTS` lists them; the pipeline sizes and fills the sample arrays from it
(:func:`csim.pipeline.run_case`, both backends: the compiled evaluation returns one array
per :attr:`Output.name` of the evaluated ones), and the HDF5 writer writes each one with its
unit and description (:func:`csim.io.hdf5.write_result_group`). A new output quantity is a
new record here, a field of :class:`csim.result.Result` and of the evaluation that
computes it (:class:`csim.solver.system.Evaluation` and the compiled
``evaluate_samples``); ``tests/test_outputs.py`` checks that each record is wired through.

Observables (one dataset per quantity the mechanism declares), drive forces and joint
reactions are written by their own code: their columns are named by the mechanism.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from csim.io.units import FORCE_UNIT, common_unit, multiplier_unit, per_time

#: units of a run's columns (:func:`csim.io.hdf5.run_units`): ``coordinate``, ``constraint``,
#: ``load``, each a list with one unit per column
ColumnUnits = dict[str, list[str]]


@dataclass(frozen=True)
class Output:
    """One per-sample output quantity.

    Attributes
    ----------
    name : str
        The :class:`csim.result.Result` field, and the name of its sample array.
    dataset : str
        Its path in a result file's run group.
    columns : {"coordinate", "constraint", "load", ""}
        What its columns run along (an HDF5 dimension scale); ``""`` for one value per sample.
    unit : callable
        The dataset's ``units`` from the run's column units (:data:`ColumnUnits`): one
        string, or a list with one unit per column where they differ.
    evaluation : str or None
        The :class:`csim.solver.system.Evaluation` field a sample's value is read from
        (None: a state the integration carried, or computed after the run).
    figure : str or None
        The ``csim plot`` figure that shows it, or the ``--series`` that draws it (None: in
        the file only).
    description : str
        The dataset's ``description`` attribute.
    """

    name: str
    dataset: str
    columns: str
    unit: Callable[[ColumnUnits], str | list[str]]
    evaluation: str | None
    figure: str | None
    description: str


def _coordinate(power: int) -> Callable[[ColumnUnits], str | list[str]]:
    return lambda u: common_unit([per_time(c, power) if power else c for c in u["coordinate"]])


def _fixed(unit: str) -> Callable[[ColumnUnits], str]:
    return lambda u: unit


#: every per-sample output quantity, in the order a result file lists them
OUTPUTS: tuple[Output, ...] = (
    Output("q", "q", "coordinate", _coordinate(0), None, "coordinates",
           "generalized coordinates, per coordinate: rad or m"),
    Output("qd", "qd", "coordinate", _coordinate(1), None, "velocities",
           "generalized velocities, per coordinate: rad/s or m/s"),
    Output("qdd", "qdd", "coordinate", _coordinate(2), "qdd", "--series qdd:NAME",
           "generalized accelerations, per coordinate: rad/s^2 or m/s^2"),
    Output("lam", "lambda", "constraint", lambda u: common_unit([multiplier_unit(c) for c in u["constraint"]]),
           "lam", "multipliers",
           "Lagrange multipliers, per constraint: N for a constraint in m (a position equation), N m for a "
           "dimensionless one (an orientation equation), J divided by the constraint's unit in general "
           "(Phi_q^T lambda is a generalized force)"),
    Output("phi", "phi", "constraint", lambda u: common_unit(u["constraint"]), "phi", "constraints",
           "constraint residuals Phi(q), per constraint: unit of the constraint function"),
    Output("phi_dot", "phi_dot", "constraint", lambda u: common_unit([per_time(c) for c in u["constraint"]]),
           "phi_dot", "constraints",
           "velocity-level residuals Phi_q qd, per constraint: unit of the constraint function per s"),
    Output("kinetic", "energy/kinetic", "", _fixed("J"), "kinetic", "energy", "kinetic energy T [J]"),
    Output("potential", "energy/potential", "", _fixed("J"), "potential", "energy", "potential energy V [J]"),
    Output("work", "energy/work", "load", _fixed("J"), None, "energy", "work of each load since t = 0 [J]"),
    Output("energy_error", "energy/balance_error", "", _fixed("J"), None, "energy",
           "T + V - (T0 + V0) - sum of load work [J]"),
    Output("loads", "forces/loads", "load", lambda u: common_unit(u["load"]), "u", "loads",
           "value u of each load: N or N m"),
    Output("generalized_forces", "forces/generalized", "coordinate",
           lambda u: common_unit([FORCE_UNIT.get(c, "") for c in u["coordinate"]]), "Q", None,
           "generalized forces Q = B u, per coordinate: N m for angles, N for lengths"),
)

#: the outputs one evaluation of the equations of motion gives, by name
EVALUATED: dict[str, Output] = {o.name: o for o in OUTPUTS if o.evaluation is not None}
