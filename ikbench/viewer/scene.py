"""Geometry the viewer needs besides viser: the URDF model, configurations, frames, framing.

The viewer draws the robot from its URDF's visual shapes with yourdfpy (what viser's
``ViserUrdf`` uses), while ikbench's kinematics run on Pinocchio; this module maps ikbench's
poses onto yourdfpy's configuration vector and the robot's base frame onto the URDF's root,
so that both agree (the viewer's tests check the drawn end frame against ``Robot.fk``).
"""

from __future__ import annotations

import math

import numpy as np

from ikbench.core.robot import Robot

RGB = tuple[int, int, int]
#: Run colours (RGB 0-255): matplotlib's tab10, as in the figures.
RUN_COLORS: tuple[RGB, ...] = ((31, 119, 180), (255, 127, 14), (148, 103, 189),
                               (214, 39, 40), (140, 86, 75), (227, 119, 194))
#: Goal paths (green).
GOAL_COLOR: RGB = (44, 160, 44)


def load_model(robot: Robot, meshes: bool = True):
    """The robot's URDF in yourdfpy with its visual scene graph.

    yourdfpy moves a prismatic joint along its axis as written; the URDF spec (and
    Pinocchio) normalise it, so the axes are normalised here.
    """
    import yourdfpy

    mesh_dir = str(robot.urdf_path.parent)

    def filename(fname: str) -> str:
        """``package://`` URIs of an installed description package resolved to its files
        (:func:`ikbench.core.robot_packages.resolve_package_uri`), else yourdfpy's guess."""
        from ikbench.core.robot_packages import resolve_package_uri

        found = resolve_package_uri(fname)
        return str(found) if found else yourdfpy.filename_handler_magic(fname, dir=mesh_dir)

    model = yourdfpy.URDF.load(str(robot.urdf_path), build_scene_graph=True,
                               load_meshes=meshes, mesh_dir=mesh_dir,
                               filename_handler=filename)
    for joint in model.robot.joints:
        if joint.type == "prismatic" and joint.axis is not None:
            joint.axis = np.asarray(joint.axis, dtype=float) / np.linalg.norm(joint.axis)
    return model


def configurations(model, robot: Robot, poses) -> np.ndarray:
    """(B, n_actuated) yourdfpy configurations [rad, m] of poses (B, dof) [pose units]:
    the chain's joints through ``Robot.to_urdf``, every other joint at 0 (as Pinocchio
    locks them)."""
    names = list(model.actuated_joint_names)
    q_urdf = np.atleast_2d(robot.to_urdf(np.atleast_2d(np.asarray(poses, dtype=float))))
    cfg = np.zeros((len(q_urdf), len(names)))
    cfg[:, [names.index(n) for n in robot.joint_names]] = q_urdf
    return cfg


def base_transform(model, robot: Robot) -> np.ndarray:
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
