"""``baumgarte``: Baumgarte's damped oscillator on the constraints.

    Phi'' + 2 d w Phi' + w^2 Phi = 0,   so   gamma* = gamma - 2 d w Phi' - w^2 Phi.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from csim.physics.jit import kernel
from csim.solver.methods.base import Method, _gain_array, option


@kernel
def baumgarte_gamma_star(r, gamma, phi, phi_dot, gains, fpar, ipar, out):
    """gamma*_i = gamma_i - 2 d_i w_i Phi'_i - w_i^2 Phi_i, with gains = [d (r), w (r)]."""
    for i in range(r):
        d, w = gains[i], gains[r + i]
        out[i] = gamma[i] - 2.0 * d * w * phi_dot[i] - w**2 * phi[i]


@dataclasses.dataclass(frozen=True)
class BaumgarteOptions:
    d: object = option(1.0, "damping ratio (1 = critical, fastest decay without overshoot)", gain=True)
    w: object = option(10.0, "natural frequency; Phi decays like exp(-d w t). Well above 1/t_end, and w h << 2.8 "
                       "for explicit steps h", "1/s", gain=True)


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
