"""pink (PyPI ``pin-pink``): QP differential IK on Pinocchio, walked back from the touch pose.

pink works on the robot's own Pinocchio model (:meth:`ikbench.core.robot.Robot.pinocchio_fk`:
the chain only, the base link as world frame), copied once per robot with the chain's limits
and an extra operational frame P on the end frame whose z-axis is the pointing axis
(``model.addFrame(pinocchio.Frame(..., OP_FRAME))``). Per goal point the scheme of
:mod:`baselines._diffik`, with these pink calls:

- ``pink.tasks.FrameTask(P, position_cost, orientation_cost=[w, w, 0])`` and
  ``task.set_target(pinocchio.SE3(R, p))``;
- ``pink.solve_ik(configuration, [task], dt, solver=qp_solver, damping=damping,
  limits=[pink.limits.ConfigurationLimit(model, config_limit_gain)])``: the joint limits are QP
  constraints ``q_min - q <= v dt <= q_max - q`` (scaled by the gain), so no step leaves them;
- ``configuration.integrate(v, dt)`` and ``configuration.update(q)``.

pink's frame error is P's body twist log(T_P^-1 T_target), so the zero cost on P's z frees the
roll. Defaults: dt 1 s with task gain 1 (a full damped Gauss-Newton step per QP), damping 1e-6
(the 7-DoF arm is redundant: a positive-definite QP Hessian, minimum-norm steps), position
cost 1 /m and orientation cost 0.1 /rad (they compete only where a goal is unreachable), limit
gain 0.5 (pink's default), QP solver daqp (qpsolvers backend, deterministic), tolerance 1e-6
m / rad, at most 100 steps per point. ``iterations`` counts QP solves.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from baselines._chain import Chain, Goals
from baselines._diffik import converge, errors, orientation_costs, target_rotation
from baselines._geometry import frame_with_z_on
from baselines._method import ChainResult, LibraryMethod
from baselines._walk import PointResult, walk_back
from ikbench.core.errors import InputError
from ikbench.methods.base import check_positive, option

POINTING_FRAME = "ikbench_pointing_frame"
_MODELS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def check_qp_solver(settings, field_name: str) -> None:
    """InputError naming the flag when the qpsolvers backend is not installed."""
    import qpsolvers

    value = getattr(settings, field_name)
    if value not in qpsolvers.available_solvers:
        from ikbench.methods.base import flag_of

        raise InputError(f"{flag_of(settings, field_name)}: {value!r} is not an installed "
                         f"qpsolvers backend; installed: {', '.join(qpsolvers.available_solvers)}")


@dataclass
class PinkSettings:
    """Settings of the pink walk (see the module docstring)."""

    dt: float = option(1.0, flag="pink-dt", unit="s",
                       help="integration step of the QP velocity (1 with gain 1: a full "
                       "Gauss-Newton step)")
    damping: float = option(1e-6, flag="pink-damping",
                            help="Tikhonov damping of the QP (solve_ik's damping)")
    position_cost: float = option(1.0, flag="pink-position-cost", unit="1/m",
                                  help="FrameTask position cost")
    orientation_cost: float = option(0.1, flag="pink-orientation-cost", unit="1/rad",
                                     help="FrameTask orientation cost on the pointing axis's "
                                     "tilt (roll free)")
    limit_gain: float = option(0.5, flag="pink-limit-gain",
                               help="ConfigurationLimit gain in (0, 1]")
    qp_solver: str = option("daqp", flag="pink-qp-solver", help="qpsolvers backend")
    tolerance: float = option(1e-6, flag="pink-tolerance", unit="m, rad",
                              help="stop a point when position and pointing errors are below")
    max_steps: int = option(100, flag="pink-max-steps", help="QP steps per goal point at most")

    def __post_init__(self):
        check_positive(self, "dt", "position_cost", "limit_gain", "tolerance")
        check_positive(self, "max_steps", integer=True)
        if self.limit_gain > 1 or self.damping < 0 or self.orientation_cost < 0:
            raise InputError("--pink-limit-gain must be in (0, 1], --pink-damping and "
                             "--pink-orientation-cost >= 0")
        self.max_steps = int(self.max_steps)
        check_qp_solver(self, "qp_solver")


def pink_model(robot, chain: Chain):
    """A copy of the robot's Pinocchio model with the chain's limits and the frame P."""
    if robot in _MODELS:
        return _MODELS[robot]
    import pinocchio as pin

    model = pin.Model(robot.pinocchio_fk().model)
    model.lowerPositionLimit = np.where(np.isfinite(chain.lower), chain.lower,
                                        model.lowerPositionLimit)
    model.upperPositionLimit = np.where(np.isfinite(chain.upper), chain.upper,
                                        model.upperPositionLimit)
    R_EP = frame_with_z_on(chain.pointing_axis)
    end = model.frames[model.getFrameId(chain.end_frame)]
    model.addFrame(pin.Frame(POINTING_FRAME, end.parentJoint,
                             end.placement * pin.SE3(R_EP, np.zeros(3)), pin.FrameType.OP_FRAME))
    _MODELS[robot] = (model, R_EP)
    return _MODELS[robot]


def solve_chain(robot, chain: Chain, goals: Goals, settings: PinkSettings) -> ChainResult:
    """The pink walk in URDF units (see the module docstring)."""
    import pink
    import pinocchio as pin
    from pink.limits import ConfigurationLimit
    from pink.tasks import FrameTask

    model, R_EP = pink_model(robot, chain)
    data = model.createData()
    task = FrameTask(POINTING_FRAME, position_cost=settings.position_cost,
                     orientation_cost=orientation_costs(goals, settings.orientation_cost))
    limits = [ConfigurationLimit(model, config_limit_gain=settings.limit_gain)]
    lower, upper = model.lowerPositionLimit, model.upperPositionLimit

    def solve_point(i: int, q_warm: np.ndarray) -> PointResult:
        configuration = pink.Configuration(model, data, q_warm)

        def frame():
            T = configuration.get_transform_frame_to_world(POINTING_FRAME)
            return T.translation, T.rotation

        def step():
            p_P, R_P = frame()
            task.set_target(pin.SE3(target_rotation(goals, i, R_P, R_EP), goals.points_m[i]))
            v = pink.solve_ik(configuration, [task], settings.dt, solver=settings.qp_solver,
                              damping=settings.damping, limits=limits)
            configuration.update(np.clip(configuration.integrate(v, settings.dt), lower, upper))

        def measure():
            p_P, R_P = frame()
            return errors(goals, i, p_P, R_P, R_EP)

        steps, ok = converge(measure, step, settings.tolerance, settings.max_steps)
        return PointResult(configuration.q.copy(), steps, ok)

    walk = walk_back(solve_point, chain, goals)
    return ChainResult.from_walk(walk, qp_solver=settings.qp_solver,
                                 iterations_are="QP solves (pink.solve_ik calls)")


class PinkIK(LibraryMethod):
    """pink's QP differential IK per point, walked back from the touch pose."""

    name = "pink"
    description = ("library: pink QP differential IK on Pinocchio per point (frame task with "
                   "position and pointing costs, joint limits as QP constraints), walked back "
                   "from the touch pose")
    library = "pin-pink"
    Settings = PinkSettings
    supports_frames = True
    loads_urdf = False  # the robot's own Pinocchio model

    def prepare(self, robot) -> None:
        """Untimed: the model copy with the pointing frame."""
        from baselines._chain import chain_of

        pink_model(robot, chain_of(robot))

    def solve_chain(self, robot, chain: Chain, goals: Goals) -> ChainResult:
        return solve_chain(robot, chain, goals, self.settings)
