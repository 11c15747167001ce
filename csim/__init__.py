"""csim: simulation of constrained multibody mechanisms in redundant coordinates.

The pipeline, one layer per subpackage::

    case file (csim.case) -> model (csim.model, csim.mechanisms)
      -> formulation and stabilizer (csim.solver) -> integrator (csim.solver.integrators)
      -> result (csim.result) -> HDF5 (csim.io) / plots

``csim.load(path)`` reads a result, comparison or sweep file into xarray and pandas
(:func:`csim.api.load`; the optional extra ``data``).
"""
from importlib.metadata import PackageNotFoundError, version

#: the distribution's name on the package index (the command is ``csim``)
DIST_NAME = "csim-multibody"

try:
    __version__ = version(DIST_NAME)
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"


def load(path, group=None):
    """Read a csim result, comparison or sweep file (:func:`csim.api.load`)."""
    from csim.api import load as _load

    return _load(path, group)
