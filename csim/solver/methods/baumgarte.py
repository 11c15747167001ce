"""``baumgarte``: Baumgarte's damped oscillator on the constraints.

    Phi'' + 2 d w Phi' + w^2 Phi = 0,   so   gamma* = gamma - 2 d w Phi' - w^2 Phi.
"""
from __future__ import annotations

import cmath
import dataclasses

import numpy as np

from csim.physics.jit import kernel
from csim.solver.methods.base import ErrorMode, Method, _gain_array, option, per_constraint


@kernel
def baumgarte_gamma_star(r, gamma, phi, phi_dot, gains, fpar, ipar, out):
    """gamma*_i = gamma_i - 2 d_i w_i Phi'_i - w_i^2 Phi_i, with gains = [d (r), w (r)]."""
    for i in range(r):
        d, w = gains[i], gains[r + i]
        out[i] = gamma[i] - 2.0 * d * w * phi_dot[i] - w**2 * phi[i]


@dataclasses.dataclass(frozen=True)
class BaumgarteOptions:
    d: object = option(1.0, "damping ratio (1 = critical, fastest decay without overshoot)", gain=True)
    w: object = option(10.0, "natural frequency; Phi decays like exp(-d w t). Well above 1/t_end; with RK4, w h "
                       "below 2.5 (its stability bound is w h = 2.785 for d = 1, and csim warns beyond 0.9 of it)",
                       "1/s", gain=True)


class Baumgarte(Method):
    """Baumgarte's damped oscillator on the constraints.

    Parameters
    ----------
    d : float or array (r,)
        Damping ratio, 0 < d (1 = critical damping, the fastest decay without overshoot).
    w : float or array (r,)
        Natural frequency [1/s]; Phi decays like exp(-d w t).
    """

    name = "baumgarte"
    rank = 10
    Options = BaumgarteOptions
    compiled = True
    gamma_star_kernel = staticmethod(baumgarte_gamma_star)

    def __init__(self, d=1.0, w=10.0):
        super().__init__(d=d, w=w)
        self.d, self.w = np.asarray(d, dtype=float), np.asarray(w, dtype=float)

    def gains(self, r):
        return [_gain_array(self.d, r), _gain_array(self.w, r)]

    def error_modes(self):
        """lambda^2 + 2 d w lambda + w^2 = 0: lambda = w (-d +- sqrt(d^2 - 1)) per constraint."""
        modes = []
        for i, (d, w) in per_constraint(self.d, self.w):
            shapes = dict.fromkeys((-d + cmath.sqrt(d * d - 1.0), -d - cmath.sqrt(d * d - 1.0)))
            modes += [ErrorMode("stabilization.w", w, shape, f"d = {d:g}", i) for shape in shapes]
        return modes
