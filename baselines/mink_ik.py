"""mink (PyPI ``mink``, on MuJoCo): pink's differential-IK scheme on a MuJoCo model of the URDF.

Loading: ``mujoco.MjSpec.from_string(urdf)`` on the chain's URDF text. MuJoCo's URDF importer
fuses static bodies (``spec.compiler.fusestatic`` is True after parsing a URDF), which would
merge the fixed end link into its parent: it is set False, so every link stays a body. MuJoCo
refuses massless moving bodies, and URDFs written for kinematics have no ``<inertial>``:
``compiler.boundmass`` / ``boundinertia`` give them a negligible mass (kinematics does not
depend on it). A site on the end body, its z-axis on the pointing axis
(``body.add_site(name, pos, quat)``), is the frame P the tasks act on; ``spec.compile()``.
The chain's limits replace ``model.jnt_range`` (continuous joints stay unlimited); goals are
turned from the base body's frame into MuJoCo's world frame.

Per goal point the scheme of :mod:`baselines._diffik`, with these mink calls:
``mink.Configuration(model, q)``, ``mink.FrameTask(site, "site", position_cost,
orientation_cost=[w, w, 0])`` with ``set_target(mink.SE3.from_rotation_and_translation(...))``,
``mink.solve_ik(configuration, tasks, dt, qp_solver, damping=..., limits=[mink.
ConfigurationLimit(model, gain)])`` and ``configuration.integrate(v, dt)`` / ``update(q)``.
``--mink-pointing-task axis-align`` points with ``mink.AxisAlignTask(site, "site", axis=z)``
(rank 2, roll free) beside a position-only FrameTask instead. Defaults as pink's except the
limit gain: mink's own default 0.95. ``iterations`` counts QP solves.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Any

import numpy as np

from baselines._chain import Chain, Goals
from baselines._diffik import converge, errors, orientation_costs, target_rotation
from baselines._geometry import frame_with_z_on
from baselines._method import ChainResult, LibraryMethod
from baselines._walk import PointResult, walk_back
from baselines.pink_ik import check_qp_solver
from ikbench.core.errors import InputError
from ikbench.methods.base import check_choice, check_positive, option

SITE = "ikbench_pointing_site"
POINTING_TASKS = ("frame", "axis-align")
_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass
class MinkSettings:
    """Settings of the mink walk (see the module docstring)."""

    pointing_task: str = option("frame", flag="mink-pointing-task", choices=POINTING_TASKS,
                                help="frame (FrameTask, roll cost 0) or axis-align "
                                "(AxisAlignTask beside a position-only FrameTask)")
    dt: float = option(1.0, flag="mink-dt", unit="s",
                       help="integration step of the QP velocity (1 with gain 1: a full "
                       "Gauss-Newton step)")
    damping: float = option(1e-6, flag="mink-damping",
                            help="Levenberg-Marquardt damping of the QP (solve_ik's damping)")
    position_cost: float = option(1.0, flag="mink-position-cost", unit="1/m",
                                  help="FrameTask position cost")
    orientation_cost: float = option(0.1, flag="mink-orientation-cost", unit="1/rad",
                                     help="cost of the pointing axis's tilt (roll free)")
    limit_gain: float = option(0.95, flag="mink-limit-gain",
                               help="ConfigurationLimit gain in (0, 1]")
    qp_solver: str = option("daqp", flag="mink-qp-solver", help="qpsolvers backend")
    tolerance: float = option(1e-6, flag="mink-tolerance", unit="m, rad",
                              help="stop a point when position and pointing errors are below")
    max_steps: int = option(100, flag="mink-max-steps", help="QP steps per goal point at most")

    def __post_init__(self):
        check_choice(self, "pointing_task", POINTING_TASKS)
        check_positive(self, "dt", "position_cost", "limit_gain", "tolerance")
        check_positive(self, "max_steps", integer=True)
        if self.limit_gain > 1 or self.damping < 0 or self.orientation_cost < 0:
            raise InputError("--mink-limit-gain must be in (0, 1], --mink-damping and "
                             "--mink-orientation-cost >= 0")
        self.max_steps = int(self.max_steps)
        check_qp_solver(self, "qp_solver")


@dataclass(frozen=True)
class MinkModel:
    """The compiled MuJoCo model and how the chain maps onto it.

    Attributes:
        model: ``mujoco.MjModel`` with the site P.
        qpos: (dof,) qpos address of each chain joint.
        R_EP: (3, 3) end frame -> P.
        R_wb, p_wb: (3, 3), (3,) the base body in MuJoCo's world frame [m].
    """

    model: Any
    qpos: np.ndarray
    R_EP: np.ndarray
    R_wb: np.ndarray
    p_wb: np.ndarray


def mink_model(chain: Chain) -> MinkModel:
    """The chain's :class:`MinkModel` (cached per chain)."""
    if chain in _MODELS:
        return _MODELS[chain]
    import mujoco

    spec = mujoco.MjSpec.from_string(chain.urdf_text)
    spec.compiler.fusestatic = False
    spec.compiler.boundmass = 1e-6
    spec.compiler.boundinertia = 1e-12
    R_EP = frame_with_z_on(chain.pointing_axis)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(R_EP).reshape(9))
    spec.body(chain.end_frame).add_site(name=SITE, pos=[0.0, 0.0, 0.0], quat=list(quat))
    model = spec.compile()
    if model.nq != chain.dof:
        raise ValueError(f"MuJoCo's model has {model.nq} coordinates, the chain {chain.dof}")
    for k, name in enumerate(chain.joint_names):
        j = model.joint(name).id
        limited = bool(np.isfinite(chain.lower[k]))
        model.jnt_limited[j] = limited
        model.jnt_range[j] = [chain.lower[k], chain.upper[k]] if limited else [0.0, 0.0]
    data = mujoco.MjData(model)
    mujoco.mj_kinematics(model, data)
    base = model.body(chain.base_link).id
    qpos = np.array([model.joint(name).qposadr[0] for name in chain.joint_names])
    _MODELS[chain] = MinkModel(model, qpos, R_EP, data.xmat[base].reshape(3, 3).copy(),
                               data.xpos[base].copy())
    return _MODELS[chain]


def solve_chain(chain: Chain, goals: Goals, settings: MinkSettings) -> ChainResult:
    """The mink walk in URDF units (see the module docstring)."""
    import mink

    m = mink_model(chain)
    model, site = m.model, m.model.site(SITE).id
    # the goals in MuJoCo's world frame
    world = Goals(goals.points_m @ m.R_wb.T + m.p_wb, goals.directions @ m.R_wb.T,
                  None if goals.rotations is None else m.R_wb @ goals.rotations, None, None)
    axis_align = settings.pointing_task == "axis-align" and goals.rotations is None
    frame_task = mink.FrameTask(SITE, "site", position_cost=settings.position_cost,
                                orientation_cost=0.0 if axis_align else
                                orientation_costs(goals, settings.orientation_cost))
    tasks: list[Any] = [frame_task]
    if axis_align:
        align = mink.AxisAlignTask(SITE, "site", axis=(0.0, 0.0, 1.0),
                                   cost=settings.orientation_cost)
        tasks.append(align)
    limits = [mink.ConfigurationLimit(model, gain=settings.limit_gain)]

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        q0 = np.zeros(model.nq)
        q0[m.qpos] = q_warm
        configuration = mink.Configuration(model, q0)
        if axis_align:
            align.set_target(world.directions[i])

        def frame():
            data = configuration.data
            return data.site_xpos[site].copy(), data.site_xmat[site].reshape(3, 3).copy()

        def step():
            p_P, R_P = frame()
            R = R_P if axis_align else target_rotation(world, i, R_P, m.R_EP)
            frame_task.set_target(mink.SE3.from_rotation_and_translation(
                mink.SO3.from_matrix(R), world.points_m[i]))
            v = mink.solve_ik(configuration, tasks, settings.dt, settings.qp_solver,
                              damping=settings.damping, limits=limits)
            q = configuration.integrate(v, settings.dt)
            q[m.qpos] = chain.clip(q[m.qpos])
            configuration.update(q)

        def measure():
            p_P, R_P = frame()
            return errors(world, i, p_P, R_P, m.R_EP)

        steps, ok = converge(measure, step, settings.tolerance, settings.max_steps)
        return PointResult(configuration.q[m.qpos].copy(), steps, ok)

    walk = walk_back(solve_point, chain, goals)
    return ChainResult.from_walk(walk, qp_solver=settings.qp_solver,
                                 pointing_task=settings.pointing_task,
                                 iterations_are="QP solves (mink.solve_ik calls)")


class MinkIK(LibraryMethod):
    """mink's QP differential IK on MuJoCo per point, walked back from the touch pose."""

    name = "mink"
    description = ("library: mink QP differential IK on MuJoCo (the URDF loaded by MuJoCo) "
                   "per point, walked back from the touch pose")
    library = "mink"
    Settings = MinkSettings
    supports_frames = True

    def prepare(self, robot) -> None:
        """Untimed: MuJoCo parses and compiles the URDF."""
        from baselines._chain import chain_of

        mink_model(chain_of(robot))

    def solve_chain(self, robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(chain, goals, self.settings)
