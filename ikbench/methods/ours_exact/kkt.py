"""The banded KKT system of one SQP step, for B trajectories at once.

Each step of :mod:`.sqp` solves the equality-constrained quadratic model

    min_s  g^T s + 1/2 s^T H s    subject to   A s = -c

over the pose steps s (N, k) (N poses of k joints). Every constraint belongs to one pose
(A is block diagonal: m rows of pose i only), and H couples a pose only with its neighbours
up to ``d`` poses away (the smoothness term couples i with i+1; a jerk term with i+3), each
joint with the same joint only. Ordering the unknowns pose by pose, ``(s_i, lambda_i)`` in
blocks of ``k + m``, the KKT matrix

    [ H   A^T ] [ s      ]   [ -g ]
    [ A  -dI  ] [ lambda ] = [ -c ]

is a band matrix of half-bandwidth ``d (k + m)``, solved by LAPACK's banded LU with partial
pivoting (``dgbsv``) in O(N) per trajectory. The small ``-d I`` block (quasi-definite
regularisation) keeps the matrix non-singular when a pose's constraint Jacobian loses rank
(a singular arm, or too many joints held at their bounds); the constraints then hold up to
``d * lambda``. Variables not ``free`` (fixed poses, joints held at a bound) get an identity
row and a zero step; their pose's constraints are not dropped (the remaining joints keep them).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

#: Quasi-definite regularisation of the multiplier block (relative to the diagonal's scale).
REGULARISATION = 1e-12


def solve_kkt(diagonal: np.ndarray, bands: dict[int, np.ndarray], jacobian: np.ndarray,
              gradient: np.ndarray, residual: np.ndarray, free: np.ndarray,
              constrained: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Solve the KKT systems of B trajectories.

    Args:
        diagonal: (B, N, k, k) the diagonal blocks of H (damping included).
        bands: {d: (B, N - d, k)} for d = 1..D: H[(i, j), (i + d, j)] (same joint j).
        jacobian: (B, N, m, k) A's blocks (constraint rows of pose i).
        gradient: (B, N, k) g.
        residual: (B, N, m) c.
        free: (B, N, k) bool: variables that may move.
        constrained: (B, N) bool: poses whose constraints apply (others: multipliers 0).

    Returns:
        (steps (B, N, k), multipliers (B, N, m), ok (B,) bool: LAPACK factored the matrix).
    """
    from scipy.linalg.lapack import dgbsv

    b, n_poses, k = gradient.shape
    m = residual.shape[-1]
    s = k + m
    reach = max(bands, default=1)
    half = reach * s
    f = free.astype(float)
    con = constrained.astype(float)[..., None]
    block = np.zeros((b, n_poses, s, s))
    block[..., :k, :k] = diagonal * f[..., :, None] * f[..., None, :]
    a = jacobian * f[..., None, :] * con[..., None]
    block[..., k:, :k] = a
    block[..., :k, k:] = a.swapaxes(-1, -2)
    scale = np.maximum(np.max(np.abs(diagonal), axis=(1, 2, 3)), 1.0)
    idx_k, idx_m = np.arange(k), k + np.arange(m)
    block[..., idx_k, idx_k] += 1.0 - f
    block[..., idx_m, idx_m] = np.where(con > 0, -REGULARISATION * scale[:, None, None], 1.0)
    rhs = np.concatenate([-gradient * f, -residual * con], axis=-1).reshape(b, -1)

    size = n_poses * s
    band = np.zeros((b, 3 * half + 1, size))      # LAPACK's layout: A[i, j] at [2h + i - j, j]
    rows, cols = _block_positions(n_poses, s, half)
    band[:, rows, cols] = block
    for d, values in bands.items():
        coupled = values * f[:, :-d] * f[:, d:]                     # (B, N - d, k)
        first = (np.arange(n_poses - d)[:, None] * s + idx_k).ravel()
        second = first + d * s
        band[:, 2 * half + d * s, first] = coupled.reshape(b, -1)   # A[second, first]
        band[:, 2 * half - d * s, second] = coupled.reshape(b, -1)  # A[first, second]
    out = np.empty((b, size))
    ok = np.ones(b, dtype=bool)
    for t in range(b):
        _, _, x, info = dgbsv(half, half, band[t], rhs[t], overwrite_ab=1, overwrite_b=0)
        ok[t] = info == 0
        out[t] = x if info == 0 else 0.0
    out = out.reshape(b, n_poses, s)
    return out[..., :k] * f, out[..., k:], ok


@lru_cache(maxsize=32)
def _block_positions(n_poses: int, s: int, half: int):
    """Band rows and columns (N, s, s) of the diagonal blocks' entries."""
    a = np.arange(s)
    base = np.arange(n_poses)[:, None, None] * s
    rows = 2 * half + a[None, :, None] - a[None, None, :] + 0 * base
    cols = base + a[None, None, :] + 0 * a[None, :, None]
    return rows, cols
