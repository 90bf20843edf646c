"""The chain's kinematics for numba: constants as plain arrays, sine and cosine, one end frame.

Shared by the compiled trajectory solver (:mod:`.compiled`: :class:`Chain`, :func:`sin_cos`)
and the compiled single-pose IK (:mod:`.single_pose_compiled`: :func:`pack`, :func:`frame`,
:func:`frame_jacobian`). Same formulas as :meth:`ikbench.core.kinematics.chain.
ChainKinematics.frames`, written per pose in scalars: a revolute joint about the unit axis u
rotates by R_j (I + sin q K + (1 - cos q) K^2) (K = [u]_x, Rodrigues), a prismatic one moves
along its world axis w by q [m]; the geometric Jacobian's columns (world-aligned) are
w x (P - o_j) and w (revolute), w and 0 (prismatic), per pose unit (times dq_urdf / dpose).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, TypeAlias

import numpy as np
import numpy.typing as npt
from numba import njit

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

#: The kernels' arrays (numba reads the types from the arguments, not from annotations).
Array: TypeAlias = np.ndarray


class Chain:
    """The chain's constants as plain arrays (k joints), for the compiled FK.

    Attributes:
        translations: (k, 3) joint placements [m].  rotations, rot_k, rot_k2: (k, 3, 3) the
            placements' rotations R_j and R_j K_j, R_j K_j^2 (K_j the axis' cross matrix).
        axes: (k, 3) joint axes (joint frame).  prismatic: (k,) bool.
        map_scale, map_offset, map_si: (k,) q_urdf = (pose * scale + offset) * si.
        urdf_per_unit: (k,) dq_urdf / dpose (the numpy chain's, for the Jacobians).
        tip_translation: (3,) [m].  tip_rotation: (3, 3) the end frame in the last joint's
            frame.  tip_axis: (3,) pointing axis in the last joint's frame.
    """

    def __init__(self, robot: Robot) -> None:
        kin = robot.chain_kinematics()
        k = kin.dof
        self.translations = np.ascontiguousarray(kin.translations, dtype=float).reshape(k, 3)
        self.rotations = np.ascontiguousarray(kin.rotations, dtype=float).reshape(k, 3, 3)
        axes = np.ascontiguousarray(kin.axes, dtype=float).reshape(k, 3)
        skew = np.zeros((k, 3, 3))
        skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -axes[:, 2], axes[:, 1], -axes[:, 0]
        skew -= skew.transpose(0, 2, 1)
        self.rot_k = np.ascontiguousarray(self.rotations @ skew)
        self.rot_k2 = np.ascontiguousarray(self.rotations @ skew @ skew)
        self.axes = axes
        self.prismatic = np.ascontiguousarray(kin.prismatic, dtype=np.bool_)
        # q_urdf as Robot.to_urdf computes it: (pose * scale + offset) * si
        si = np.asarray(robot._si_per_unit, dtype=float)
        self.map_scale = np.asarray(robot.scale, dtype=float) * np.ones(k)
        self.map_offset = np.asarray(robot.offset_deg, dtype=float) * np.ones(k)
        self.map_si = si
        self.urdf_per_unit = np.asarray(kin.urdf_per_unit, dtype=float)  # as the Jacobians
        self.tip_translation = np.asarray(kin.tip_translation, dtype=float)
        self.tip_rotation = np.asarray(kin.tip_rotation, dtype=float)
        self.tip_axis = np.asarray(kin.tip_axis, dtype=float)

    def arrays(self) -> tuple[np.ndarray, ...]:
        """The constants :mod:`.compiled`'s kernels take (``tip_rotation`` is not among them)."""
        return (self.translations, self.rotations, self.rot_k, self.rot_k2, self.axes,
                self.prismatic, self.urdf_per_unit, self.map_scale, self.map_offset,
                self.map_si, self.tip_translation, self.tip_axis)


#: Columns of :func:`pack`'s joint rows: placement translation [m] (3), rotation R_j, R_j K_j,
#: R_j K_j^2 (9 each, row-major), axis (3), prismatic (1.0 or 0.0), dq_urdf / dpose, the
#: motor map's scale, offset and SI factor, the limits [pose units] (+-inf when unbounded).
TRANSLATION, ROTATION, ROT_K, ROT_K2, AXIS = 0, 3, 12, 21, 30
PRISMATIC, PER_UNIT, SCALE, OFFSET, SI, LOWER, UPPER = 33, 34, 35, 36, 37, 38, 39
#: Columns of :func:`pack`'s last row: the end frame in the last joint's frame.
TIP_TRANSLATION, TIP_ROTATION = 0, 3
WIDTH = 40


def pack(chain: Chain, lower: npt.ArrayLike, upper: npt.ArrayLike) -> np.ndarray:
    """The chain and its limits [pose units] as one array (k + 1, :data:`WIDTH`): one row per
    joint, then the end frame (columns above). One array is one argument for numba to type
    (~0.1 us a call) where :meth:`Chain.arrays`' tuple of twelve costs ~0.7 us."""
    k = len(chain.translations)
    out = np.zeros((k + 1, WIDTH))
    out[:k, TRANSLATION:TRANSLATION + 3] = chain.translations
    out[:k, ROTATION:ROTATION + 9] = chain.rotations.reshape(k, 9)
    out[:k, ROT_K:ROT_K + 9] = chain.rot_k.reshape(k, 9)
    out[:k, ROT_K2:ROT_K2 + 9] = chain.rot_k2.reshape(k, 9)
    out[:k, AXIS:AXIS + 3] = chain.axes
    out[:k, PRISMATIC] = chain.prismatic
    out[:k, PER_UNIT] = chain.urdf_per_unit
    out[:k, SCALE], out[:k, OFFSET], out[:k, SI] = chain.map_scale, chain.map_offset, \
        chain.map_si
    out[:k, LOWER], out[:k, UPPER] = lower, upper
    out[k, TIP_TRANSLATION:TIP_TRANSLATION + 3] = chain.tip_translation
    out[k, TIP_ROTATION:TIP_ROTATION + 9] = chain.tip_rotation.reshape(9)
    return out


#: pi/2 in two parts (fdlibm's pio2_1, pio2_1t): k * PIO2_HI is exact for |k| < 2^20.
PIO2_HI = 1.57079632673412561417e+00
PIO2_LO = 6.07710050650619224932e-11
#: fdlibm's minimax polynomials of sin and cos on [-pi/4, pi/4] (__kernel_sin, __kernel_cos).
S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@njit(cache=True, inline="always")
def sin_cos(angle: float) -> tuple[float, float]:
    """(sin, cos) of an angle [rad] of moderate size (|angle| < 1e5), within ~1 ulp of libm's:
    fdlibm's reduction to [-pi/4, pi/4] and its kernels, without branches (vectorisable;
    libm's sin and cos were most of the chain's time)."""
    quadrant = math.floor(angle * (2.0 / math.pi) + 0.5)
    r = (angle - quadrant * PIO2_HI) - quadrant * PIO2_LO
    z = r * r
    sin_r = r + z * r * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))))
    cos_r = 1.0 - (0.5 * z - z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))))
    m = int(quadrant) & 3
    sin_sign = 1.0 - 2.0 * ((m >> 1) & 1)
    cos_sign = 1.0 - 2.0 * (((m + 1) >> 1) & 1)
    if m & 1:
        return sin_sign * cos_r, cos_sign * sin_r
    return sin_sign * sin_r, cos_sign * cos_r


@njit(cache=True, inline="always")
def rotate(a: float, b: float, c: float, d: float, e: float, f: float, g: float, h: float,
           o: float, s00: float, s01: float, s02: float, s10: float, s11: float, s12: float,
           s20: float, s21: float, s22: float) -> tuple[float, ...]:
    """The product of two rotations in scalars (row-major): (a .. o) (s00 .. s22)."""
    return (a * s00 + b * s10 + c * s20, a * s01 + b * s11 + c * s21,
            a * s02 + b * s12 + c * s22, d * s00 + e * s10 + f * s20,
            d * s01 + e * s11 + f * s21, d * s02 + e * s12 + f * s22,
            g * s00 + h * s10 + o * s20, g * s01 + h * s11 + o * s21,
            g * s02 + h * s12 + o * s22)


@njit(cache=True, inline="always")
def joint_step(chain: tuple, j: int, q_urdf: float, sn: float, vs: float, a: float, b: float,
               c: float, d: float, e: float, f: float, g: float, h: float, o: float, p0: float,
               p1: float, p2: float) -> tuple[float, ...]:
    """Joint ``j`` of the forward product on :meth:`Chain.arrays`' constants, in scalars: from
    the frame before it, the rotation (a .. o, row-major) and origin (p0, p1, p2) [m], to its
    own after its placement and its motion (``q_urdf`` [rad, m], ``sn`` = sin q_urdf, ``vs``
    = 1 - cos q_urdf; a prismatic joint ignores the two). Returns (a .. o, p0, p1, p2, w0, w1,
    w2): the rotation and origin after the joint and its axis in the base frame."""
    trans, rots, rot_k, rot_k2, axes, prismatic = (chain[0], chain[1], chain[2], chain[3],
                                                   chain[4], chain[5])
    t0, t1, t2 = trans[j, 0], trans[j, 1], trans[j, 2]
    p0 += a * t0 + b * t1 + c * t2
    p1 += d * t0 + e * t1 + f * t2
    p2 += g * t0 + h * t1 + o * t2
    if prismatic[j]:
        sn = vs = 0.0
    m = rots[j]
    a, b, c, d, e, f, g, h, o = rotate(
        a, b, c, d, e, f, g, h, o,
        m[0, 0] + sn * rot_k[j, 0, 0] + vs * rot_k2[j, 0, 0],
        m[0, 1] + sn * rot_k[j, 0, 1] + vs * rot_k2[j, 0, 1],
        m[0, 2] + sn * rot_k[j, 0, 2] + vs * rot_k2[j, 0, 2],
        m[1, 0] + sn * rot_k[j, 1, 0] + vs * rot_k2[j, 1, 0],
        m[1, 1] + sn * rot_k[j, 1, 1] + vs * rot_k2[j, 1, 1],
        m[1, 2] + sn * rot_k[j, 1, 2] + vs * rot_k2[j, 1, 2],
        m[2, 0] + sn * rot_k[j, 2, 0] + vs * rot_k2[j, 2, 0],
        m[2, 1] + sn * rot_k[j, 2, 1] + vs * rot_k2[j, 2, 1],
        m[2, 2] + sn * rot_k[j, 2, 2] + vs * rot_k2[j, 2, 2])
    u0, u1, u2 = axes[j, 0], axes[j, 1], axes[j, 2]
    w0 = a * u0 + b * u1 + c * u2
    w1 = d * u0 + e * u1 + f * u2
    w2 = g * u0 + h * u1 + o * u2
    if prismatic[j]:
        p0 += w0 * q_urdf
        p1 += w1 * q_urdf
        p2 += w2 * q_urdf
    return a, b, c, d, e, f, g, h, o, p0, p1, p2, w0, w1, w2


@njit(cache=True, inline="always")
def frame(spec: Array, k: int, q: Array, point: Array, rotation: Array, axes_world: Array,
          origins: Array, trig: Array) -> None:
    """End frame of one pose: ``point`` (3,) [m] and ``rotation`` (3, 3) in the base frame,
    the joints' world axes ``axes_world`` (k, 3) and origins ``origins`` (k, 3) [m], written
    in place; ``q`` (k,) [pose units], ``spec``: :func:`pack`'s array, ``trig`` (k, 3)
    scratch (all the joints' sines first: they do not wait on the product, which does)."""
    for j in range(k):
        q_urdf = (q[j] * spec[j, SCALE] + spec[j, OFFSET]) * spec[j, SI]
        sn, cs = sin_cos(q_urdf)
        trig[j, 0], trig[j, 1], trig[j, 2] = q_urdf, sn, 1.0 - cs
    a, b, c, d, e, f, g, h, o = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    p0 = p1 = p2 = 0.0
    for j in range(k):  # spec[j, column], not a row view: a view costs a reference count
        t0, t1, t2 = spec[j, TRANSLATION], spec[j, TRANSLATION + 1], spec[j, TRANSLATION + 2]
        p0 += a * t0 + b * t1 + c * t2
        p1 += d * t0 + e * t1 + f * t2
        p2 += g * t0 + h * t1 + o * t2
        q_urdf, sn, vs = trig[j, 0], trig[j, 1], trig[j, 2]
        prismatic = spec[j, PRISMATIC] != 0.0
        if prismatic:
            sn = vs = 0.0
        a, b, c, d, e, f, g, h, o = rotate(
            a, b, c, d, e, f, g, h, o,
            spec[j, ROTATION] + sn * spec[j, ROT_K] + vs * spec[j, ROT_K2],
            spec[j, ROTATION + 1] + sn * spec[j, ROT_K + 1] + vs * spec[j, ROT_K2 + 1],
            spec[j, ROTATION + 2] + sn * spec[j, ROT_K + 2] + vs * spec[j, ROT_K2 + 2],
            spec[j, ROTATION + 3] + sn * spec[j, ROT_K + 3] + vs * spec[j, ROT_K2 + 3],
            spec[j, ROTATION + 4] + sn * spec[j, ROT_K + 4] + vs * spec[j, ROT_K2 + 4],
            spec[j, ROTATION + 5] + sn * spec[j, ROT_K + 5] + vs * spec[j, ROT_K2 + 5],
            spec[j, ROTATION + 6] + sn * spec[j, ROT_K + 6] + vs * spec[j, ROT_K2 + 6],
            spec[j, ROTATION + 7] + sn * spec[j, ROT_K + 7] + vs * spec[j, ROT_K2 + 7],
            spec[j, ROTATION + 8] + sn * spec[j, ROT_K + 8] + vs * spec[j, ROT_K2 + 8])
        u0, u1, u2 = spec[j, AXIS], spec[j, AXIS + 1], spec[j, AXIS + 2]
        w0 = a * u0 + b * u1 + c * u2
        w1 = d * u0 + e * u1 + f * u2
        w2 = g * u0 + h * u1 + o * u2
        axes_world[j, 0], axes_world[j, 1], axes_world[j, 2] = w0, w1, w2
        if prismatic:
            p0 += w0 * q_urdf
            p1 += w1 * q_urdf
            p2 += w2 * q_urdf
        origins[j, 0], origins[j, 1], origins[j, 2] = p0, p1, p2
    t0, t1, t2 = spec[k, TIP_TRANSLATION], spec[k, TIP_TRANSLATION + 1], \
        spec[k, TIP_TRANSLATION + 2]
    point[0] = p0 + a * t0 + b * t1 + c * t2
    point[1] = p1 + d * t0 + e * t1 + f * t2
    point[2] = p2 + g * t0 + h * t1 + o * t2
    for col in range(3):
        r0, r1, r2 = (spec[k, TIP_ROTATION + col], spec[k, TIP_ROTATION + 3 + col],
                      spec[k, TIP_ROTATION + 6 + col])
        rotation[0, col] = a * r0 + b * r1 + c * r2
        rotation[1, col] = d * r0 + e * r1 + f * r2
        rotation[2, col] = g * r0 + h * r1 + o * r2


@njit(cache=True, inline="always")
def frame_jacobian(spec: Array, k: int, point: Array, axes_world: Array, origins: Array,
                   j_point: Array, j_angular: Array) -> None:
    """The geometric Jacobian of :func:`frame`'s end point, world-aligned, per pose unit:
    ``j_point`` (3, k) [m / pose unit] and ``j_angular`` (3, k) [rad / pose unit], in place."""
    for j in range(k):
        s = spec[j, PER_UNIT]
        w0, w1, w2 = axes_world[j, 0], axes_world[j, 1], axes_world[j, 2]
        if spec[j, PRISMATIC] != 0.0:
            j_point[0, j], j_point[1, j], j_point[2, j] = w0 * s, w1 * s, w2 * s
            j_angular[0, j] = j_angular[1, j] = j_angular[2, j] = 0.0
        else:
            d0 = point[0] - origins[j, 0]
            d1 = point[1] - origins[j, 1]
            d2 = point[2] - origins[j, 2]
            j_point[0, j] = (w1 * d2 - w2 * d1) * s
            j_point[1, j] = (w2 * d0 - w0 * d2) * s
            j_point[2, j] = (w0 * d1 - w1 * d0) * s
            j_angular[0, j], j_angular[1, j], j_angular[2, j] = w0 * s, w1 * s, w2 * s


@njit(cache=True)
def _frames_all(spec, poses, point, rotation, j_point, j_angular):
    k = poses.shape[1]
    axes_world, origins, trig = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    for i in range(poses.shape[0]):
        frame(spec, k, poses[i], point[i], rotation[i], axes_world, origins, trig)
        frame_jacobian(spec, k, point[i], axes_world, origins, j_point[i], j_angular[i])


def frames(robot: Robot, poses: npt.ArrayLike
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`~ikbench.core.kinematics.chain.ChainKinematics.frames` compiled: (point_m
    (M, 3), rotation (M, 3, 3), J_point (M, 3, dof) [m / pose unit], J_angular (M, 3, dof)
    [rad / pose unit], world-aligned) of poses (M, dof) [pose units]."""
    poses = np.ascontiguousarray(poses, dtype=float).reshape(-1, robot.dof)
    m, k = poses.shape
    spec = pack(Chain(robot), robot.lower, robot.upper)
    point, rotation = np.empty((m, 3)), np.empty((m, 3, 3))
    j_point, j_angular = np.empty((m, 3, k)), np.empty((m, 3, k))
    _frames_all(spec, poses, point, rotation, j_point, j_angular)
    return point, rotation, j_point, j_angular
