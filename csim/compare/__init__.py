"""Compare stabilization methods on one case: accuracy, constraint errors and cost.

:func:`compare` runs a case once per method of :data:`csim.solver.stabilizers.STABILIZERS`
(``stabilization.method`` set to each), optionally at several tolerances (a work-precision
study), and one tight-tolerance reference run of the same case. The runs go to separate
processes when there are several jobs. Each run is measured against the reference:

motion error
    max over the output times t_k and the coordinates i of |q_i(t_k) - q_ref_i(t_k)|
    [rad or m, the coordinates' own units]; a run that stopped early is measured over the
    output times it reached (``error_until``).
final error
    max over i of |q_i(t_end) - q_ref_i(t_end)|; NaN for a run that did not reach t_end.
constraint errors
    max |Phi| over the run, |Phi| at its last sample, and max |Phi_q qd| over the run.
cost
    wall time [s] (measured in the worker, so parallel runs share the CPU), right-hand-side
    evaluations and accepted steps.

A run that fails (blow-up, Newton failure, an exception) becomes a row with status
``failed`` and its numbers up to the failure; the other runs go on.

The package, one concern per module:

``specs``
    method specs (``METHOD:INTEGRATOR``) and tolerance values: checked, parsed, as text.
``plan``
    which runs: the validated case of every (method, tolerance) and of the reference.
``pool``
    running them, in this process or in worker processes; Ctrl-C.
``metrics``
    the figures of merit from a run's arrays: constraint and motion errors.
``runs``
    :class:`Run`, one run and its figures of merit.
``table``
    the comparison as text.
``files``
    the comparison file.
``comparison``
    :func:`compare` and the :class:`Comparison` it returns.

Every name is importable from ``csim.compare`` itself. The runs call
``csim.compare.run_case`` (:func:`csim.pipeline.run_case`), looked up here at each run, so
that a test may replace it on this package.
"""
from __future__ import annotations

from csim.compare.comparison import Comparison, compare
from csim.compare.metrics import NAN
from csim.compare.plan import ReferenceSettings
from csim.compare.runs import INTERRUPTED, Run
from csim.compare.specs import (
    check_methods,
    check_tolerances,
    default_methods,
    parse_methods,
    parse_tolerances,
    split_method,
    tol_text,
)
from csim.pipeline import run_case as run_case  # what the runs call: see above

__all__ = ["INTERRUPTED", "NAN", "Comparison", "ReferenceSettings", "Run", "check_methods", "check_tolerances",
           "compare", "default_methods", "parse_methods", "parse_tolerances", "split_method", "tol_text"]
