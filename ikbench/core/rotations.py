"""Rotations in numpy, batched: quaternions (w first), the SO(3) exp and log maps.

Conventions: rotation matrices R (..., 3, 3) act on column vectors; quaternions are
(w, x, y, z), unit, and written with w >= 0; rotation vectors phi = angle * axis [rad]. The
distance between two rotations is the geodesic angle |log(R_a^T R_b)| [rad], in [0, pi].
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

#: Below this angle [rad] the series expansions of the maps are used.
SMALL_ANGLE = 1e-6


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrices (..., 3, 3) of vectors (..., 3): skew(a) @ b = a x b."""
    v = np.asarray(v, dtype=float)
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def quat_wxyz_to_matrix(q: npt.ArrayLike) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of quaternions (..., 4) (w, x, y, z); normalised first."""
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(q, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def matrix_to_quat_wxyz(R: npt.ArrayLike) -> np.ndarray:
    """Unit quaternions (..., 4) (w, x, y, z) with w >= 0 of rotation matrices (..., 3, 3).

    Shepperd's method: the largest of w, x, y, z is computed from the diagonal, the others
    from the off-diagonal entries, so no branch loses precision.
    """
    R = np.asarray(R, dtype=float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    candidates = np.stack([1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22,
                           1 - m00 - m11 + m22], -1)
    k = np.argmax(candidates, axis=-1)
    s = 2.0 * np.sqrt(np.maximum(np.take_along_axis(candidates, k[..., None], -1)[..., 0],
                                 1e-300))
    d21, d02, d10 = R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], \
        R[..., 1, 0] - R[..., 0, 1]
    s21, s02, s10 = R[..., 2, 1] + R[..., 1, 2], R[..., 0, 2] + R[..., 2, 0], \
        R[..., 1, 0] + R[..., 0, 1]
    options = np.stack([
        np.stack([s / 4, d21 / s, d02 / s, d10 / s], -1),
        np.stack([d21 / s, s / 4, s10 / s, s02 / s], -1),
        np.stack([d02 / s, s10 / s, s / 4, s21 / s], -1),
        np.stack([d10 / s, s02 / s, s21 / s, s / 4], -1),
    ], -2)
    q = np.take_along_axis(options, k[..., None, None], -2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0, -q, q)


def so3_exp(phi: npt.ArrayLike) -> np.ndarray:
    """Rotation matrices (..., 3, 3) of rotation vectors (..., 3) [rad] (Rodrigues)."""
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = theta < SMALL_ANGLE
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - theta**2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    return np.eye(3) + a * K + b * (K @ K)


def so3_log(R: npt.ArrayLike) -> np.ndarray:
    """Rotation vectors (..., 3) [rad], angle in [0, pi], of rotation matrices (..., 3, 3).

    Accurate near 0 (series) and near pi (the axis from the symmetric part of R).
    """
    R = np.asarray(R, dtype=float)
    trace = R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2]
    vee = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                          R[..., 1, 0] - R[..., 0, 1]], -1)          # sin(theta) * axis
    sin = np.linalg.norm(vee, axis=-1)
    theta = np.arctan2(sin, 0.5 * (trace - 1.0))
    small = theta < SMALL_ANGLE
    factor = np.where(small, 1.0 + theta**2 / 6.0, theta / np.where(small, 1.0, sin + 1e-300))
    out = vee * factor[..., None]
    near_pi = theta > np.pi - 1e-3
    if np.any(near_pi):
        out[near_pi] = _log_near_pi(R[near_pi], theta[near_pi], vee[near_pi])
    return out


def _log_near_pi(R, theta, vee):
    """Rotation vectors for angles close to pi: axis from R + R^T = 2 cos I + 2 (1 - cos) a a^T."""
    c = np.cos(theta)[:, None, None]
    aat = (0.5 * (R + R.swapaxes(-1, -2)) - c * np.eye(3)) / (1.0 - c)
    k = np.argmax(np.diagonal(aat, axis1=-2, axis2=-1), axis=-1)
    axis = np.take_along_axis(aat, k[:, None, None], -2)[:, 0, :]
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    sign = np.where(np.sum(axis * vee, axis=-1) < 0, -1.0, 1.0)  # the sine part fixes the sign
    return axis * (sign * theta)[:, None]


def right_jacobian_inverse(phi: npt.ArrayLike) -> np.ndarray:
    """Jr^-1(phi) (..., 3, 3): log(exp(phi) exp(d)) = phi + Jr^-1(phi) d + O(|d|^2)."""
    phi = np.asarray(phi, dtype=float)
    theta = np.linalg.norm(phi, axis=-1)[..., None, None]
    K = skew(phi)
    small = theta < 1e-2  # series: the closed form cancels badly for small angles
    safe = np.where(small, 1.0, np.minimum(theta, 3.0))  # bounded near pi (log is not smooth)
    coefficient = np.where(small, 1.0 / 12.0 + theta**2 / 720.0 + theta**4 / 30240.0,
                           1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    return np.eye(3) + 0.5 * K + coefficient * (K @ K)


def geodesic_angle(R_a: npt.ArrayLike, R_b: npt.ArrayLike) -> np.ndarray:
    """The angles (...,) [rad] between rotations (..., 3, 3): |log(R_a^T R_b)|."""
    R_a, R_b = np.asarray(R_a, dtype=float), np.asarray(R_b, dtype=float)
    return np.linalg.norm(so3_log(R_a.swapaxes(-1, -2) @ R_b), axis=-1)
