"""Small dense linear algebra: LU with partial pivoting, in place (LAPACK getrf/getrs order).

The systems of a mechanism are small (a few to a few dozen unknowns), where a plain loop
beats a LAPACK call through its wrapper. Both backends solve every KKT and projection
system with these two functions, so they agree to the last bit.

Matrices are passed as flat row-major arrays (an n x n matrix A is A_flat[i * n + j]):
compiled, a 1-D slice of a workspace is free where a reshaped 2-D view costs tens of ns.
"""
from __future__ import annotations

import numpy as np

from csim.physics.jit import inline_kernel


def _python_quotient(a, b):
    """a / b as compiled code divides: complex numbers by CPython's algorithm (``_Py_c_quot``, which
    numba's complex division is), not numpy's, whose complex128 scalars round otherwise."""
    if isinstance(a, complex) or isinstance(b, complex):  # (numpy's complex128 is a complex)
        return complex(a) / complex(b)
    return a / b


@inline_kernel(python=_python_quotient)
def quotient(a, b):
    """a / b. Where it runs as Python (the interpreted kernels), numpy's complex128 scalars divide
    otherwise than numba does: the interpreted Radau, whose complex LU divides them, took other
    steps than the compiled one."""
    return a / b


def as_core(a) -> np.ndarray:
    """``a`` (a vector or a matrix) as the core functions take it: C-contiguous float64, flat row-major.

    No copy where ``a`` already is one (a matrix's ``ravel`` is then a view).
    """
    return np.ascontiguousarray(a, dtype=float).ravel()


@inline_kernel
def lu_factor(A, n, piv):
    """Factor A (n * n, row-major) in place into L (unit lower, below the diagonal) and U; pivots into piv.

    Returns False if a pivot is exactly zero (A singular), True otherwise.
    """
    for c in range(n):
        p = c
        big = abs(A[c * n + c])
        for i in range(c + 1, n):
            v = abs(A[i * n + c])
            if v > big:
                big = v
                p = i
        piv[c] = p
        if A[p * n + c] == 0.0:
            return False
        if p != c:
            for j in range(n):
                tmp = A[c * n + j]
                A[c * n + j] = A[p * n + j]
                A[p * n + j] = tmp
        inv = quotient(1.0, A[c * n + c])
        for i in range(c + 1, n):
            A[i * n + c] *= inv
            lic = A[i * n + c]
            if lic != 0.0:
                for j in range(c + 1, n):
                    A[i * n + j] -= lic * A[c * n + j]
    return True


@inline_kernel
def lu_solve(A, n, piv, b):
    """Solve A x = b with the factors of :func:`lu_factor`; b (n,) is overwritten by x."""
    for c in range(n):
        p = piv[c]
        if p != c:
            tmp = b[c]
            b[c] = b[p]
            b[p] = tmp
    for i in range(n):  # L y = P b
        s = b[i]
        for j in range(i):
            s -= A[i * n + j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):  # U x = y
        s = b[i]
        for j in range(i + 1, n):
            s -= A[i * n + j] * b[j]
        b[i] = quotient(s, A[i * n + i])
