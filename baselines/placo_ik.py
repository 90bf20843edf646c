"""placo (PyPI ``placo``, Rhoban): QP task-space kinematics on Pinocchio, tracking the goal
points from the start pose onto the touch pose (``scheme`` track, the default) or walked back
from the touch pose (walk, :mod:`ikbench.schemes.walk`); and its single-pose IK for
``ikbench ik`` (:class:`PlacoSolver`).

placo loads the chain's URDF text (:func:`ikbench.schemes.chain.chain_urdf_text`)
with ``placo.RobotWrapper("", placo.Flags.ignore_collisions, urdf_text)`` (a floating base,
masked: ``solver.mask_fbase(True)``), once per robot. Every solve builds a
``placo.KinematicsSolver(robot)`` and calls ``solver.solve(True)`` (one QP: a joint
displacement dq, applied), ``robot.update_kinematics()``, ``robot.set_joint`` /
``robot.get_joint`` and ``robot.get_T_world_frame``. Goals in the chain's base frame are moved
into placo's world frame (the URDF root) by the base link's constant placement.

Tasks (all ``soft``: a weighted least-squares QP; placo weights squared errors):

- ``solver.add_position_task(end_frame, p_i)``, weight ``position_weight`` [1/m^2]: the goal
  point;
- ``solver.add_axisalign_task(end_frame, pointing_axis, d_i)``, weight ``pointing_weight``
  [1/rad^2]: the pointing axis along the scheduled direction, the roll about it free (placo's
  axis-align task constrains only the two rotations across the axis); not added when the task
  asks no pointing;
- one ``solver.add_joints_task()`` per joint, ``set_joints({joint: posture_i})``, weight
  ``posture_weight`` times the square of the joint's per-pose-unit factor
  (:func:`ikbench.schemes.diffik.posture_weights`: a motor degree of NICO's wrist
  costs as much as one of its shoulder): the posture toward the start-to-touch joint line;
- joint limits: ``solver.enable_joint_limits(True)`` (hard: q + dq within
  ``robot.set_joint_limits``). The speed limit enters here too: at step i every joint's limits
  are narrowed to the speed box (:class:`ikbench.schemes.diffik.SpeedBox`: within
  ``speed_fraction`` of the contract's largest change per segment from step i-1 and within
  (n - i) such changes of the touch pose), so no QP of the step leaves it. placo's own
  velocity limit (``enable_velocity_limits``: |dq| <= dt v_max) bounds each QP, not a
  segment made of several QPs, and is not used.

Per step, from the step before moved on by the last segment's motion (a constant-speed warm
start, clipped into the box), QPs until the position error is below ``tolerance`` and either
the pointing is within ``tolerance`` [rad] of its schedule or the last QP moved no joint more
than ``stall`` (:func:`ikbench.schemes.diffik.settle`), at most ``max_steps``. A step
counts as converged when its position error, by placo's FK, is within ``tolerance``.
``iterations`` counts QP solves (``solver.solve`` calls).

The walk (``--scheme walk``) asks, per goal point from the previous one, the position and
axis-align tasks only (no posture, no box). Continuous joints (two configuration values in
Pinocchio) are refused: placo's joint-limit constraint assumes one value per joint.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.methods.options import check_choice, check_positive, option
from ikbench.methods.registry import Adapter
from ikbench.schemes.chain import Chain, Goals
from ikbench.schemes.diffik import SpeedBox, posture_weights, settle
from ikbench.schemes.geometry import angle_between_rad, rotation_angle_rad
from ikbench.schemes.method import ChainResult, LibraryMethod
from ikbench.schemes.single_pose import PoseOut, PoseSolver, steps_to_tolerance
from ikbench.schemes.track import SCHEME_HELP, SCHEMES, TrackPlan, track
from ikbench.schemes.walk import PointResult, walk_back

if TYPE_CHECKING:
    from ikbench.core.robot import Robot

_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class PlacoSettings:
    """Settings of placo's track and walk (see the module docstring)."""

    scheme: str = option("track", flag="scheme", choices=SCHEMES, help=SCHEME_HELP)
    position_weight: float = option(1e6, flag="placo-position-weight", unit="1/m^2",
                                    help="position task weight (the goal point is the hard "
                                    "goal; the other weights are small against it)")
    pointing_weight: float = option(1e-2, flag="placo-pointing-weight", unit="1/rad^2",
                                    help="axis-align task weight (the pointing axis along the "
                                    "scheduled direction, roll free)")
    posture_weight: float = option(1e-4, flag="placo-posture-weight", unit="1/rad^2",
                                   help="scheme track: joints task weight toward the "
                                   "start-to-touch posture (per pose unit: a motor degree "
                                   "for NICO)")
    speed_fraction: float = option(
        0.95, flag="placo-speed-fraction",
        help="scheme track: each step moves every joint by at most this fraction of the "
        "contract's speed-limit step and keeps the touch pose within reach at that speed "
        "(placo's joint limits narrowed per step); 0: no box")
    tolerance: float = option(1e-6, flag="placo-tolerance", unit="m, rad",
                              help="a step is converged when the position error is below this")
    stall: float = option(1e-4, flag="placo-stall", unit="rad, m",
                          help="a step ends once the position is within the tolerance and "
                          "the last QP moved no joint more than this")
    max_steps: int = option(100, flag="placo-max-steps", help="QP solves per step at most")

    def __post_init__(self):
        check_choice(self, "scheme", SCHEMES)
        check_positive(self, "position_weight", "tolerance", "stall")
        check_positive(self, "max_steps", integer=True)
        self.max_steps = int(self.max_steps)
        if not (self.pointing_weight >= 0 and self.posture_weight >= 0
                and 0 <= self.speed_fraction <= 1):
            raise InputError("--placo-pointing-weight and --placo-posture-weight must be >= 0, "
                             "--placo-speed-fraction in [0, 1]")


@dataclass(frozen=True, eq=False)
class PlacoModel:
    """placo's robot for a chain: the wrapper and the base link's placement in its world.

    Attributes:
        robot: ``placo.RobotWrapper``.
        R_wb: (3, 3) rotation of the base link in placo's world (the URDF root).
        p_wb: (3,) position of the base link [m].
    """

    robot: Any
    R_wb: np.ndarray
    p_wb: np.ndarray

    def set_q(self, chain: Chain, q: np.ndarray) -> None:
        """Set the chain's joints (dof,) [rad, m] and update the kinematics."""
        for name, value in zip(chain.joint_names, q):
            self.robot.set_joint(name, float(value))
        self.robot.update_kinematics()

    def get_q(self, chain: Chain) -> np.ndarray:
        """The chain's joints (dof,) [rad, m]."""
        return np.array([self.robot.get_joint(name) for name in chain.joint_names])

    def set_limits(self, chain: Chain, lower: np.ndarray, upper: np.ndarray) -> None:
        """placo's joint limits (hard constraints of every QP) [rad, m]."""
        for name, lo, hi in zip(chain.joint_names, lower, upper):
            self.robot.set_joint_limits(name, float(lo), float(hi))

    def end(self, chain: Chain) -> tuple[np.ndarray, np.ndarray]:
        """(position (3,) [m], rotation (3, 3)) of the end frame in the chain's base frame."""
        T = np.asarray(self.robot.get_T_world_frame(chain.end_frame))
        return (self.R_wb.T @ (T[:3, 3] - self.p_wb), self.R_wb.T @ T[:3, :3])

    def world_point(self, point_m: np.ndarray) -> np.ndarray:
        """A point (3,) of the base frame in placo's world [m]."""
        return self.R_wb @ np.asarray(point_m, dtype=float) + self.p_wb


def check_chain(chain: Chain) -> None:
    """InputError for continuous joints (see the module docstring)."""
    continuous = [n for n, t in zip(chain.joint_names, chain.joint_types) if t == "continuous"]
    if continuous:
        raise InputError(f"--method placo: joint(s) {', '.join(continuous)} are continuous; "
                         "placo's joint-limit constraint takes one value per joint")


def placo_urdf_text(chain: Chain) -> str:
    """The chain's URDF text with every joint that shares its name with a link renamed
    (``<name>__joint``), unless the chain moves it.

    placo finds frames by name only, and Pinocchio holds two frames when a fixed joint and its
    child link share one (z1's ``gripperStator``): every task on such a frame fails with
    "Several frames match the filter". The other adapters pick the link's ``BODY`` frame
    (:func:`ikbench.core.kinematics.pinocchio_fk.link_frame_id`); placo takes no frame type,
    so the joint's frame is given another name. Placements and the chain are unchanged.
    """
    import xml.etree.ElementTree as ET

    root = ET.fromstring(chain.urdf_text)
    links = {link.get("name") for link in root.iter("link")}
    names = links | {joint.get("name") for joint in root.iter("joint")}
    renamed: dict[str, str] = {}
    for joint in root.iter("joint"):
        name = joint.get("name") or ""
        if name in links and name not in chain.joint_names:
            new = f"{name}__joint"
            while new in names:
                new += "_"
            joint.set("name", new)
            names.add(new)
            renamed[name] = new
    if not renamed:
        return chain.urdf_text
    for mimic in root.iter("mimic"):
        named = mimic.get("joint") or ""
        mimic.set("joint", renamed.get(named, named))
    return ET.tostring(root, encoding="unicode")


def placo_model(chain: Chain) -> PlacoModel:
    """placo's robot for ``chain`` (loaded once per chain)."""
    if chain in _MODELS:
        return _MODELS[chain]
    import placo

    check_chain(chain)
    robot = placo.RobotWrapper("", placo.Flags.ignore_collisions, placo_urdf_text(chain))
    robot.update_kinematics()
    T = np.asarray(robot.get_T_world_frame(chain.base_link))
    _MODELS[chain] = PlacoModel(robot, T[:3, :3].copy(), T[:3, 3].copy())
    return _MODELS[chain]


def new_solver(model: PlacoModel) -> Any:
    """A ``placo.KinematicsSolver`` with the floating base masked and joint limits on."""
    import placo

    solver = placo.KinematicsSolver(model.robot)
    solver.mask_fbase(True)
    solver.enable_joint_limits(True)
    solver.enable_velocity_limits(False)
    return solver


def settle_point(model: PlacoModel, chain: Chain, solver: Any, point_m: np.ndarray,
                 direction: np.ndarray | None, settings: PlacoSettings) -> PointResult:
    """QPs from the robot's current joints until the step settles
    (:func:`ikbench.schemes.diffik.settle`): the goal point ``point_m`` (3,) [m]
    and, unless None, the pointing ``direction`` (3,) (base frame)."""

    def measure() -> tuple[float, float]:
        p, R = model.end(chain)
        error = float(np.linalg.norm(p - point_m))
        if direction is None:
            return error, 0.0
        return error, angle_between_rad(R @ chain.pointing_axis, direction)

    def step_once() -> float:
        before = model.get_q(chain)
        solver.solve(True)
        model.robot.update_kinematics()
        return float(np.max(np.abs(model.get_q(chain) - before)))

    steps, ok = settle(measure, step_once, settings.tolerance, settings.stall,
                       settings.max_steps)
    return PointResult(model.get_q(chain), steps, ok)


def solve_track(robot: Robot, chain: Chain, plan: TrackPlan, settings: PlacoSettings,
                step: np.ndarray | None = None) -> ChainResult:
    """placo's track from the start pose onto the touch pose (``step``: (dof,) the contract's
    largest joint change per segment [rad, m], or None: no speed box)."""
    model = placo_model(chain)
    model.set_limits(chain, chain.lower, chain.upper)
    model.set_q(chain, plan.q_start)
    solver = new_solver(model)
    position = solver.add_position_task(chain.end_frame, model.world_point(plan.points_m[0]))
    position.configure("position", "soft", settings.position_weight)
    axis = None
    if plan.directions is not None:
        axis = solver.add_axisalign_task(chain.end_frame, chain.pointing_axis,
                                         model.R_wb @ plan.directions[0])
        axis.configure("pointing", "soft", settings.pointing_weight)
    postures = []
    for name, factor in zip(chain.joint_names, posture_weights(robot)):
        task = solver.add_joints_task()
        task.set_joints({name: 0.0})
        task.configure(f"posture {name}", "soft", settings.posture_weight * factor ** 2)
        postures.append((name, task))
    box = None
    if step is not None and settings.speed_fraction > 0:
        box = SpeedBox(settings.speed_fraction * step, plan.q_touch, len(plan) - 1,
                       chain.lower, chain.upper, 1.0)
    previous: dict[str, Any] = {"q": None}

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        q0 = q_warm
        if box is not None:
            box.set_step(i, q_warm)
            model.set_limits(chain, box.lo, box.hi)
        if previous["q"] is not None:  # the last segment's motion again
            q0 = q_warm + (q_warm - previous["q"])
            q0 = chain.clip(box.clip(q0) if box is not None else q0)
        previous["q"] = q_warm
        model.set_q(chain, q0)
        position.target_world = model.world_point(plan.points_m[i])
        if axis is not None:
            assert plan.directions is not None
            axis.targetAxis_world = model.R_wb @ plan.directions[i]
        for (name, task), value in zip(postures, plan.posture[i]):
            task.set_joint(name, float(value))

        direction = None if plan.directions is None else plan.directions[i]
        return settle_point(model, chain, solver, plan.points_m[i], direction, settings)

    try:
        walk = track(solve_point, chain, plan)
    finally:
        model.set_limits(chain, chain.lower, chain.upper)
    return ChainResult.from_walk(walk, scheme="track", speed_box=box is not None,
                                 iterations_are="QP solves (placo solver.solve calls)")


def solve_walk(chain: Chain, goals: Goals, settings: PlacoSettings) -> ChainResult:
    """placo's walk back from the touch pose: position and axis-align tasks per goal point."""
    model = placo_model(chain)
    model.set_limits(chain, chain.lower, chain.upper)
    solver = new_solver(model)
    position = solver.add_position_task(chain.end_frame, model.world_point(goals.points_m[-1]))
    position.configure("position", "soft", settings.position_weight)
    axis = solver.add_axisalign_task(chain.end_frame, chain.pointing_axis,
                                     model.R_wb @ goals.directions[-1])
    axis.configure("pointing", "soft", settings.pointing_weight)

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        model.set_q(chain, q_warm)
        position.target_world = model.world_point(goals.points_m[i])
        axis.targetAxis_world = model.R_wb @ goals.directions[i]

        return settle_point(model, chain, solver, goals.points_m[i], goals.directions[i],
                            settings)

    walk = walk_back(solve_point, chain, goals)
    return ChainResult.from_walk(walk, scheme="walk",
                                 iterations_are="QP solves (placo solver.solve calls)")


class Placo(LibraryMethod):
    """placo's QP task-space kinematics, tracking from the start pose onto the touch pose
    (or walked back from the touch pose: ``--scheme walk``)."""

    name = "placo"
    description = ("library: placo (Rhoban) QP kinematics on Pinocchio tracking the goal "
                   "points from the start pose (position task + axis-align task + joints "
                   "tasks toward the start-to-touch posture, joint limits narrowed to the "
                   "speed limits per step), landing on the touch pose (--scheme walk: walked "
                   "back from the touch pose)")
    library = "placo"
    Settings = PlacoSettings
    chain_check = staticmethod(check_chain)  # InputError for continuous joints
    chain_model = staticmethod(placo_model)  # untimed: placo parses the URDF

    def solve_chain(self, robot: Robot, chain: Chain, goals: Goals) -> ChainResult:
        if goals.track is not None:
            return solve_track(robot, chain, goals.track, self.settings, goals.max_step)
        return solve_walk(chain, goals, self.settings)


class PlacoSolver(PoseSolver):
    """placo's single-pose IK: a frame task on the end frame (a position task for points),
    joint limits on, one ``solver.solve(True)`` QP per step until both errors are below the
    library tolerance."""

    rank = 110
    name, library, modules = "placo", "placo", ("placo",)
    iterations_are = "QP solves (placo solver.solve calls)"
    attempt_bound = "LIBRARY_TOLERANCE (1e-6, m and rad), 100 QP steps"

    def prepare(self) -> None:
        check_chain(self.chain)
        self.model = placo_model(self.chain)

    def solve(self, q_init: np.ndarray, point_m: np.ndarray, rotation: np.ndarray) -> PoseOut:
        model, chain, pose = self.model, self.chain, self.kind == "pose"
        model.set_limits(chain, chain.lower, chain.upper)
        model.set_q(chain, chain.clip(q_init))
        solver = new_solver(model)
        if pose:
            T = np.eye(4)
            T[:3, :3], T[:3, 3] = model.R_wb @ rotation, model.world_point(point_m)
            solver.add_frame_task(chain.end_frame, T).configure("frame", "soft", 1.0, 1.0)
        else:
            solver.add_position_task(chain.end_frame, model.world_point(point_m)).configure(
                "position", "soft", 1.0)

        def measure() -> tuple[float, float]:
            p, R = model.end(chain)
            return (float(np.linalg.norm(p - point_m)),
                    rotation_angle_rad(R, rotation) if pose else 0.0)

        def step() -> None:
            solver.solve(True)
            model.robot.update_kinematics()

        steps, ok = steps_to_tolerance(measure, step)
        return PoseOut(model.get_q(chain), steps, ok)


#: What this library brings (found by :mod:`ikbench.methods.registry`).
ADAPTER = Adapter(library="placo", requires=("placo",),
                  methods=(Placo,), solvers=(PlacoSolver,), rank=130)
