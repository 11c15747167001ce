"""csim: simulation of constrained multibody mechanisms in redundant coordinates.

The pipeline, one layer per subpackage::

    case file (csim.case) -> model (csim.model, csim.mechanisms)
      -> formulation and stabilizer (csim.solver) -> integrator (csim.solver.integrators)
      -> result (csim.result) -> HDF5 (csim.io) / plots
"""
from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("csim")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
