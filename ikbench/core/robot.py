"""The robot model: a URDF chain from a base link to an end frame, its pose units and limits.

A robot is a URDF plus a small config (``urdf/<name>.toml``, see :func:`load_robot`). Its
joints are the movable joints on the path from ``base_link`` to ``end_frame``; every other
movable joint of the URDF is locked at 0. Positions are expressed in the base link's frame.

Poses at every interface are in **pose units**, in the order of ``Robot.joint_names``:

- with a motor map (NICO): **motor degrees**, what the robot reports; the affine map
  ``joint_deg = scale * motor_deg + offset_deg`` per joint lives in a data file next to the
  URDF (``*.motors.json``);
- without one (Panda, Fetch, a user's URDF): **joint degrees** for revolute and continuous
  joints and **millimetres** for prismatic ones.

The URDF speaks SI (radians, metres): :meth:`Robot.to_urdf` / :meth:`Robot.from_urdf` map
between (``motor_to_joint_rad`` / ``joint_rad_to_motor_deg`` are their older names).
Continuous joints have no limits (-inf, +inf).

A config may lock joints of the chain (``locked = {torso_lift_joint = 0.0}``, pose units): they
stay on the chain at that value but are not part of the pose (Fetch's arm with its torso held,
as jstmn/jrl's ``fetch_arm``). It may also give ``validity_limits`` (pose units): the bounds a
benchmark's validity check applies where they differ from the URDF's, e.g. the [-180, 180] deg
that jrl/CppFlow give the continuous rolls of the Fetch arm.
"""

from __future__ import annotations

import functools
import json
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple, overload

import numpy as np
import numpy.typing as npt

from ikbench.core.defaults import DEFAULT_ROBOT
from ikbench.core.errors import InputError, refuse_unknown_keys
from ikbench.core.kinematics.chain import ChainKinematics
from ikbench.core.kinematics.pinocchio_fk import PinocchioFK
from ikbench.core.kinematics.torch_fk import TorchFK
from ikbench.core.robot_config import CONFIG_KEYS, RobotConfig
from ikbench.core.robot_packages import is_package_name, package_urdf, resolve
from ikbench.core.urdf_model import (
    MAX_LIMIT_M,
    MAX_LIMIT_RAD,
    MOVABLE_TYPES,
    UrdfJoint,
    UrdfModel,
    load_urdf_model,
)

if TYPE_CHECKING:
    import torch

DEG2RAD = math.pi / 180.0
MM_PER_M = 1000.0
#: Tolerance [pose units] when checking that a pose lies within the limits.
RANGE_TOLERANCE_DEG = 1e-6
#: Tolerance [pose units] when reading a pose from a file: a trajectory written from float32
#: iterates (``ours``: Adam in float32) may pass a limit by an ulp of float32 (1.5e-5 deg at
#: 166 deg); the judge (:meth:`Robot.within_limits`) keeps :data:`RANGE_TOLERANCE_DEG`.
FILE_RANGE_TOLERANCE_DEG = 1e-4


def robots_dir() -> Path:
    """Where the shipped robot models live: ``ikbench/robots`` in an installed wheel, the
    checkout's top-level ``urdf/`` folder in an editable install."""
    here = Path(__file__).resolve().parents[1]
    shipped = here / "robots"
    return shipped if shipped.is_dir() else here.parent / "urdf"


class FKResult(NamedTuple):
    """End-frame point [mm] and unit pointing direction (the pointing axis), both (B, 3)."""

    point_mm: np.ndarray
    direction: np.ndarray


@dataclass(frozen=True, eq=False)
class Robot:
    """A serial chain of a URDF, with its pose units, limits and conventions.

    Attributes:
        name: robot name (``nico_right_arm``, or the URDF's stem).
        urdf_path: path of the URDF (SI units).
        end_frame: the link whose origin is the end point and whose ``pointing_axis`` points.
        root_link: the chain's base link; positions are in its frame.
        joint_names: the chain's movable joints, base to end, in pose order.
        scale: (dof,) joint value = scale * pose + offset (1 and 0 without a motor map).
        offset_deg: (dof,) see ``scale`` (deg for rotational joints, mm for prismatic).
        lower: (dof,) lower limits [pose units] (-inf for continuous joints).
        upper: (dof,) upper limits [pose units] (+inf for continuous joints).
        joint_types: (dof,) ``revolute``, ``continuous`` or ``prismatic``.
        pointing_axis: (3,) unit axis of the end frame that "points" (default z).
        has_motor_map: True when poses are motor degrees (a ``*.motors.json`` map).
        config: the robot config (:class:`RobotConfig`: description, source, targets, frame,
            letters, batch ...).
        locked_urdf: joints of the chain held fixed, name -> value [rad or m]; they are not in
            ``joint_names`` (the config gives them in pose units, ``locked``).
        validity_lower: (dof,) lower bounds [pose units] a benchmark's validity check uses
            (the config's ``validity_limits``, else the limits; None: the limits).
        validity_upper: (dof,) see ``validity_lower``.
    """

    name: str
    urdf_path: Path
    end_frame: str
    root_link: str
    joint_names: tuple[str, ...]
    scale: np.ndarray
    offset_deg: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    joint_types: tuple[str, ...] = ()
    pointing_axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    has_motor_map: bool = True
    config: RobotConfig = field(default_factory=RobotConfig)
    locked_urdf: dict = field(default_factory=dict)
    validity_lower: np.ndarray | None = None
    validity_upper: np.ndarray | None = None
    _cache: dict = field(default_factory=dict, repr=False)
    if TYPE_CHECKING:  # set by __post_init__: SI units per pose unit (rad per deg, m per mm)
        _si_per_unit: np.ndarray = field(init=False, repr=False)

    def __repr__(self) -> str:
        return (f"Robot({self.name!r}: {self.dof} joints, {self.root_link} -> {self.end_frame}, "
                f"poses in {self.pose_unit})")

    def __post_init__(self):
        if not self.joint_types:
            object.__setattr__(self, "joint_types", ("revolute",) * len(self.joint_names))
        # SI units per pose unit: rad per deg, or m per mm for prismatic joints
        si = np.array([1.0 / MM_PER_M if t == "prismatic" else DEG2RAD
                       for t in self.joint_types])
        object.__setattr__(self, "_si_per_unit", si)
        if self.validity_lower is None:
            object.__setattr__(self, "validity_lower", self.lower)
        if self.validity_upper is None:
            object.__setattr__(self, "validity_upper", self.upper)

    @property
    def dof(self) -> int:
        """Number of movable joints of the chain."""
        return len(self.joint_names)

    @property
    def prismatic(self) -> np.ndarray:
        """(dof,) True for prismatic joints (pose unit mm)."""
        return np.array([t == "prismatic" for t in self.joint_types])

    @property
    def continuous(self) -> np.ndarray:
        """(dof,) True for continuous joints (no limits; a turn of 360 joint deg is the same
        pose)."""
        return np.array([t == "continuous" for t in self.joint_types], dtype=bool)

    @property
    def pose_unit(self) -> str:
        """How poses are given: ``motor deg`` or ``joint deg`` (mm for prismatic joints)."""
        if self.has_motor_map:
            return "motor deg"
        return "joint deg, mm for prismatic" if self.prismatic.any() else "joint deg"

    def unit(self, joint: int) -> str:
        """The unit of one joint's pose value: ``motor deg``, ``deg`` or ``mm``."""
        if self.has_motor_map:
            return "motor deg"
        return "mm" if self.joint_types[joint] == "prismatic" else "deg"

    @property
    def urdf_model(self) -> UrdfModel:
        """The URDF as read when the robot was loaded (:mod:`ikbench.core.urdf_model`): links,
        joints, limits, velocities, collision elements, and the text the libraries load."""
        if "urdf_model" not in self._cache:
            self._cache["urdf_model"] = load_urdf_model(self.urdf_path)
        return self._cache["urdf_model"]

    @property
    def urdf_sha256(self) -> str:
        """SHA-256 of the URDF file (recorded with results)."""
        return self.urdf_model.sha256

    @property
    def sample_lower(self) -> np.ndarray:
        """Lower limits with continuous joints at -180 deg (for sampling poses)."""
        return np.where(np.isfinite(self.lower), self.lower, -180.0)

    @property
    def sample_upper(self) -> np.ndarray:
        """Upper limits with continuous joints at +180 deg (for sampling poses)."""
        return np.where(np.isfinite(self.upper), self.upper, 180.0)

    def describe(self) -> dict:
        """Name, dof, end frame, source and URDF hash (``ikbench robots``, run.json)."""
        return {"name": self.name, "dof": self.dof, "base_link": self.root_link,
                "end_frame": self.end_frame, "joints": list(self.joint_names),
                "pose_unit": self.pose_unit, "urdf": self.urdf_path.name,
                "urdf_sha256": self.urdf_sha256,
                **({"locked_urdf": dict(self.locked_urdf)} if self.locked_urdf else {}),
                "description": self.config.description,
                "source": self.config.source}

    # ----- pose units <-> URDF units ---------------------------------------------------------
    @overload
    def to_urdf(self, q: torch.Tensor) -> torch.Tensor: ...
    @overload
    def to_urdf(self, q: npt.ArrayLike) -> np.ndarray: ...

    def to_urdf(self, q: Any) -> Any:
        """Poses [pose units] -> URDF joint values [rad, m]; numpy arrays or tensors (..., dof)."""
        scale, offset, si = self._map_constants(q)
        return (q * scale + offset) * si

    @overload
    def from_urdf(self, q_urdf: torch.Tensor) -> torch.Tensor: ...
    @overload
    def from_urdf(self, q_urdf: npt.ArrayLike) -> np.ndarray: ...

    def from_urdf(self, q_urdf: Any) -> Any:
        """Inverse of :meth:`to_urdf`."""
        scale, offset, si = self._map_constants(q_urdf)
        return (q_urdf / si - offset) / scale

    def motor_to_joint_rad(self, poses: npt.ArrayLike) -> np.ndarray:
        """Poses [pose units: Robot.pose_unit] -> URDF joint values (the older name of
        :meth:`to_urdf`)."""
        return self.to_urdf(poses)

    def joint_rad_to_motor_deg(self, q_rad: npt.ArrayLike) -> np.ndarray:
        """URDF joint values -> poses (the older name of :meth:`from_urdf`)."""
        return self.from_urdf(q_rad)

    def _map_constants(self, like):
        constants = (self.scale, self.offset_deg, self._si_per_unit)
        if isinstance(like, np.ndarray) or np.isscalar(like) or isinstance(like, list):
            return constants
        import torch

        key = ("map", like.dtype, like.device)
        if key not in self._cache:
            self._cache[key] = tuple(torch.as_tensor(c, dtype=like.dtype, device=like.device)
                                     for c in constants)
        return self._cache[key]

    # ----- validation -------------------------------------------------------------------------
    def check_pose(self, pose: npt.ArrayLike, what: str = "pose",
                   tol_deg: float = RANGE_TOLERANCE_DEG) -> np.ndarray:
        """Validate one pose [pose units: Robot.pose_unit] (length, finite, within the limits
        to ``tol_deg`` [pose units]); return it as float64.

        Raises:
            InputError: naming the bad entry and the allowed values.
        """
        try:
            array = np.asarray(pose, dtype=float)
        except (TypeError, ValueError):
            raise InputError(
                f"{what}: {pose!r} is not a list of {self.dof} numbers "
                f"({self.pose_unit}, order {', '.join(self.joint_names)})"
            ) from None
        if array.shape != (self.dof,):
            kind = "values" if self.prismatic.any() else "angles"
            raise InputError(
                f"{what}: expected {self.dof} {kind} ({', '.join(self.joint_names)}; "
                f"{self.pose_unit}), got {array.size}"
            )
        for j, (name, value, lo, hi) in enumerate(zip(
                self.joint_names, array, self.lower, self.upper)):
            if not math.isfinite(value):
                raise InputError(f"{what}: {name} = {value} is not a finite number")
            if value < lo - tol_deg or value > hi + tol_deg:
                raise InputError(f"{what}: {name} = {value:g} {self.unit(j)} is outside its "
                                 f"range [{lo:g}, {hi:g}]")
        return array

    def check_poses(self, poses: npt.ArrayLike, what: str = "poses") -> np.ndarray:
        """Validate poses (B, dof) or (dof,); InputError naming the shape expected."""
        array = np.asarray(poses, dtype=float)
        if array.ndim not in (1, 2) or array.shape[-1] != self.dof:
            raise InputError(f"{what}: shape {array.shape} is not (B, {self.dof}) or "
                             f"({self.dof},): {self.dof} values per pose "
                             f"({', '.join(self.joint_names)}; {self.pose_unit})")
        return array

    def within_limits(self, poses: npt.ArrayLike,
                      tol_deg: float = RANGE_TOLERANCE_DEG) -> bool:
        """True when every pose in (..., dof) [pose units: Robot.pose_unit] lies within the
        limits (+- ``tol_deg``)."""
        poses = np.asarray(poses, dtype=float)
        return bool(
            np.all(poses >= self.lower - tol_deg)
            and np.all(poses <= self.upper + tol_deg)
        )

    # ----- kinematics -------------------------------------------------------------------------
    def torch_fk(self, dtype: torch.dtype | None = None, device: str = "cpu") -> TorchFK:
        """The pytorch-kinematics FK backend (cached per dtype/device); see ``TorchFK``."""
        import torch


        dtype = dtype or torch.float32
        key = ("torch_fk", dtype, str(device))
        if key not in self._cache:
            self._cache[key] = TorchFK(self, dtype=dtype, device=device)
        return self._cache[key]

    def pinocchio_fk(self) -> PinocchioFK:
        """The Pinocchio FK backend (cached); see ``PinocchioFK``."""

        if "pin_fk" not in self._cache:
            self._cache["pin_fk"] = PinocchioFK(self)
        return self._cache["pin_fk"]

    def check_loads(self) -> None:
        """Build the Pinocchio model now (cached); InputError, one line, when it cannot be
        built (a URDF Pinocchio cannot read, a frame it cannot find, ...), so a command stops
        before any work with the reason instead of a traceback in the middle of it."""
        try:
            self.pinocchio_fk()
        except InputError:
            raise
        except Exception as exc:  # whatever Pinocchio or the URDF reader raises
            text = " ".join(str(exc).split())
            raise InputError(f"robot: {self.name}'s kinematics cannot be built "
                             f"({type(exc).__name__}: {text})") from None

    def chain_kinematics(self) -> ChainKinematics:
        """The vectorised numpy chain (cached); see ``ChainKinematics``."""

        if "chain" not in self._cache:
            self._cache["chain"] = ChainKinematics(self)
        return self._cache["chain"]

    def fk(self, poses: npt.ArrayLike, backend: str = "pinocchio") -> FKResult:
        """End point [mm] and pointing direction for poses (dof,) or (B, dof) [pose units].

        Args:
            poses: pose(s) (dof,) or (B, dof) [pose units: Robot.pose_unit].
            backend: ``"pinocchio"`` or ``"torch"`` (pytorch-kinematics, float64).

        Returns:
            FKResult with arrays of shape (B, 3) (B = 1 for a single pose).
        """
        q = np.atleast_2d(self.check_poses(poses, "fk"))
        T_base_tip = self.fk_transform(q, backend)
        return FKResult(T_base_tip[:, :3, 3] * MM_PER_M, T_base_tip[:, :3, :3]
                        @ self.pointing_axis)

    def skeleton_mm(self, poses: npt.ArrayLike) -> np.ndarray:
        """The arm as a polyline: points (B, dof + 2, 3) [mm] in the base frame for poses
        (dof,) or (B, dof) [pose units: Robot.pose_unit].

        Point 0 is the base link's origin, points 1..dof the origins of the movable joints'
        frames along the chain (Pinocchio's joint placements, which fold in the fixed joints
        between them), the last the end frame. Drawing lines through them gives the arm's
        links, base to end frame; it needs no visual shapes.
        """
        q = np.atleast_2d(self.check_poses(poses, "skeleton"))
        point_m, _, _, origins_m = self.chain_kinematics().transforms(q)
        base = np.zeros((len(q), 1, 3))
        return np.concatenate([base, origins_m, point_m[:, None]], axis=1) * MM_PER_M

    def fk_transform(self, poses: npt.ArrayLike, backend: str = "pinocchio") -> np.ndarray:
        """End-frame transforms (B, 4, 4) in the base frame [m] for poses (dof,) or
        (B, dof) [pose units: Robot.pose_unit]."""
        q = np.atleast_2d(self.check_poses(poses, "fk"))
        if backend == "pinocchio":
            return self.pinocchio_fk().transforms(q)
        if backend == "torch":
            import torch

            fk = self.torch_fk(dtype=torch.float64)
            with torch.no_grad():
                return fk.transform(torch.as_tensor(q, dtype=torch.float64)).numpy()
        raise InputError(f"backend {backend!r} is unknown; choose one of: pinocchio, torch")


# ----- loading ------------------------------------------------------------------------------
def chain_joints(urdf: UrdfModel, base_link: str, end_frame: str) -> list[UrdfJoint]:
    """The movable joints on the path base_link -> end_frame of a URDF, base first.

    Raises:
        InputError: a joint naming a link the URDF does not define, unknown link, end_frame
            not below base_link, a joint type a chain cannot hold, no movable joint on the
            path, or a chain joint :func:`check_chain_joint` refuses.
    """
    name = urdf.path.name
    if base_link not in urdf.links:
        raise InputError(f"base link: {base_link!r} is not a link of {name}; links: "
                         f"{', '.join(urdf.links)}")
    if end_frame not in urdf.links:
        raise InputError(f"end_frame: {end_frame!r} is not a link of {name}; "
                         f"{urdf.candidates_text(base_link)}")
    try:
        path = urdf.path_between(base_link, end_frame)
    except LookupError:
        raise InputError(f"end_frame: {end_frame!r} is not below the base link "
                         f"{base_link!r} in {name}; "
                         f"{urdf.candidates_text(base_link)}") from None
    joints = []
    for joint in path:
        if joint.type == "fixed":
            continue
        if joint.type not in MOVABLE_TYPES:
            raise InputError(f"{name}: joint {joint.name!r} is {joint.type!r}; a "
                             f"chain may hold {', '.join(MOVABLE_TYPES)} and fixed joints")
        check_chain_joint(joint, name)
        joints.append(joint)
    if not joints:
        raise InputError(f"{name}: no movable joint between {base_link!r} and "
                         f"{end_frame!r}")
    return joints


def check_chain_joint(joint: UrdfJoint, urdf_name: str) -> None:
    """Refuse (one line, InputError) a movable joint of a chain that would change how the
    chain is judged or solved without a word:

    - a velocity limit that is zero or negative (a joint without ``<limit>``, a continuous
      one, has none: the speed criterion is then said to be unknown, not judged);
    - limits beyond |:data:`~ikbench.core.urdf_model.MAX_LIMIT_RAD`| rad (revolute) or
      |:data:`~ikbench.core.urdf_model.MAX_LIMIT_M`| m (prismatic): sampling and the methods'
      arithmetic overflow there;
    - a ``<mimic>`` joint: every method solves a chain joint on its own, none as a follower.
    """
    where = f"robot: {urdf_name}: joint {joint.name!r} of the chain"
    if joint.mimic is not None:
        raise InputError(f"{where} mimics joint {joint.mimic!r} (<mimic>): ikbench solves "
                         "every chain joint independently and models no coupled joint; end "
                         "the chain before it (--end-frame) or make it fixed")
    if joint.velocity <= 0:  # NaN (no <limit>) is no limit known, said by the contract
        raise InputError(f'{where} has <limit velocity="{joint.velocity:g}">; a chain '
                         "joint's velocity limit must be a positive number [rad/s, m/s for "
                         "prismatic] (the speed criterion is judged against it)")
    if joint.type in ("revolute", "prismatic"):
        bound, unit = ((MAX_LIMIT_M, "m") if joint.type == "prismatic"
                       else (MAX_LIMIT_RAD, "rad"))
        if max(abs(joint.lower), abs(joint.upper)) > bound:
            hint = ("" if joint.type == "prismatic"
                    else ' (a joint that turns without limits is type="continuous")')
            raise InputError(f'{where} has <limit lower="{joint.lower:g}" upper='
                             f'"{joint.upper:g}">; a {joint.type} joint\'s limits must lie '
                             f"within +-{bound:g} {unit}{hint}")


def shipped_robots() -> dict[str, Path]:
    """name -> config path of every robot shipped in :func:`robots_dir`."""
    return {p.stem: p for p in sorted(robots_dir().glob("*.toml"))}


def _unit_axis(values, what: str) -> np.ndarray:
    axis = np.asarray(values, dtype=float)
    if axis.shape != (3,) or not np.all(np.isfinite(axis)) or not np.any(axis):
        raise InputError(f"{what}: {values!r} must be three finite numbers, not all zero")
    return axis / np.linalg.norm(axis)


def _read_config(path: Path) -> dict:
    try:
        if path.suffix == ".toml":
            config = tomllib.loads(path.read_text(encoding="utf-8"))
        else:  # the older form: a *.motors.json map that names its URDF
            spec = json.loads(path.read_text(encoding="utf-8"))
            config = {"name": path.name.removesuffix(".motors.json"), "urdf": spec["urdf"],
                      "base_link": spec["root_link"], "end_frame": spec["end_frame"],
                      "motor_map": path.name}
    except (OSError, UnicodeDecodeError, ValueError, KeyError) as exc:
        raise InputError(f"robot config {str(path)!r} cannot be read: {exc}") from None
    refuse_unknown_keys(config, CONFIG_KEYS, f"robot config {str(path)!r}")
    RobotConfig.from_dict(config, f"robot config {str(path)!r}")  # wrong types refused
    missing = [k for k in ("urdf", "end_frame") if k not in config]
    if missing:
        raise InputError(f"robot config {str(path)!r}: missing key(s) {', '.join(missing)}")
    return config


def _motor_map(path: Path, joints: list[UrdfJoint]):
    """scale, offset, lower, upper (dof,) from a ``*.motors.json`` map in the chain's order."""
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
        entries = {j["name"]: j for j in spec["joints"]}
        rows = [entries[j.name] for j in joints]
        scale = np.array([r["scale"] for r in rows], dtype=float)
        offset = np.array([r["offset_deg"] for r in rows], dtype=float)
        lower = np.array([r["lower_motor_deg"] for r in rows], dtype=float)
        upper = np.array([r["upper_motor_deg"] for r in rows], dtype=float)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"motor map {str(path)!r} cannot be used: {exc!r} (it needs name, "
                         "scale, offset_deg, lower_motor_deg, upper_motor_deg for every joint "
                         "of the chain)") from None
    return scale, offset, lower, upper


def robot_from_config(path: Path, end_frame: str | None = None) -> Robot:
    """Build a :class:`Robot` from a config file (``*.toml`` or an older ``*.motors.json``)."""
    config = _read_config(path)
    if is_package_name(config["urdf"]):  # urdf = "example-robot-data:romeo"
        try:
            urdf_path = package_urdf(config["urdf"])
        except InputError as exc:
            raise InputError(f"robot config {str(path)!r}: urdf: {exc}") from None
    else:
        urdf_path = (path.parent / config["urdf"]).resolve()
    if not urdf_path.is_file():
        raise InputError(f"robot config {str(path)!r}: URDF {str(urdf_path)!r} not found")
    end = end_frame or config["end_frame"]
    urdf = load_urdf_model(urdf_path)
    base = config.get("base_link") or urdf.root_link
    joints, locked = _split_locked(chain_joints(urdf, base, end), config.get("locked"),
                                   path)
    names = tuple(j.name for j in joints)
    if "joints" in config and tuple(config["joints"]) != names:
        raise InputError(f"robot config {str(path)!r}: joints {config['joints']} differ from "
                         f"the URDF chain {base} -> {end}: {list(names)}")
    types = tuple(j.type for j in joints)
    if config.get("motor_map"):
        scale, offset, lower, upper = _motor_map(path.parent / config["motor_map"], joints)
        has_map = True
    else:
        scale, offset = np.ones(len(joints)), np.zeros(len(joints))
        per_unit = np.array([MM_PER_M if t == "prismatic" else 1.0 / DEG2RAD for t in types])
        lower = np.array([j.lower for j in joints]) * per_unit
        upper = np.array([j.upper for j in joints]) * per_unit
        has_map = False
    valid_lower, valid_upper = _validity_limits(config.get("validity_limits"), names, lower,
                                                upper, path)
    return Robot(name=str(config.get("name") or urdf_path.stem), urdf_path=urdf_path,
                 end_frame=end, root_link=base, joint_names=names, scale=scale,
                 offset_deg=offset, lower=lower, upper=upper,
                 joint_types=types,
                 pointing_axis=_unit_axis(config.get("pointing_axis", (0, 0, 1)),
                                          f"{path.name}: pointing_axis"),
                 has_motor_map=has_map, config=RobotConfig.from_dict(
                     config, f"robot config {str(path)!r}", path),
                 locked_urdf=locked, validity_lower=valid_lower, validity_upper=valid_upper,
                 _cache={"urdf_model": urdf})


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _split_locked(joints: list[UrdfJoint], spec, path: Path):
    """(the chain's free joints, {locked name: value [rad or m]}) from a config's ``locked``
    table (values in pose units: deg, mm for prismatic joints)."""
    if not spec:
        return joints, {}
    where = f"robot config {str(path)!r}: locked"
    by_name = {j.name: j for j in joints}
    if not isinstance(spec, dict):
        raise InputError(f"{where} must be a table of joint = value (deg, mm for prismatic)")
    locked = {}
    for name, value in spec.items():
        joint = by_name.get(name)
        if joint is None:
            raise InputError(f"{where}: {name!r} is not a joint of the chain; joints: "
                             f"{', '.join(by_name)}")
        if not _number(value):
            raise InputError(f"{where}: {name} = {value!r} is not a finite number")
        si = value / MM_PER_M if joint.type == "prismatic" else value * DEG2RAD
        if not joint.lower - 1e-12 <= si <= joint.upper + 1e-12:
            raise InputError(f"{where}: {name} = {value:g} is outside its URDF limits")
        locked[name] = float(si)
    free = [j for j in joints if j.name not in locked]
    if not free:
        raise InputError(f"{where}: every joint of the chain is locked")
    return free, locked


def _validity_limits(spec, names, lower, upper, path: Path):
    """(lower, upper) (dof,) [pose units]: the limits with a config's ``validity_limits``
    table (joint = [lower, upper]) applied; (None, None) when the config has none."""
    if not spec:
        return None, None
    where = f"robot config {str(path)!r}: validity_limits"
    if not isinstance(spec, dict):
        raise InputError(f"{where} must be a table of joint = [lower, upper]")
    lo, hi = np.array(lower, dtype=float), np.array(upper, dtype=float)
    for name, bounds in spec.items():
        if name not in names:
            raise InputError(f"{where}: {name!r} is not a joint of the pose; joints: "
                             f"{', '.join(names)}")
        if not (isinstance(bounds, list) and len(bounds) == 2 and all(map(_number, bounds))
                and bounds[0] < bounds[1]):
            raise InputError(f"{where}: {name} = {bounds!r} must be [lower, upper] with "
                             "lower < upper (pose units)")
        j = names.index(name)
        lo[j], hi[j] = max(lo[j], bounds[0]), min(hi[j], bounds[1])
    return lo, hi


def robot_from_urdf(urdf_path: Path, end_frame: str, base_link: str | None = None) -> Robot:
    """A robot from a bare URDF: the chain from its root (or ``base_link``) to ``end_frame``;
    poses in joint degrees (mm for prismatic joints), the end frame's z-axis points."""
    urdf = load_urdf_model(urdf_path)
    base = base_link or urdf.root_link
    joints = chain_joints(urdf, base, end_frame)
    types = tuple(j.type for j in joints)
    per_unit = np.array([MM_PER_M if t == "prismatic" else 1.0 / DEG2RAD for t in types])
    return Robot(name=urdf_path.stem, urdf_path=urdf_path.resolve(), end_frame=end_frame,
                 root_link=base, joint_names=tuple(j.name for j in joints),
                 scale=np.ones(len(joints)), offset_deg=np.zeros(len(joints)),
                 lower=np.array([j.lower for j in joints]) * per_unit,
                 upper=np.array([j.upper for j in joints]) * per_unit,
                 joint_types=types, has_motor_map=False,
                 config=RobotConfig(
                     description=f"{urdf_path.name}, chain {base} -> {end_frame}",
                     source=str(urdf_path)),
                 _cache={"urdf_model": urdf})


def robot_from_package(name: str, end_frame: str | None) -> Robot:
    """A robot of an installed description package, ``PACKAGE:NAME``
    (:mod:`ikbench.core.robot_packages`); named ``NAME``, its source the package."""
    from dataclasses import replace


    urdf_path, base, end, description = resolve(name, end_frame)
    robot = robot_from_urdf(urdf_path, end, base)
    return replace(robot, name=name.partition(":")[2], _cache={"urdf_model": robot.urdf_model},
                   config=RobotConfig(description=description, source=name))


@functools.lru_cache(maxsize=16)
def _load(name_or_path: str, end_frame: str | None) -> Robot:

    shipped = shipped_robots()
    if name_or_path in shipped:
        return robot_from_config(shipped[name_or_path], end_frame)
    if is_package_name(name_or_path):
        return robot_from_package(name_or_path, end_frame)
    path = Path(name_or_path)
    if path.suffix.lower() == ".urdf":
        if not path.is_file():
            raise InputError(f"robot: URDF {name_or_path!r} not found")
        if not end_frame:
            urdf = load_urdf_model(path)  # a broken file is refused before the end frame
            raise InputError(f"robot: {name_or_path}: a bare URDF needs an end frame, a link "
                             "(--end-frame LINK; the chain runs from the URDF's root to that "
                             f"link); {urdf.candidates_text()}")
        return robot_from_urdf(path, end_frame)
    if path.suffix.lower() in (".toml", ".json") and path.is_file():
        return robot_from_config(path, end_frame)
    if path.name.endswith(".motors.json") or path.suffix.lower() in (".toml", ".json"):
        raise InputError(f"robot: robot config {name_or_path!r} not found")
    raise InputError(f"robot: {name_or_path!r} is not a shipped robot ("
                     f"{', '.join(shipped) or 'none'}), a robot config (*.toml), a URDF "
                     "(*.urdf, with an end frame) or PACKAGE:NAME from an installed description "
                     "package (ikbench robots --all lists them)")


def load_robot(name_or_path: str | Path = DEFAULT_ROBOT, end_frame: str | None = None) -> Robot:
    """Load a robot by name, config file or bare URDF.

    Args:
        name_or_path: a shipped robot's name (``"nico_right_arm"``; ``ikbench robots`` lists
            them), a robot config (``*.toml``, or an older ``*.motors.json``), or a URDF.
        end_frame: the end link; required with a bare URDF, optional otherwise (it replaces
            the config's).

    Raises:
        InputError: naming the bad value and what is allowed.
    """
    return _load(str(name_or_path), end_frame or None)


def as_robot(robot: Robot | str | Path | None) -> Robot:
    """``robot`` itself, or the robot a name/config/URDF path names (None: the default)."""
    return robot if isinstance(robot, Robot) else load_robot(robot or DEFAULT_ROBOT)


def unwrap_continuous(robot: Robot, poses: npt.ArrayLike) -> np.ndarray:
    """Poses (..., n+1, dof) [pose units] with each continuous joint unwrapped along each path.

    A step of more than half a turn (180 joint deg) between consecutive poses in a continuous
    joint is replaced by the same pose a whole number of turns away (``np.unwrap``), so the
    path never turns such a joint the long way round; values may leave [-180, 180]. The first
    pose, every bounded joint (revolute with limits, prismatic) and the FK are unchanged. This
    is what every writer of a trajectory file and every timing applies.
    """
    out = np.array(poses, dtype=float)
    mask = robot.continuous
    if out.ndim < 2 or out.shape[-2] < 2 or not mask.any():
        return out
    scale = np.broadcast_to(np.asarray(robot.scale, dtype=float), (robot.dof,))
    for j in np.flatnonzero(mask):
        out[..., j] = np.unwrap(out[..., j], period=360.0 / abs(float(scale[j])), axis=-1)
    return out


def pose_difference(robot: Robot, poses: npt.ArrayLike, goal: npt.ArrayLike) -> np.ndarray:
    """``poses - goal`` (..., dof) [pose units], a continuous joint's difference taken the short
    way round (within half a turn): a written trajectory is unwrapped, so its continuous joints
    may end a whole turn from a pose given in [-180, 180] and still be the same arm."""
    diff = np.asarray(poses, dtype=float) - np.asarray(goal, dtype=float)
    mask = robot.continuous
    if not mask.any():
        return diff
    turn = np.abs(360.0 / np.broadcast_to(np.asarray(robot.scale, dtype=float), (robot.dof,)))
    short = diff - turn * np.round(diff / np.where(mask, turn, 1.0))
    return np.where(mask, short, diff)


def wrap_continuous(robot: Robot, poses: npt.ArrayLike) -> np.ndarray:
    """Poses (..., dof) [pose units] with each continuous joint outside [-180, 180] joint deg
    moved by whole turns into it (values inside are kept bit for bit; bounded joints are
    unchanged): what a check against limits such as jrl's [-180, 180] deg compares."""
    out = np.array(poses, dtype=float)
    mask = robot.continuous
    if not mask.any():
        return out
    joint_deg = np.degrees(robot.to_urdf(out))
    turns = np.where(np.abs(joint_deg) > 180.0, np.round(joint_deg / 360.0), 0.0)
    scale = np.broadcast_to(np.asarray(robot.scale, dtype=float), (robot.dof,))
    shift = np.where(mask, -360.0 * turns / scale, 0.0)
    return np.where(mask, out + shift, out)

