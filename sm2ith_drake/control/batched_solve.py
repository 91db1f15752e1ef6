"""Many small dense linear systems solved at once, compiled (numba).

HPIPM's data path (control/hpipm_stage_qp.py) solves the dynamics rows of
every step for the next knot's states: K systems of 18–24 unknowns with
~60 right-hand sides per stage QP. ``np.linalg.solve`` on the stack spent
0.3–0.6 ms per QP in LAPACK's per-matrix overhead; this is the same
Gaussian elimination with partial pivoting (LAPACK's getrf/getrs) in one
compiled loop.

``cache=True`` keeps the machine code next to this file, as
humans/kernels.py does.
"""

import numba
import numpy as np


def solve_batched(M: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """X with M[k] @ X[k] = rhs[k] for the stacks M (K, m, m) and rhs
    (K, m, r).

    Raises:
        np.linalg.LinAlgError: a singular (or non-finite) M[k].
    """
    M = np.array(M, dtype=float, order="C")  # factored in place (a copy)
    X = np.array(rhs, dtype=float, order="C")
    if M.ndim != 3 or M.shape[1] != M.shape[2] or X.shape[:2] != M.shape[:2]:
        raise ValueError(f"shapes {M.shape} and {np.shape(rhs)} do not match")
    if not np.all(np.isfinite(M)) or not _LuSolve(M, X):
        raise np.linalg.LinAlgError("Singular or non-finite matrix")
    return X


@numba.njit(cache=True)
def _LuSolve(M, X):  # pragma: no cover
    """Overwrites X with M⁻¹X (and M with its factors), matrix by matrix.
    False if a pivot is zero."""
    K, m, r = X.shape
    for k in range(K):
        A = M[k]
        B = X[k]
        for j in range(m):
            # Partial pivoting: the largest entry of column j at or below j.
            p = j
            best = abs(A[j, j])
            for i in range(j + 1, m):
                if abs(A[i, j]) > best:
                    best = abs(A[i, j])
                    p = i
            if not (best > 0.0):
                return False
            if p != j:
                for c in range(m):
                    A[j, c], A[p, c] = A[p, c], A[j, c]
                for c in range(r):
                    B[j, c], B[p, c] = B[p, c], B[j, c]
            pivot = A[j, j]
            for i in range(j + 1, m):
                f = A[i, j] / pivot
                if f != 0.0:
                    for c in range(j + 1, m):
                        A[i, c] -= f * A[j, c]
                    for c in range(r):
                        B[i, c] -= f * B[j, c]
        # Back substitution, row by row (zeros of the factor skipped: the
        # dynamics blocks are mostly identity).
        for j in range(m - 1, -1, -1):
            for i in range(j + 1, m):
                a = A[j, i]
                if a != 0.0:
                    for c in range(r):
                        B[j, c] -= a * B[i, c]
            inv = 1.0 / A[j, j]
            for c in range(r):
                B[j, c] *= inv
    return True
