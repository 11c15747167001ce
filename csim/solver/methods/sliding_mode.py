"""``sliding_mode``: the paper's sliding-mode stabilization.

    s = Phi' + Lambda Phi,   s' = -K s - k sw(s),
    so   gamma* = gamma - Lambda Phi' - K s - k sw(s),

with sw the sign function or one of its smooth replacements (:mod:`csim.physics.switching`).
On s = 0, Phi decays like exp(-Lambda t).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from csim.physics.jit import kernel
from csim.physics.switching import SLOPE_KEYS, SWITCHING_NAMES, slope_at_zero, switch
from csim.solver.methods.base import ErrorMode, Method, _gain_array, option, per_constraint


@kernel
def sliding_mode_gamma_star(r, gamma, phi, phi_dot, gains, fpar, ipar, out):
    """gamma*_i = gamma_i - Lambda_i Phi'_i - K_i s_i - k_i sw(s_i), s_i = Phi'_i + Lambda_i Phi_i.

    gains = [Lambda (r), K (r), k (r)]; ipar[0] the switching function's code, fpar[0] its width.
    """
    for i in range(r):
        lam, K, k = gains[i], gains[r + i], gains[2 * r + i]
        s = phi_dot[i] + lam * phi[i]
        out[i] = gamma[i] - lam * phi_dot[i] - K * s - k * switch(ipar[0], s, fpar[0])


@dataclasses.dataclass(frozen=True)
class SlidingModeOptions:
    Lambda: object = option(10.0, "slope of s = Phi' + Lambda Phi; on s = 0, Phi decays like exp(-Lambda t)",
                            "1/s", gain=True)
    K: object = option(10.0, "linear reaching gain, s decays like exp(-K t)", "1/s", gain=True)
    k: object = option(1e-6, "switching gain, small: it only has to beat the integration error's drift of s",
                       "unit of Phi/s^2", gain=True)
    switching: str = option("tanh", "sgn, or a smooth replacement: sat, tanh, atan, sqrt",
                            choices=tuple(SWITCHING_NAMES))
    eps: float = option(1e-6, "boundary-layer width of sat and sqrt", "unit of Phi/s", gt=0.0)
    c: float = option(1e6, "steepness of tanh and atan", "s/unit of Phi", gt=0.0)


class SlidingMode(Method):
    """The paper's sliding-mode stabilization.

    Parameters
    ----------
    Lambda : float or array (r,)
        Slope of the sliding surface s = Phi' + Lambda Phi [1/s]; on s = 0, Phi decays like
        exp(-Lambda t).
    K : float or array (r,)
        Linear reaching gain [1/s]: s decays like exp(-K t) away from s = 0.
    k : float or array (r,)
        Switching gain [unit of Phi / s^2]: drives s to zero in finite time.
    switching : {"sgn", "sat", "tanh", "atan", "sqrt"}
        The switching function: sgn itself or one of its smooth replacements.
    eps : float
        Boundary-layer width of ``sat`` and ``sqrt`` [unit of Phi / s].
    c : float
        Steepness of ``tanh`` and ``atan`` [s / unit of Phi].
    """

    name = "sliding_mode"
    rank = 20
    Options = SlidingModeOptions
    compiled = True
    gamma_star_kernel = staticmethod(sliding_mode_gamma_star)

    def __init__(self, Lambda=10.0, K=10.0, k=1e-6, switching="tanh", eps=1e-6, c=1e6):
        super().__init__(Lambda=Lambda, K=K, k=k, switching=switching, eps=eps, c=c)
        if switching not in SWITCHING_NAMES:
            raise ValueError(f"switching must be one of {', '.join(SWITCHING_NAMES)}; got {switching!r}")
        self.Lambda, self.K, self.k = (np.asarray(g, dtype=float) for g in (Lambda, K, k))
        self.switching = switching
        self.width = {"eps": eps, "c": c, None: None}[SWITCHING_NAMES[switching]]

    def sliding_variable(self, phi, phi_dot):
        """s = Phi' + Lambda Phi."""
        return phi_dot + self.Lambda * phi

    def gains(self, r):
        return [_gain_array(self.Lambda, r), _gain_array(self.K, r), _gain_array(self.k, r)]

    def parameters(self):
        code = list(SWITCHING_NAMES).index(self.switching)
        return [1.0 if self.width is None else float(self.width)], [code]

    def error_modes(self):
        """Near s = 0: Phi' = s - Lambda Phi and s' = -(K + k sw'(0)) s, so lambda = -Lambda and
        -(K + k sw'(0)) per constraint; once sw has saturated (sgn: always), s' = -K s -+ k, rate -K."""
        slope = slope_at_zero(self.switching, self.width)
        modes = []
        for i, (lam, K, k) in per_constraint(self.Lambda, self.K, self.k):
            modes += [ErrorMode("stabilization.Lambda", lam, -1.0, "", i), ErrorMode("stabilization.K", K, -1.0, "", i)]
            if slope < np.inf and k > 0:  # sw saturates at +-1: beyond the region s chatters, it does not grow
                modes.append(ErrorMode(f"(stabilization.K + stabilization.k {SLOPE_KEYS[self.switching]})",
                                       K + k * slope, -1.0, f"switching {self.switching}", i,
                                       saturates=f"s chatters in a band about k h wide instead of settling "
                                                 f"(as with sgn), since {self.switching} saturates"))
        return modes
