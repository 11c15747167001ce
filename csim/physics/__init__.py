"""The numeric core that both backends run: plain array functions, written once.

Every function here works on NumPy arrays and scalars only, in the subset of Python that
numba compiles. The Python driver (:mod:`csim.solver`) calls them directly; the compiled
kernels (:mod:`csim.fast.kernels`) call the very same functions from inside their step
loops. Neither backend restates what is here.

``jit``         the ``kernel`` decorator (numba's njit when numba loads, the plain function otherwise)
``status``      status codes of a run and the one message each gives
``linalg``      small dense LU with partial pivoting (LAPACK's getrf/getrs order of operations)
``switching``   sgn and its smooth replacements, by code
``loads``       switched load laws: switching functions, load values, the mode
``kkt``         the augmented (KKT) system M qdd + Phi_q^T lambda = p, Phi_q qdd = gamma*
``projection``  Gauss-Newton correction onto Phi = 0 and Phi_q qd = 0, the round-off stop
``steps``       the divergence checks after an accepted step
``events``      the chatter check on the event times (events piling up at one instant)
"""
