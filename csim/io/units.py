"""Units of everything csim records: the one place they are documented.

csim works in SI units throughout. Coordinates are angles [rad] or lengths [m], as each
mechanism declares (``coordinate_units`` attribute of ``q`` in a result file); the units
of velocity-like and acceleration-like arrays follow from those per column.
"""

#: dataset path in a result file -> unit (``per coordinate`` means: see the dataset's
#: ``units`` attribute, one entry per column)
UNITS: dict[str, str] = {
    "t": "s",
    "q": "per coordinate: rad or m",
    "qd": "per coordinate: rad/s or m/s",
    "qdd": "per coordinate: rad/s^2 or m/s^2",
    "lambda": "per constraint: N or N m divided by the constraint's unit (Phi_q^T lambda is a generalized force)",
    "phi": "per constraint: unit of the constraint function (m for the quick-return mechanism)",
    "phi_dot": "per constraint: unit of the constraint function per s",
    "energy/kinetic": "J",
    "energy/potential": "J",
    "energy/work": "J, one column per load",
    "energy/balance_error": "J: T + V - (T0 + V0) - sum of load work",
    "forces/loads": "per load: N or N m",
    "forces/generalized": "per coordinate: N m for angles, N for lengths",
    "forces/drive": "per drive: N m for a rotation, N for a translation; the torque or force the drive "
                    "applies along its joint variable (driven dynamics)",
    "energy/drive_work": "J, one column per drive: the work of the drive since t = 0",
    "reactions": "the force and the moment that link i exerts on link j of the joint (i, k)-(j, m), at the "
                 "origin of joint frame jm; link i receives the opposite",
    "reactions/force_global": "N, in the fixed frame's axes",
    "reactions/force_joint": "N, in the axes of joint frame ik",
    "reactions/torque_global": "N m, about the origin of joint frame jm, in the fixed frame's axes",
    "reactions/torque_joint": "N m, about the origin of joint frame jm, in the axes of joint frame ik",
    "events/times": "s",
    "wall_time": "s",
}
