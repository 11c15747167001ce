"""An independent reference for the quick-return mechanism: minimal coordinates.

Written for the tests, sharing nothing with csim's model layer or driver. The only
coordinate is the crank angle q1; the rocker and rod angles follow in closed form from the
loop equations (the rocker line passes through the crank pin A; D stays at height h2,
branch cos q3 < 0). Lagrange's equation of the second kind in q1,

    m*(q1) q1'' + 1/2 dm*/dq1 q1'^2 + dV*/dq1 = M + F dx_D/dq1,

is integrated by scipy's solve_ivp (DOP853) with terminal events at the switching instants
of the cutting force.
"""
from __future__ import annotations

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

BRIEF = dict(l1=1.5, l2=4.0, l3=1.9, h1=2.0, h2=4.0, a1=0.0, a2=2.0, a3=0.95,
             m1=4000.0, m2=100.0, m3=30.0, m4=5.0, m5=50.0,
             J1=4000.0, J2=100.0, J3=10.0, J4=0.05, g=9.81)


def closed_form(q1, p=BRIEF):
    """Rocker and rod angles (q2, q3) from the crank angle in closed form."""
    ax, ay = p["l1"] * np.cos(q1), p["h1"] + p["l1"] * np.sin(q1)
    q2 = np.arctan2(ay, ax)
    q3 = np.pi - np.arcsin((p["h2"] - p["l2"] * np.sin(q2)) / p["l3"])
    return q2, q3


class MinimalQuickReturn:
    """1-DOF model of the quick-return mechanism in the crank angle.

    Parameters
    ----------
    torque : float
        Constant crank torque [N m].
    force : float
        Cutting force magnitude [N] (0 switches it off).
    window : (float, float)
        x_D interval where the force may act [m]; it acts while v_D < 0.
    """

    def __init__(self, torque=165521.0, force=200000.0, window=(-4.0, 1.2), p=BRIEF):
        self.torque, self.force, self.window = torque, force, window
        x = sp.Symbol("x", real=True)  # the crank angle
        s = {k: sp.Float(v) for k, v in p.items()}
        ax, ay = s["l1"] * sp.cos(x), s["h1"] + s["l1"] * sp.sin(x)
        q2 = sp.atan2(ay, ax)
        q3 = sp.pi - sp.asin((s["h2"] - s["l2"] * sp.sin(q2)) / s["l3"])
        C = (s["l2"] * sp.cos(q2), s["l2"] * sp.sin(q2))
        D = (C[0] + s["l3"] * sp.cos(q3), C[1] + s["l3"] * sp.sin(q3))
        # (mass, inertia, centre of mass, angle) per body, all functions of the crank angle
        bodies = [
            (s["m1"], s["J1"], (s["a1"] * sp.cos(x), s["h1"] + s["a1"] * sp.sin(x)), x),
            (s["m2"], s["J2"], (s["a2"] * sp.cos(q2), s["a2"] * sp.sin(q2)), q2),
            (s["m3"], s["J3"], (C[0] + s["a3"] * sp.cos(q3), C[1] + s["a3"] * sp.sin(q3)), q3),
            (s["m4"], s["J4"], (ax, ay), q2),
            (s["m5"], 0, (D[0], s["h2"]), 0),  # the ram only translates at the guide height
        ]
        # generalized mass m*(q1) = sum m |dr/dq1|^2 + J (dtheta/dq1)^2
        mstar = sum(m * (sp.diff(r[0], x) ** 2 + sp.diff(r[1], x) ** 2) + J * sp.diff(th, x) ** 2
                    for m, J, r, th in bodies)
        V = sum(m * s["g"] * r[1] for m, J, r, th in bodies)
        xD_prime = sp.diff(D[0], x)
        self._mstar = sp.lambdify(x, mstar, "math", cse=True)
        self._mstar_prime = sp.lambdify(x, sp.diff(mstar, x), "math", cse=True)
        self._V_prime = sp.lambdify(x, sp.diff(V, x), "math", cse=True)
        self._xD = sp.lambdify(x, D[0], "math", cse=True)
        self._xD_prime = sp.lambdify(x, xD_prime, "math", cse=True)
        self._V = sp.lambdify(x, V, "math", cse=True)

    def switching(self, y):
        """Switching functions, each > 0 where its condition holds."""
        xD, vD = self._xD(y[0]), self._xD_prime(y[0]) * y[1]
        return np.array([xD - self.window[0], self.window[1] - xD, -vD])

    def rhs(self, t, y, active):
        q, w = y[0], y[1]
        F = self.force if active else 0.0
        Q = self.torque + F * self._xD_prime(q)
        wdd = (Q - 0.5 * self._mstar_prime(q) * w**2 - self._V_prime(q)) / self._mstar(q)
        return [w, wdd]

    def solve(self, q1_0=3.0020, w0=6.2832, t_end=5.0, rtol=1e-12, atol=1e-12, t_eval=None):
        """Integrate; returns (t (N,), y (N, 2), event times)."""
        flags = self.switching([q1_0, w0]) > 0
        t, y = 0.0, np.array([q1_0, w0])
        ts, ys, events = [t], [y], []
        while t < t_end:
            def make_event(j):
                def event(t_, y_, active):
                    return self.switching(y_)[j]
                event.terminal = True
                event.direction = -1.0 if flags[j] else 1.0  # leave the side it is on
                return event

            evs = [make_event(j) for j in range(3)]
            sol = solve_ivp(self.rhs, (t, t_end), y, method="DOP853", rtol=rtol, atol=atol,
                            events=evs, args=(bool(np.all(flags)),), dense_output=True)
            assert sol.status >= 0, sol.message
            if t_eval is not None:
                inside = t_eval[(t_eval > t) & (t_eval <= sol.t[-1])]
                ts.extend(inside)
                ys.extend(sol.sol(inside).T)
            t, y = sol.t[-1], sol.y[:, -1]
            if sol.status == 1:
                for j, te in enumerate(sol.t_events):
                    if te.size:
                        flags[j] = not flags[j]
                events.append(t)
        if t_eval is None:
            ts, ys = [t], [y]
        return np.array(ts), np.array(ys), events
