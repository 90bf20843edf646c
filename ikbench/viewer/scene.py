"""Geometry the viewer needs besides viser: the URDF model, configurations, frames, framing.

The viewer draws the robot from its URDF's visual shapes with yourdfpy (what viser's
``ViserUrdf`` uses), while ikbench's kinematics run on Pinocchio; this module maps ikbench's
poses onto yourdfpy's configuration vector and the robot's base frame onto the URDF's root,
so that both agree (the viewer's tests check the drawn end frame against ``Robot.fk``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.robot import Robot
from ikbench.core.robot_packages import resolve_package_uri
from ikbench.render.arm_plots import colliding_waypoints, halfspace_patch

if TYPE_CHECKING:
    import viser
    import yourdfpy

    from ikbench.core.obstacles import Obstacle

RGB = tuple[int, int, int]
#: Run colours (RGB 0-255): matplotlib's tab10, as in the figures.
RUN_COLORS: tuple[RGB, ...] = ((31, 119, 180), (255, 127, 14), (148, 103, 189),
                               (214, 39, 40), (140, 86, 75), (227, 119, 194))
#: Goal paths (green).
GOAL_COLOR: RGB = (44, 160, 44)


def load_model(robot: Robot, meshes: bool = True) -> yourdfpy.URDF:
    """The robot's URDF in yourdfpy with its visual scene graph.

    yourdfpy moves a prismatic joint along its axis as written; the URDF spec (and
    Pinocchio) normalise it, so the axes are normalised here.
    """
    import yourdfpy

    mesh_dir = str(robot.urdf_path.parent)

    def filename(fname: str) -> str:
        """``package://`` URIs of an installed description package resolved to its files
        (:func:`ikbench.core.robot_packages.resolve_package_uri`), else yourdfpy's guess."""

        found = resolve_package_uri(fname)
        return str(found) if found else yourdfpy.filename_handler_magic(fname, dir=mesh_dir)

    model = robot.urdf_model.to_yourdfpy(build_scene_graph=True, load_meshes=meshes,
                                         mesh_dir=mesh_dir, filename_handler=filename)
    for joint in model.robot.joints:
        if joint.type == "prismatic" and joint.axis is not None:
            joint.axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
    return model


def configurations(model: yourdfpy.URDF, robot: Robot, poses: npt.ArrayLike) -> np.ndarray:
    """(B, n_actuated) yourdfpy configurations [rad, m] of poses (B, dof) [pose units]:
    the chain's joints through ``Robot.to_urdf``, every other joint at 0 (as Pinocchio
    locks them)."""
    names = list(model.actuated_joint_names)
    q_urdf = np.atleast_2d(robot.to_urdf(np.atleast_2d(np.asarray(poses, dtype=float))))
    cfg = np.zeros((len(q_urdf), len(names)))
    cfg[:, [names.index(n) for n in robot.joint_names]] = q_urdf
    return cfg


def base_transform(model: yourdfpy.URDF, robot: Robot) -> np.ndarray:
    """T_root_base (4, 4): the robot's base link in the URDF's root frame (other joints 0)."""
    model.update_cfg(np.zeros(len(model.actuated_joint_names)))
    return np.asarray(model.get_transform(robot.root_link), dtype=float)


def to_root_m(T_root_base: np.ndarray, points_mm: np.ndarray) -> np.ndarray:
    """Points (..., 3) [mm] in the base frame -> the URDF's root frame [m]."""
    return points_mm / 1000.0 @ T_root_base[:3, :3].T + T_root_base[:3, 3]


def view_direction(elevation_deg: float, azimuth_deg: float) -> np.ndarray:
    """Unit vector from the scene towards the camera for a matplotlib-style view."""
    e, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def camera_pose(points_m: np.ndarray, direction: np.ndarray,
                fov_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera position and look-at point [m] that frame ``points_m`` (N, 3) from
    ``direction``."""
    lo, hi = points_m.min(axis=0), points_m.max(axis=0)
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(points_m - centre, axis=1).max()), 0.05)
    distance = radius / math.sin(fov_rad / 2)  # the bounding sphere fits the view
    return centre + direction / np.linalg.norm(direction) * distance, centre


def segments(points: np.ndarray) -> np.ndarray:
    """(N-1, 2, 3) consecutive segments of a polyline (N >= 2)."""
    return np.stack([points[:-1], points[1:]], axis=1)


def lighter(rgb: RGB, amount: float = 0.6) -> RGB:
    """``rgb`` blended towards white by ``amount`` (0: unchanged, 1: white)."""
    r, g, b = (int(round(c + (255 - c) * amount)) for c in rgb)
    return r, g, b


# ----- obstacles and collisions (Task.obstacles, ikbench.core.collision) ----------------------

#: Obstacles (translucent brown) and the markers at colliding waypoints (red), RGB 0-255.
OBSTACLE_COLOR: RGB = (153, 115, 77)
OBSTACLE_OPACITY = 0.45
COLLISION_COLOR: RGB = (220, 20, 20)


def rotation_wxyz(R: np.ndarray) -> np.ndarray:
    """(4,) the unit quaternion (w, x, y, z) of a rotation matrix (viser's ``wxyz``)."""
    R = np.asarray(R, dtype=float)
    t = np.trace(R)
    # Shepperd: from the largest of 4w^2, 4x^2, 4y^2, 4z^2 (no cancellation near 180 deg)
    k = int(np.argmax([t, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        r = math.sqrt(1.0 + t)
        q = np.array([r, (R[2, 1] - R[1, 2]) / r, (R[0, 2] - R[2, 0]) / r,
                      (R[1, 0] - R[0, 1]) / r])
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        r = math.sqrt(max(1.0 + R[i, i] - R[j, j] - R[m, m], 1e-300))
        q = np.empty(4)
        q[0] = (R[m, j] - R[j, m]) / r
        q[1 + i], q[1 + j], q[1 + m] = r, (R[j, i] + R[i, j]) / r, (R[m, i] + R[i, m]) / r
    return q / np.linalg.norm(q)


def capsule_mesh(radius_mm: float, length_mm: float, rings: int = 8,
                 sectors: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """(vertices (V, 3) [mm], faces (F, 3)) of a capsule along the local z, centred: a UV
    sphere whose upper half is moved up and lower half down by ``length_mm / 2``."""
    polar = np.concatenate([np.linspace(0, np.pi / 2, rings + 1),
                            np.linspace(np.pi / 2, np.pi, rings + 1)])
    shift = np.where(np.arange(len(polar)) <= rings, 0.5, -0.5) * length_mm
    azim = np.linspace(0, 2 * np.pi, sectors, endpoint=False)
    p, a = np.meshgrid(polar, azim, indexing="ij")
    vertices = np.stack([radius_mm * np.sin(p) * np.cos(a), radius_mm * np.sin(p) * np.sin(a),
                         radius_mm * np.cos(p) + shift[:, None]], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(len(polar) - 1):
        for j in range(sectors):
            a0, a1 = i * sectors + j, i * sectors + (j + 1) % sectors
            b0, b1 = a0 + sectors, a1 + sectors
            faces += [[a0, b0, b1], [a0, b1, a1]]
    return vertices, np.array(faces, dtype=np.int32)


def add_obstacles(server: viser.ViserServer, obstacles: Sequence[Obstacle],
                  T_root_base: np.ndarray, around_mm: np.ndarray | None = None,
                  name: str = "/obstacles") -> list:
    """Add a task's obstacles to a viser scene (translucent brown; base frame [mm] -> the
    URDF's root [m]): boxes with ``add_box``, spheres with ``add_icosphere``, capsules and
    a half-space's surface (a square around ``around_mm`` (N, 3) [mm], base frame: e.g. the
    goal path; :func:`ikbench.render.arm_plots.halfspace_patch`) with ``add_mesh_simple``.
    Returns the handles, one per obstacle."""

    R_root = np.asarray(T_root_base, dtype=float)[:3, :3]
    style: dict[str, Any] = {"color": OBSTACLE_COLOR, "opacity": OBSTACLE_OPACITY}
    handles = []
    for k, obstacle in enumerate(obstacles):
        node = f"{name}/{k}_" + "".join(c if c.isalnum() or c in "_-." else "_"
                                        for c in obstacle.name)
        position = to_root_m(T_root_base, np.asarray(obstacle.center_mm, dtype=float))
        wxyz = rotation_wxyz(R_root @ np.asarray(obstacle.rotation, dtype=float))
        if obstacle.kind == "box":
            handle = server.scene.add_box(node, dimensions=tuple(np.asarray(
                obstacle.size_mm, dtype=float) / 1000.0), wxyz=wxyz, position=position,
                side="double", **style)
        elif obstacle.kind == "sphere":
            handle = server.scene.add_icosphere(node, radius=obstacle.radius_mm / 1000.0,
                                                position=position, **style)
        elif obstacle.kind == "capsule":
            vertices, faces = capsule_mesh(obstacle.radius_mm, obstacle.length_mm)
            handle = server.scene.add_mesh_simple(node, vertices / 1000.0, faces, wxyz=wxyz,
                                                  position=position, side="double", **style)
        else:
            corners = to_root_m(T_root_base, halfspace_patch(obstacle, around_mm))
            handle = server.scene.add_mesh_simple(node, corners, np.array([[0, 1, 2],
                                                                            [0, 2, 3]]),
                                                  side="double", **style)
        handles.append(handle)
    return handles


def colliding_tips_m(robot: Robot, poses: npt.ArrayLike, tip_mm: np.ndarray,
                     obstacles: Sequence[Obstacle], T_root_base: np.ndarray) -> np.ndarray:
    """(K, 3) [m, URDF root] the end points of the waypoints where poses (N, dof) collide
    with an obstacle or the robot itself (:func:`ikbench.render.arm_plots.
    colliding_waypoints`); empty without obstacles, collision model or collision."""

    colliding = colliding_waypoints(robot, poses, obstacles)
    if colliding is None or not colliding.any():
        return np.zeros((0, 3))
    return to_root_m(T_root_base, np.asarray(tip_mm, dtype=float)[colliding])


def add_collision_markers(server: viser.ViserServer, name: str, robot: Robot,
                          poses: npt.ArrayLike, tip_mm: np.ndarray,
                          obstacles: Sequence[Obstacle], T_root_base: np.ndarray,
                          point_size: float = 0.012) -> viser.PointCloudHandle | None:
    """Red points at a trajectory's colliding waypoints' end points (:func:`colliding_tips_m`)
    as one viser point cloud named ``name``; None when no waypoint collides."""
    points = colliding_tips_m(robot, poses, tip_mm, obstacles, T_root_base)
    if not len(points):
        return None
    return server.scene.add_point_cloud(name, points.astype(np.float32), COLLISION_COLOR,
                                        point_size=point_size, point_shape="circle")
