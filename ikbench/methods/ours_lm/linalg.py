"""Block-tridiagonal linear algebra of the Gauss-Newton system (numpy and LAPACK).

The matrix has diagonal blocks (B, N, k, k) and off-diagonal blocks ``-coupling (B,) * I``:
a band matrix of half-bandwidth k, solved by banded Cholesky (LAPACK ``pbsv`` via scipy) or
a numpy block-Thomas elimination, vectorised over the batch.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class Blocks(Protocol):
    """J^T J by its blocks: ``diagonal`` (B, N, dof, dof) and ``coupling`` (B,) (the
    off-diagonal blocks are -coupling * I): a :class:`.problem.Evaluation` or a
    :class:`.torch_backend.TorchEvaluation`."""

    diagonal: Any
    coupling: Any


def solve_normal_equations(diagonal: np.ndarray, coupling: np.ndarray, rhs: np.ndarray,
                           free: np.ndarray, solver: str = "banded"
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Solve the block-tridiagonal system for the free variables.

    The matrix has diagonal blocks ``diagonal`` (B, N, k, k) and off-diagonal blocks
    ``-coupling (B,) * I``; rows and columns of variables with ``free`` (B, N, k) False are
    replaced by the identity (their step is 0).

    Returns:
        (steps (B, N, k), ok (B,) bool: False where the matrix was not positive definite).
    """
    b, n_poses, k = rhs.shape
    f = free.astype(float)
    diag = diagonal * f[..., :, None] * f[..., None, :]
    idx = np.arange(k)
    diag[..., idx, idx] += 1.0 - f
    off = coupling[:, None, None] * f[:, :-1] * f[:, 1:]          # (B, N-1, k), sign: -off
    rhs = rhs * f
    if solver == "banded":
        try:
            return _solve_banded(diag, off, rhs)
        except ImportError:
            pass
    return _solve_thomas(diag, off, rhs)


def _solve_banded(diag, off, rhs):
    from scipy.linalg.lapack import dpbsv

    b, n_poses, k = rhs.shape
    band = np.zeros((b, n_poses, k, k + 1))                      # [.., a, d] = A[ia+d, ia]
    for d in range(k):
        band[:, :, : k - d, d] = np.diagonal(diag, offset=-d, axis1=2, axis2=3)
    band[:, :-1, :, k] = -off
    band = band.reshape(b, n_poses * k, k + 1)
    out = np.empty((b, n_poses * k))
    ok = np.ones(b, dtype=bool)
    flat = rhs.reshape(b, -1)
    for t in range(b):
        _, x, info = dpbsv(band[t].T, flat[t], lower=1)
        ok[t] = info == 0
        out[t] = x if info == 0 else 0.0
    return out.reshape(b, n_poses, k), ok


def _solve_thomas(diag, off, rhs):
    """Block Thomas elimination, vectorised over the batch (numpy only)."""
    b, n_poses, k = rhs.shape
    inverses = np.empty_like(diag)
    y = np.empty_like(rhs)
    ok = np.ones(b, dtype=bool)
    schur, y_prev = diag[:, 0], rhs[:, 0]
    for i in range(n_poses):
        if i:
            c = off[:, i - 1]                                    # C = -diag(c)
            schur = diag[:, i] - c[:, :, None] * inverses[:, i - 1] * c[:, None, :]
            y_prev = rhs[:, i] + c * (inverses[:, i - 1] @ y[:, i - 1, :, None])[..., 0]
        ok &= np.all(np.linalg.eigvalsh(schur) > 0, axis=-1)
        inverses[:, i] = np.linalg.inv(np.where(ok[:, None, None], schur, np.eye(k)))
        y[:, i] = y_prev
    x = np.empty_like(rhs)
    x[:, -1] = (inverses[:, -1] @ y[:, -1, :, None])[..., 0]
    for i in range(n_poses - 2, -1, -1):
        x[:, i] = (inverses[:, i] @ (y[:, i] + off[:, i] * x[:, i + 1])[..., None])[..., 0]
    x[~ok] = 0.0
    return x, ok


def block_matvec(evaluation: Blocks, x: Any) -> Any:
    """(J^T J) x for x (B, N, dof): numpy arrays, or torch tensors on any device."""
    out = (evaluation.diagonal @ x[..., None])[..., 0]
    c = evaluation.coupling[:, None, None]
    out[:, 1:] -= c * x[:, :-1]
    out[:, :-1] -= c * x[:, 1:]
    return out


