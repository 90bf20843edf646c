"""ikpy (PyPI ``ikpy``): sequential IK walked back from the touch pose, the paper's own baseline.

The paper's authors generated their Table 2 trajectories with ikpy (andylucny/nico2,
``generate-ikpy/generate-ikpy.py``): starting at the touch pose, one
``Chain.inverse_kinematics_frame(target=frame, initial_position=previous)`` per goal point,
where ``frame`` is a 4x4 target whose translation is the goal point and whose z-axis is the
(negated) line direction. They passed no ``orientation_mode``, and ikpy then fits the position
only (``ikpy.inverse_kinematics.inverse_kinematic_optimization`` builds its residual from
``target_frame[:3, 3]`` alone): the rotation in the frame is ignored.

Orientation modes (``--ikpy-orientation``):

- ``position`` (default): the authors' call, position only (a target rotation is still built
  the way they built it, and ignored by ikpy as it was for them);
- ``pointing``: ikpy's single-axis mode, ``orientation_mode="X" | "Y" | "Z"`` on the end
  frame's pointing axis (a negative axis gets the negated direction); ikpy minimises
  ``[p - p_goal, axis - d]``, roll free. Only coordinate pointing axes are possible.

Tasks with 6-D goal frames use ``orientation_mode="all"`` (``[p - p_goal, R - R_goal]``).

The chain: ``ikpy.chain.Chain.from_urdf_file`` on the chain's URDF text with
``base_elements`` = the explicit link / joint path from the base link to the end frame, cut
after the end frame's joint, then rebuilt with ``ikpy.chain.Chain(links, active_links_mask)``
active exactly on the robot's joints, each link's ``bounds`` set to the chain's limits. ikpy
passes the bounds to ``scipy.optimize.least_squares`` (method "trf", strictly feasible
iterates), so every solution is within the limits; a warm start on a limit is first nudged
1e-3 rad inside (``strictly_inside_bounds``). ikpy returns joint values only: no iteration
count (``iterations`` counts ikpy calls) and no success flag.
"""

from __future__ import annotations

import io
import warnings
import weakref
from dataclasses import dataclass

import numpy as np

from baselines._chain import Chain, Goals, element_path
from baselines._method import ChainResult, LibraryMethod
from baselines._walk import PointResult, walk_back
from ikbench.core.errors import InputError
from ikbench.methods.base import check_choice, option

ORIENTATIONS = ("position", "pointing")
_CHAINS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class IkpySettings:
    """Settings of the ikpy walk.

    Attributes:
        orientation: ``"position"`` (the authors' call) or ``"pointing"`` (ikpy's axis mode).
    """

    orientation: str = option("position", flag="ikpy-orientation", choices=ORIENTATIONS,
                              help="position (the paper authors' call: a target frame without "
                              "orientation_mode, which fits the position only) or pointing "
                              "(ikpy's orientation_mode on the pointing axis, roll free)")

    def __post_init__(self):
        check_choice(self, "orientation", ORIENTATIONS)


def authors_rotation(direction) -> np.ndarray:
    """The target rotation the authors built (their ``rotation_from_z``): z on ``direction``,
    x = up x z with up = +y (+x when z is parallel to +-y). ikpy ignores it in position mode."""
    z = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    up = np.array([0.0, 1.0, 0.0])
    if np.isclose(abs(z @ up), 1.0):
        up = np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def ikpy_chain(chain: Chain):
    """The ikpy chain of ``chain`` and the indices of its active links (cached per chain)."""
    if chain in _CHAINS:
        return _CHAINS[chain]
    import ikpy.chain

    path = element_path(chain.urdf_text, chain.base_link, chain.end_frame)
    elements = [chain.base_link]
    for joint, _, child in path:
        elements += [joint, child]
    with warnings.catch_warnings():  # it warns about the fixed links of its default mask
        warnings.simplefilter("ignore")
        full = ikpy.chain.Chain.from_urdf_file(io.StringIO(chain.urdf_text),
                                               base_elements=elements, name=chain.end_frame)
        names = [link.name for link in full.links]
        links = full.links[:names.index(path[-1][0]) + 1]  # nothing below the end frame
        mask = [link.name in chain.joint_names for link in links]
        for link, is_active in zip(links, mask):
            if is_active:
                k = chain.joint_names.index(link.name)
                link.bounds = (float(chain.lower[k]), float(chain.upper[k]))
        ik_chain = ikpy.chain.Chain(links, active_links_mask=mask, name=chain.end_frame)
    active = np.flatnonzero(mask)
    if [links[k].name for k in active] != list(chain.joint_names):
        raise ValueError(f"ikpy's chain {names} does not hold the joints {chain.joint_names}")
    _CHAINS[chain] = (ik_chain, active)
    return _CHAINS[chain]


def axis_mode(chain: Chain) -> tuple[str, float]:
    """ikpy's ``orientation_mode`` for the pointing axis and its sign; InputError if the axis
    is not a coordinate axis of the end frame."""
    k = int(np.argmax(np.abs(chain.pointing_axis)))
    if not np.isclose(abs(chain.pointing_axis[k]), 1.0):
        raise InputError(f"--ikpy-orientation pointing: ikpy points a coordinate axis of the "
                         f"end frame; the robot's pointing axis {tuple(chain.pointing_axis)} "
                         "is none (use --ikpy-orientation position)")
    return "XYZ"[k], float(np.sign(chain.pointing_axis[k]))


def solve_chain(chain: Chain, goals: Goals, settings: IkpySettings) -> ChainResult:
    """The ikpy walk in URDF units (see the module docstring)."""
    ik_chain, active = ikpy_chain(chain)
    mode, sign = (None, 1.0) if settings.orientation == "position" else axis_mode(chain)
    if goals.rotations is not None:
        mode = "all"
    kwargs = {} if mode is None else {"orientation_mode": mode}

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        frame = np.eye(4)
        frame[:3, 3] = goals.points_m[i]
        if goals.rotations is not None:
            frame[:3, :3] = goals.rotations[i]
        else:
            frame[:3, :3] = authors_rotation(-goals.directions[i])  # as the authors built it
            if mode is not None:
                frame[:3, "XYZ".index(mode)] = sign * goals.directions[i]
        start = np.zeros(len(ik_chain.links))
        start[active] = q_warm
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            full = ik_chain.inverse_kinematics_frame(target=frame, initial_position=start,
                                                     **kwargs)
        return PointResult(np.asarray(full, dtype=float)[active], 1, True)

    walk = walk_back(solve_point, chain, goals)
    info = walk.info()
    del info["points_not_converged"]  # ikpy reports no success: unknown, not zero
    return ChainResult(walk.q, walk.iterations, True,
                       {**info, "orientation_mode": mode or "none (position only)",
                        "iterations_are": "ikpy calls (ikpy reports no iteration count)"})


class IkpyIK(LibraryMethod):
    """ikpy's ``inverse_kinematics_frame`` per point, walked back from the touch pose."""

    name = "ikpy"
    description = ("library: ikpy inverse_kinematics_frame per point, walked back from the "
                   "touch pose (the paper authors' baseline call; --ikpy-orientation)")
    library = "ikpy"
    Settings = IkpySettings
    supports_frames = True

    def check_robot(self, robot) -> None:
        """Pointing mode needs a coordinate pointing axis (ikpy's X / Y / Z modes)."""
        if self.settings.orientation == "pointing":
            from baselines._chain import chain_of

            axis_mode(chain_of(robot))

    def prepare(self, robot) -> None:
        """Untimed: parse the URDF and build ikpy's chain (sympy-compiled link matrices)."""
        from baselines._chain import chain_of

        ikpy_chain(chain_of(robot))

    def solve_chain(self, robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings)
