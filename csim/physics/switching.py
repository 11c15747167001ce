"""sgn and its smooth replacements, the switching functions sw(s) of the sliding-mode law.

Each is selected by a code (the position of its name in :data:`SWITCHING_NAMES`) and has
one width parameter: ``eps`` for sat and sqrt [unit of s], ``c`` for tanh and atan
[1 / unit of s]; sgn has none.
"""
from __future__ import annotations

import math

from csim.physics.jit import kernel

#: name -> the name of its width parameter (None: no width), in code order
SWITCHING_NAMES = {"sgn": None, "sat": "eps", "tanh": "c", "atan": "c", "sqrt": "eps"}
SGN, SAT, TANH, ATAN, SQRT = range(5)


@kernel
def switch(kind, s, width):
    """sw(s) for the switching function ``kind`` (a code) with its ``width``.

    sgn(s); sat(s / eps) = s / eps clipped to [-1, 1]; tanh(c s); (2/pi) arctan(c s);
    s / sqrt(s^2 + eps^2). Each tends to sgn(s) as eps -> 0 or c -> inf.
    """
    if kind == SGN:
        return 1.0 if s > 0 else (-1.0 if s < 0 else (0.0 if s == 0 else s))  # NaN stays NaN
    if kind == SAT:
        return min(1.0, max(-1.0, s / width))
    if kind == TANH:
        return math.tanh(width * s)
    if kind == ATAN:
        return 2.0 / math.pi * math.atan(width * s)
    return s / math.sqrt(s * s + width * width)


def slope_at_zero(name: str, width: float | None) -> float:
    """d sw / ds at s = 0 of the switching function ``name`` with its ``width``.

    Parameters
    ----------
    name : {"sgn", "sat", "tanh", "atan", "sqrt"}
    width : float or None
        eps for sat and sqrt [unit of s], c for tanh and atan [1 / unit of s].

    Returns
    -------
    float
        1/eps for sat and sqrt, c for tanh, 2 c / pi for atan; inf for sgn (a jump: no
        linear region around s = 0).
    """
    if name == "sgn":
        return math.inf
    if name in ("sat", "sqrt"):
        return 1.0 / width
    if name == "tanh":
        return float(width)
    if name == "atan":
        return 2.0 * float(width) / math.pi
    raise ValueError(f"unknown switching function {name!r}; valid names: {', '.join(SWITCHING_NAMES)}")


#: name -> k sw'(0) written with the case-file keys, after "stabilization.k" (sgn: none)
SLOPE_KEYS = {"sgn": None, "sat": "/ stabilization.eps", "tanh": "* stabilization.c",
              "atan": "* 2 stabilization.c / pi", "sqrt": "/ stabilization.eps"}
