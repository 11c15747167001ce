"""The stabilization methods by name: the registry of :mod:`csim.solver.methods`.

Every formulation solves ``Phi_q qdd = gamma*``; a method chooses gamma* and, for some,
what is integrated (``stabilization.method`` in a case file). Each method lives in its own
file under ``csim/solver/methods/``; this module gives their registry and classes one
import path.
"""
from __future__ import annotations

import numpy as np

from csim.physics.switching import SWITCHING_NAMES, switch
from csim.solver.methods import STABILIZERS, make_stabilizer, register
from csim.solver.methods.base import Method
from csim.solver.methods.baumgarte import Baumgarte
from csim.solver.methods.ggl import GGL
from csim.solver.methods.minimal import Minimal
from csim.solver.methods.none import NoStabilization
from csim.solver.methods.projection import Projection
from csim.solver.methods.sliding_mode import SlidingMode


def _vectorized(kind: int):
    """sw(s, width) of the switching function ``kind``, elementwise over an array s."""

    def sw(s, width):
        width = 1.0 if width is None else float(width)
        return np.vectorize(lambda x: switch(kind, float(x), width))(s)

    return sw


#: name -> (sw(s, width) on arrays, the name of its width parameter); sw approximates sgn
SWITCHING_FUNCTIONS = {name: (_vectorized(code), width) for code, (name, width) in enumerate(SWITCHING_NAMES.items())}

__all__ = ["GGL", "STABILIZERS", "SWITCHING_FUNCTIONS", "Baumgarte", "Method", "Minimal", "NoStabilization",
           "Projection", "SlidingMode", "make_stabilizer", "register"]
