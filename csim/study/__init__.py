"""Parameter studies: ``csim sweep`` runs one case over a grid or a random design of case
values and records each run's outcome and figures of merit in one file.

Modules, in the order of the pipeline: ``values`` (what ``--vary`` means), ``plan`` (the
runs), ``execute`` (where they run: this process, worker processes, a Dask cluster),
``metrics`` (what is recorded of each run), ``sweep`` (checkpoints, resume, the file).
"""
from csim.study.metrics import COLUMNS, failure_reason
from csim.study.plan import SAMPLINGS, SweepPlan, make_plan
from csim.study.sweep import Sweep, run_sweep
from csim.study.values import Variation, parse_variation

__all__ = ["COLUMNS", "SAMPLINGS", "Sweep", "SweepPlan", "Variation", "failure_reason", "make_plan",
           "parse_variation", "run_sweep"]
