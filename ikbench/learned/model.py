"""The networks of ``ikbench learn`` and the loaded model's API (:class:`LearnedModel`).

Two kinds, both small multilayer perceptrons in float32 on the CPU:

- ``pose``: a mixture density network (:class:`PoseMDN`). Input: the target end frame's
  position [m, normalised by the training set's mean and spread] and its rotation as the 6-D
  representation (the first two columns of the rotation matrix). Output: K diagonal Gaussians
  over the joint configuration in normalised joint space (each joint's sampling range mapped
  to [-1, 1]): weights, means, log standard deviations. Several IK branches are several
  components.
- ``trajectory``: a mixture density network (:class:`TrajectoryMDN`) from (start pose, goal
  point [mm]) to whole trajectories: each component a touch pose and the offsets of the n - 1
  inner poses from the linear interpolation between the start pose and that touch pose, in
  normalised joint space; step 0 is the start pose. A goal point leaves the touch pose open
  (a redundant arm reaches a point in many ways, and the dataset's touch poses are drawn at
  random), so a single regression would average branches into no pose at all.

:class:`LearnedModel` wraps a loaded model file (:func:`ikbench.learned.train.load_model`):
``propose`` (pose kind), ``predict`` and ``candidates`` (trajectory kind), ``error`` and the
file's metadata.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import torch
from torch import nn

from ikbench.core.errors import InputError
from ikbench.core.robot import Robot

KINDS = ("pose", "trajectory")
#: Log standard deviations of the mixture's components are kept within this range
#: (normalised joint units: exp(-7) ~ 1e-3 of the half range, exp(1) ~ 2.7 half ranges).
LOG_SIGMA_RANGE = (-7.0, 1.0)
#: Features of a frame: position (3) and the 6-D rotation representation (6).
FRAME_FEATURES = 9


def mlp(inputs: int, outputs: int, hidden: int, layers: int) -> nn.Sequential:
    """``layers`` hidden layers of ``hidden`` units with SiLU, then a linear output."""
    modules: list[nn.Module] = []
    width = inputs
    for _ in range(layers):
        modules += [nn.Linear(width, hidden), nn.SiLU()]
        width = hidden
    modules.append(nn.Linear(width, outputs))
    return nn.Sequential(*modules)


class MDN(nn.Module):
    """Features (B, inputs) -> a mixture of ``components`` diagonal Gaussians over (dims,)."""

    def __init__(self, inputs: int, dims: int, components: int, hidden: int,
                 layers: int) -> None:
        super().__init__()
        self.dims, self.components = dims, components
        self.body = mlp(inputs, components * (1 + 2 * dims), hidden, layers)

    def forward(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(log weights (B, K), means (B, K, dims), log sigmas (B, K, dims))."""
        out = self.body(x)
        k, d = self.components, self.dims
        logits = out[:, :k]
        mean = out[:, k:k + k * d].reshape(-1, k, d)
        log_sigma = out[:, k + k * d:].reshape(-1, k, d).clamp(*LOG_SIGMA_RANGE)
        return torch.log_softmax(logits, dim=-1), mean, log_sigma

    def loss(self, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
        """Mean negative log-likelihood per sample of targets y (B, dims), per dimension
        (the constant 0.5 log(2 pi) left out)."""
        log_w, mean, log_sigma = self(x)
        z = (y[:, None, :] - mean) * torch.exp(-log_sigma)
        log_p = -0.5 * (z * z).sum(-1) - log_sigma.sum(-1)
        return -torch.logsumexp(log_w + log_p, dim=-1).mean() / self.dims


class PoseMDN(MDN):
    """Frame features (B, 9) -> a mixture over normalised configurations (dof,)."""

    def __init__(self, dof: int, components: int, hidden: int, layers: int) -> None:
        super().__init__(FRAME_FEATURES, dof, components, hidden, layers)


class TrajectoryMDN(MDN):
    """(start pose, goal point) features (B, dof + 3) -> a mixture over whole trajectories in
    normalised joint space, each written as the touch pose (dof) and the n - 1 inner poses'
    offsets from the linear interpolation between the start pose and that touch pose
    (:func:`trajectory_vector`, :func:`vector_trajectory`)."""

    def __init__(self, dof: int, steps: int, components: int, hidden: int,
                 layers: int) -> None:
        super().__init__(dof + 3, steps * dof, components, hidden, layers)
        self.dof, self.steps = dof, steps


def _line(start_u: np.ndarray, touch_u: np.ndarray, steps: int) -> np.ndarray:
    fraction = np.linspace(0.0, 1.0, steps + 1)[:, None]
    return start_u[..., None, :] + fraction * (touch_u - start_u)[..., None, :]


def trajectory_vector(u: np.ndarray) -> np.ndarray:
    """Trajectories (B, n + 1, dof) [normalised] -> vectors (B, n x dof): the touch pose, then
    the inner poses' offsets from the line between the start and touch poses."""
    steps = u.shape[1] - 1
    offsets = u[:, 1:-1] - _line(u[:, 0], u[:, -1], steps)[:, 1:-1]
    return np.concatenate([u[:, -1], offsets.reshape(len(u), -1)], axis=1)


def vector_trajectory(v: np.ndarray, start_u: np.ndarray, dof: int) -> np.ndarray:
    """Vectors (..., n x dof) and start poses (..., dof) [normalised] -> trajectories
    (..., n + 1, dof) (the inverse of :func:`trajectory_vector`)."""
    steps = v.shape[-1] // dof
    touch = v[..., :dof]
    line = _line(start_u, touch, steps)
    inner = v[..., dof:].reshape(*v.shape[:-1], steps - 1, dof)
    zero = np.zeros_like(touch)[..., None, :]
    return line + np.concatenate([zero, inner, zero], axis=-2)


def build_net(kind: str, dof: int, hyper: dict[str, Any]) -> nn.Module:
    """The untrained network of ``kind`` (weights from torch's current random state)."""
    if kind == "pose":
        return PoseMDN(dof, hyper["components"], hyper["hidden"], hyper["layers"])
    return TrajectoryMDN(dof, hyper["steps"], hyper["components"], hyper["hidden"],
                         hyper["layers"])


class JointScale:
    """Pose units <-> normalised joint space: each joint's sampling range
    (:attr:`Robot.sample_lower` .. :attr:`Robot.sample_upper`) mapped to [-1, 1]."""

    def __init__(self, lower: npt.ArrayLike, upper: npt.ArrayLike) -> None:
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.half = (self.upper - self.lower) / 2.0
        self.mid = (self.upper + self.lower) / 2.0

    def to_unit(self, q: npt.ArrayLike) -> np.ndarray:
        return (np.asarray(q, dtype=float) - self.mid) / self.half

    def from_unit(self, u: npt.ArrayLike) -> np.ndarray:
        """Configurations [pose units] within the range (u clipped to [-1, 1])."""
        return self.mid + np.clip(np.asarray(u, dtype=float), -1.0, 1.0) * self.half


def frame_features(T: np.ndarray, mean_m: np.ndarray, std_m: np.ndarray) -> np.ndarray:
    """Features (B, 9) of frames T (B, 4, 4) [m]: the normalised position and the 6-D
    rotation (the rotation matrix's first two columns)."""
    position = (T[:, :3, 3] - mean_m) / std_m
    six = T[:, :3, :2].transpose(0, 2, 1).reshape(len(T), 6)
    return np.concatenate([position, six], axis=1)


def frame_errors(robot: Robot, T: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(position error [mm], rotation error [deg]) of configurations q (B, dof) [pose units]
    against frames T (B, 4, 4) [m], by the robot's own FK (the vectorised chain)."""
    point_m, rotation, _, _ = robot.chain_kinematics().transforms(np.asarray(q, dtype=float))
    position_mm = np.linalg.norm(point_m - T[:, :3, 3], axis=-1) * 1000.0
    cos = (np.einsum("bij,bij->b", rotation, T[:, :3, :3]) - 1.0) / 2.0
    return position_mm, np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


class LearnedModel:
    """A model file of ``ikbench learn``, loaded (:func:`ikbench.learned.train.load_model`).

    Attributes:
        kind: ``pose`` or ``trajectory``.
        robot: the robot it was trained for.
        meta: the model file's dict without its weights (dataset, commit, samples, epochs,
            training CPU-minutes, hyper-parameters, held-out error, query time ...).
        net: the torch module (float32, CPU, in eval mode).
    """

    def __init__(self, payload: dict[str, Any], robot: Robot) -> None:
        self.kind: str = payload["kind"]
        self.robot = robot
        self.meta = {k: v for k, v in payload.items() if k not in ("state_dict", "held_out")}
        self.held_out_trajectories = np.asarray(payload["held_out"], dtype=np.int64)
        hyper = payload["hyper"]
        with torch.random.fork_rng(devices=[]):  # the initial weights are replaced below:
            self.net = build_net(self.kind, robot.dof, hyper)  # leave torch's RNG as it was
        self.net.load_state_dict(payload["state_dict"])
        self.net.eval()
        norm = payload["normalisation"]
        self.scale = JointScale(norm["joint_lower"], norm["joint_upper"])
        self._in_mean = np.asarray(norm["input_mean"], dtype=float)
        self._in_std = np.asarray(norm["input_std"], dtype=float)
        self.dof = robot.dof

    def __repr__(self) -> str:
        return (f"LearnedModel({self.kind} model of {self.robot.name}: "
                f"{self.meta['samples']['train']} training samples, "
                f"{self.meta['epochs']} epochs)")

    # ----- pose kind --------------------------------------------------------------------------
    def _need(self, kind: str, call: str) -> None:
        if self.kind != kind:
            raise InputError(f"model: {call} needs a {kind} model; this is a {self.kind} model")

    def _frames(self, T: npt.ArrayLike) -> np.ndarray:
        T = np.asarray(T, dtype=float)
        single = T.ndim == 2
        T = T[None] if single else T
        if T.ndim != 3 or T.shape[1:] != (4, 4):
            raise InputError(f"T: shape {np.shape(T)} is not (4, 4) or (B, 4, 4)")
        if not np.all(np.isfinite(T)):
            raise InputError("T: holds a value that is not finite")
        return T

    def _mixture(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(weights (B, K), means (B, K, dims), sigmas (B, K, dims)) for features x, the
        components sorted by weight, heaviest first."""
        with torch.inference_mode():
            log_w, mean, log_sigma = self.net(torch.as_tensor(x, dtype=torch.float32))
        w, mu, sigma = log_w.exp().numpy(), mean.numpy(), log_sigma.exp().numpy()
        order = np.argsort(-w, axis=1, kind="stable")
        take = np.take_along_axis
        return (take(w, order, 1), take(mu, order[..., None], 1),
                take(sigma, order[..., None], 1))

    def mixture(self, T: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The mixture for frames T (4, 4) or (B, 4, 4) [m]: (weights (B, K), means
        (B, K, dof), sigmas (B, K, dof)) in normalised joint space, components sorted by
        weight, heaviest first."""
        self._need("pose", "mixture")
        T = self._frames(T)
        return self._mixture(frame_features(T, self._in_mean, self._in_std))

    def propose(self, T: npt.ArrayLike, count: int = 1, seed: int = 0) -> np.ndarray:
        """``count`` configurations for the frame T (4, 4) [m] (or (B, 4, 4): (B, count,
        dof)), in the robot's pose units, within its joint limits: first the means of the
        mixture's components, heaviest first (the model's best proposal is row 0), then, past
        K, samples drawn from the mixture (seeded by ``seed``)."""
        self._need("pose", "propose")
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise InputError(f"count: {count!r} must be an integer >= 1")
        single = np.asarray(T).ndim == 2
        w, mu, sigma = self.mixture(T)
        k = mu.shape[1]
        u = mu[:, :min(count, k)]
        if count > k:
            rng = np.random.default_rng(seed)
            extra = count - k
            cumulative = np.cumsum(w, axis=1)
            pick = (rng.random((len(w), extra, 1)) > cumulative[:, None, :]).sum(-1)
            pick = np.minimum(pick, k - 1)
            take = np.take_along_axis
            m = take(mu, pick[..., None], 1)
            s = take(sigma, pick[..., None], 1)
            u = np.concatenate([u, m + s * rng.standard_normal(m.shape)], axis=1)
        q = np.clip(self.scale.from_unit(u), self.robot.lower, self.robot.upper)
        return q[0] if single else q

    def error(self, T: npt.ArrayLike, q: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """(position error [mm], rotation error [deg]) of configurations q (B, dof) [pose
        units] against frames T (B, 4, 4) (or one of each), by the robot's FK."""
        T = self._frames(T)
        q = np.atleast_2d(self.robot.check_poses(q, "q"))
        return frame_errors(self.robot, np.broadcast_to(T, (len(q), 4, 4)), q)

    # ----- trajectory kind --------------------------------------------------------------------
    def candidates(self, start_pose: npt.ArrayLike, goal_point_mm: npt.ArrayLike
                   ) -> np.ndarray:
        """The K trajectories of the mixture's component means, heaviest first, (K, n + 1,
        dof) [pose units] for one start pose (dof,) and goal point (3,) [mm] (B of each:
        (B, K, n + 1, dof)), within the joint limits; step 0 is the start pose."""
        self._need("trajectory", "candidates")
        start = np.asarray(start_pose, dtype=float)
        goal = np.asarray(goal_point_mm, dtype=float)
        single = start.ndim == 1
        start, goal = np.atleast_2d(start), np.atleast_2d(goal)
        self.robot.check_poses(start, "start_pose")
        if goal.shape != (len(start), 3) or not np.all(np.isfinite(goal)):
            raise InputError(f"goal_point_mm: shape {goal.shape} is not (3,) or "
                             f"({len(start)}, 3) of finite values [mm]")
        start_u = self.scale.to_unit(start)
        x = np.concatenate([start_u, (goal - self._in_mean) / self._in_std], axis=1)
        _, mu, _ = self._mixture(x)
        u = vector_trajectory(mu, start_u[:, None, :], self.dof)
        q = np.clip(self.scale.from_unit(u), self.robot.lower, self.robot.upper)
        q[:, :, 0] = start[:, None, :]
        return q[0] if single else q

    def predict(self, start_pose: npt.ArrayLike, goal_point_mm: npt.ArrayLike) -> np.ndarray:
        """The model's best trajectory (the heaviest component's mean), (n + 1, dof) [pose
        units], from ``start_pose`` (dof,) to the goal point (3,) [mm] (or B of each:
        (B, n + 1, dof)), within the joint limits; row 0 is the start pose."""
        self._need("trajectory", "predict")
        q = self.candidates(start_pose, goal_point_mm)
        return q[..., 0, :, :]
