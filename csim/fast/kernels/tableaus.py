"""The explicit pairs' coefficients as the kernels' constants: scipy's DOP853 arrays, and
the 5(4) pairs and Verner's 7(6) pair of :mod:`csim.physics.tableaus`.
"""
import importlib.util
import os

import numpy as np

from csim.physics.tableaus import (
    RK45_A,
    RK45_B,
    RK45_C,
    RK45_E,
    RK45_P,
    TSIT5_A,
    TSIT5_B,
    TSIT5_C,
    TSIT5_E,
    TSIT5_P,
    VERN7_A,
    VERN7_A_EXTRA,
    VERN7_B,
    VERN7_C,
    VERN7_C_EXTRA,
    VERN7_E,
    VERN7_P,
)


def _dop853_coefficients():
    """scipy's own DOP853 coefficient module, loaded as a file: importing it through its
    package would import all of scipy.integrate (half a second) for a table of numbers."""
    scipy_dir = os.path.dirname(importlib.util.find_spec("scipy").origin)
    path = os.path.join(scipy_dir, "integrate", "_ivp", "dop853_coefficients.py")
    spec = importlib.util.spec_from_file_location("_csim_dop853_coefficients", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


_dop = _dop853_coefficients()


# DOP853 coefficients, the very arrays scipy's DOP853 uses
DOP_NS = _dop.N_STAGES  # 12
DOP_A = np.ascontiguousarray(_dop.A[:DOP_NS, :DOP_NS])
DOP_B = np.ascontiguousarray(_dop.B)
DOP_C = np.ascontiguousarray(_dop.C[:DOP_NS])
DOP_E3 = np.ascontiguousarray(_dop.E3)
DOP_E5 = np.ascontiguousarray(_dop.E5)
DOP_D = np.ascontiguousarray(_dop.D)
DOP_A_EXTRA = np.ascontiguousarray(_dop.A[DOP_NS + 1:])
DOP_C_EXTRA = np.ascontiguousarray(_dop.C[DOP_NS + 1:])
DOP_NX = _dop.N_STAGES_EXTENDED  # 16
DOP_POWER = _dop.INTERPOLATOR_POWER  # 7


# the 5(4) pairs, stacked (index 0: RK45, 1: Tsit5), A and B padded to ERK_NS stages
ERK_NS = 6
ERK_A = np.ascontiguousarray(np.stack([np.pad(a, ((0, 0), (0, ERK_NS - a.shape[1]))) for a in (RK45_A, TSIT5_A)]))
ERK_B = np.ascontiguousarray(np.stack((RK45_B, TSIT5_B)))
ERK_C = np.ascontiguousarray(np.stack((RK45_C, TSIT5_C)))
ERK_E = np.ascontiguousarray(np.stack((RK45_E, TSIT5_E)))
ERK_P = np.ascontiguousarray(np.stack((RK45_P, TSIT5_P)))
# Verner's 7(6) pair: ten stages, the new point, five extra stages for its interpolant
V7_NS = VERN7_C.size
V7_A = np.ascontiguousarray(VERN7_A)
V7_B = np.ascontiguousarray(VERN7_B)
V7_C = np.ascontiguousarray(VERN7_C)
V7_E = np.ascontiguousarray(VERN7_E)
V7_A_EXTRA = np.ascontiguousarray(VERN7_A_EXTRA)
V7_C_EXTRA = np.ascontiguousarray(VERN7_C_EXTRA)
V7_P = np.ascontiguousarray(VERN7_P)
