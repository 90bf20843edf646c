"""What the two Drake methods share: the plant of a chain, the solver choice and its options.

Plant: ``MultibodyPlant(time_step=0)``, ``Parser(plant).AddModelsFromString(urdf, "urdf")``
on the chain's URDF text, the URDF's root link welded to the world (``plant.WeldFrames``;
Drake would give it a floating joint otherwise), ``plant.Finalize()``. Drake warns once per
joint whose ``<dynamics>`` has a friction (it ignores joint friction, which kinematics do not
use): those warnings become one line (:func:`add_urdf`). Goals are expressed in
``plant.GetFrameByName(base_link)``. The chain's joints are the plant's positions (the other
joints are fixed in the text), mapped by ``joint.position_start()``.

Solver (``--drake-solver``): ``auto`` lets ``pydrake.solvers.Solve`` choose (SNOPT for these
nonlinear programs; the pip wheel bundles it), or ``snopt`` / ``ipopt`` / ``nlopt`` by name.
The tolerances set: SNOPT's "Major feasibility tolerance" / "Major optimality tolerance",
IPOPT's ``constr_viol_tol`` / ``tol``, NLopt's ``xtol_rel`` (optimality only).

Obstacles (:func:`drake_scene_chain`, only for a task with obstacles: without them the plant
above is used unchanged). The same URDF in a ``DiagramBuilder`` with
``AddMultibodyPlantSceneGraph(builder, 0.0)``; the robot's capsules
(:mod:`ikbench.schemes.collision`) registered on their links' bodies
(``plant.RegisterCollisionGeometry(body, X_BG, Capsule(radius, length), ...)``, the capsule's
axis its local z, X_BG from its two end points), the obstacles on the world body (``Box``,
``Sphere``, ``Capsule``; a half-space as a large box). Collision filters
(``scene_graph.collision_filter_manager().Apply(CollisionFilterDeclaration()...)``):
``ExcludeWithin`` every robot geometry, then ``AllowBetween`` the capsules of each of the
collision model's ``self_pairs``; robot-obstacle pairs stay (Drake itself filters the
geometry welded to the world, e.g. the base link, against the obstacles: no joint moves it).
The programs then add ``MinimumDistanceLowerBoundConstraint`` (bound = the clearance) on the
plant context of the diagram's context.
"""

from __future__ import annotations

import logging
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ikbench.core.chatter import quiet
from ikbench.core.errors import InputError
from ikbench.schemes.chain import Chain, chain_of
from ikbench.schemes.method import LibraryMethod, shared_option

if TYPE_CHECKING:
    from ikbench.core.robot import Robot
    from ikbench.schemes.collision import Scene

SOLVERS = ("auto", "snopt", "ipopt", "nlopt")
#: The options both Drake methods take (``--drake-<field>``, :func:`drake_option`).
OPTIONS: dict[str, dict[str, Any]] = {
    "solver": {"default": "auto", "choices": SOLVERS,
               "help": "auto (Drake's choice: SNOPT) or a solver by name"},
    "feasibility_tolerance": {"default": 1e-9,
                              "help": "SNOPT major feasibility / IPOPT constr_viol_tol"},
    "optimality_tolerance": {"default": 1e-6,
                             "help": "SNOPT major optimality / IPOPT tol / NLopt xtol_rel"},
    "clearance": {"default": 5.0, "unit": "mm",
                  "help": "tasks with obstacles: the least distance kept between the robot's "
                  "capsules and the obstacles and between self pairs "
                  "(MinimumDistanceLowerBoundConstraint's bound)"},
    "influence": {"default": 1.0, "unit": "mm",
                  "help": "tasks with obstacles: pairs closer than clearance + this enter the "
                  "constraint (its influence_distance_offset)"},
}
_PLANTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class DrakeChain:
    """A chain's Drake plant.

    Attributes:
        plant: the finalised ``MultibodyPlant``.
        index: (dof,) position index of each chain joint.
        base_frame, end_frame: the plant's frames of the base link and the end frame.
        diagram, root_context, context: with obstacles (:func:`drake_scene_chain`): the
            diagram of plant and SceneGraph, its context, and the plant's context within it
            (the one collision constraints need); None otherwise.
    """

    plant: Any
    index: np.ndarray
    base_frame: Any
    end_frame: Any

    diagram: Any = None
    root_context: Any = None
    context: Any = None

    def positions(self, q_chain: npt.ArrayLike) -> np.ndarray:
        """The plant's position vector for chain joint values (dof,)."""
        q = np.zeros(self.plant.num_positions())
        q[self.index] = q_chain
        return q


class _Friction(logging.Filter):
    """Holds back Drake's per-joint "non-zero value for the 'friction' attribute" warnings,
    counting them."""

    def __init__(self) -> None:
        super().__init__()
        self.count = 0

    def filter(self, record: logging.LogRecord) -> bool:
        if "'friction' attribute" in record.getMessage():
            self.count += 1
            return False
        return True


def add_urdf(plant: Any, urdf_text: str) -> None:
    """``Parser(plant).AddModelsFromString(urdf_text, "urdf")``, Drake's per-joint friction
    warnings summarised in one line of the ``drake`` logger."""
    from pydrake.multibody.parsing import Parser

    logger = logging.getLogger("drake")
    friction = _Friction()
    logger.addFilter(friction)
    try:
        Parser(plant).AddModelsFromString(urdf_text, "urdf")
    finally:
        logger.removeFilter(friction)
    if friction.count:
        logger.warning(f"{friction.count} joint(s) of the URDF have a friction in <dynamics>; "
                       "Drake's MultibodyPlant ignores joint friction (kinematics unaffected)")


def drake_chain(chain: Chain) -> DrakeChain:
    """The chain's :class:`DrakeChain` (cached per chain)."""
    if chain in _PLANTS:
        return _PLANTS[chain]
    from pydrake.multibody.plant import MultibodyPlant

    plant = MultibodyPlant(time_step=0.0)
    with quiet("drake", loggers=("drake",)):  # a warning per URDF tag it ignores
        add_urdf(plant, chain.urdf_text)
    root = chain.urdf.root_link
    if root != "world":  # a URDF link named world is Drake's world body already (UR, xArm)
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(root))
    plant.Finalize()
    if plant.num_positions() != chain.dof:
        raise ValueError(f"Drake's plant has {plant.num_positions()} positions, the chain "
                         f"{chain.dof}")
    index = np.array([plant.GetJointByName(n).position_start() for n in chain.joint_names])
    _PLANTS[chain] = DrakeChain(plant, index, plant.GetFrameByName(chain.base_link),
                                plant.GetFrameByName(chain.end_frame))
    return _PLANTS[chain]


_SCENE_PLANTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def drake_scene_chain(chain: Chain, scene: Scene) -> DrakeChain:
    """The chain's plant with the collision geometry of ``scene``
    (:class:`ikbench.schemes.collision.Scene`) in a SceneGraph (see the module
    docstring); cached per chain and scene."""
    cache = _SCENE_PLANTS.setdefault(chain, {})
    if scene.key in cache:
        return cache[scene.key]
    from pydrake.geometry import (
        Box,
        Capsule,
        CollisionFilterDeclaration,
        GeometrySet,
        Sphere,
    )
    from pydrake.math import RigidTransform, RotationMatrix
    from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
    from pydrake.systems.framework import DiagramBuilder

    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, 0.0)
    with quiet("drake", loggers=("drake",)):  # a warning per URDF tag it ignores
        add_urdf(plant, chain.urdf_text)
    root = chain.urdf.root_link
    if root != "world":
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(root))
    friction = CoulombFriction(0.5, 0.5)

    def shape_of(shape):
        if shape.kind == "capsule":
            return Capsule(shape.radius_m, shape.length_m)
        if shape.kind == "sphere":
            return Sphere(shape.radius_m)
        return Box(*map(float, shape.size_m))

    def pose(shape):
        return RigidTransform(RotationMatrix(shape.rotation), shape.center_m)

    by_link: dict[str | None, list] = {}  # every link shape names its link
    for shape in scene.links:
        body = plant.GetBodyByName(shape.link)
        by_link.setdefault(shape.link, []).append(plant.RegisterCollisionGeometry(
            body, pose(shape), shape_of(shape), shape.name, friction))
    # obstacles are in the base link's frame: the base link's pose in the world is fixed
    # (every joint between the URDF root and it is fixed: only the chain's joints move)
    X_WB = _base_pose(chain, root)
    for shape in scene.obstacles:
        plant.RegisterCollisionGeometry(plant.world_body(), X_WB @ pose(shape),
                                        shape_of(shape), shape.name, friction)
    plant.Finalize()
    robot = GeometrySet([g for ids in by_link.values() for g in ids])
    declaration = CollisionFilterDeclaration().ExcludeWithin(robot)
    for a, b in scene.self_pairs:
        declaration.AllowBetween(GeometrySet(by_link[a]), GeometrySet(by_link[b]))
    scene_graph.collision_filter_manager().Apply(declaration)
    diagram = builder.Build()
    diagram_context = diagram.CreateDefaultContext()
    context = plant.GetMyMutableContextFromRoot(diagram_context)
    index = np.array([plant.GetJointByName(n).position_start() for n in chain.joint_names])
    result = DrakeChain(plant, index, plant.GetFrameByName(chain.base_link),
                        plant.GetFrameByName(chain.end_frame), diagram, diagram_context,
                        context)
    cache[scene.key] = result
    return result


def _base_pose(chain: Chain, root: str):
    """World <- base link, on the plain plant (the base is fixed in the world)."""
    plain = drake_chain(chain)
    context = plain.plant.CreateDefaultContext()
    return plain.plant.CalcRelativeTransform(context, plain.plant.world_frame(),
                                             plain.base_frame)


def min_distance_constraint(drake: DrakeChain, clearance_m: float, influence_m: float) -> Any:
    """``MinimumDistanceLowerBoundConstraint(plant, clearance, plant_context, None,
    influence)`` on ``drake`` (a :func:`drake_scene_chain`): every unfiltered pair at least
    ``clearance_m`` apart (pairs farther than clearance + influence are not evaluated)."""
    from pydrake.multibody.inverse_kinematics import MinimumDistanceLowerBoundConstraint

    return MinimumDistanceLowerBoundConstraint(drake.plant, clearance_m, drake.context,
                                               None, influence_m)


def make_solver(name: str) -> Any:
    """The Drake solver called ``name`` (None for ``auto``); InputError if not usable here."""
    if name == "auto":
        return None
    from pydrake.solvers import IpoptSolver, NloptSolver, SnoptSolver

    solver = {"snopt": SnoptSolver, "ipopt": IpoptSolver, "nlopt": NloptSolver}[name]()
    if not (solver.available() and solver.enabled()):
        raise InputError(f"--drake-solver {name}: this Drake build cannot use it "
                         "(not available or not enabled)")
    return solver


def set_tolerances(prog: Any, feasibility: float, optimality: float,
                   major_iterations: int | None = None) -> None:
    """Set the tolerances (and SNOPT's major iteration limit) for every solver on ``prog``."""
    from pydrake.solvers import IpoptSolver, NloptSolver, SnoptSolver

    snopt, ipopt = SnoptSolver().solver_id(), IpoptSolver().solver_id()
    prog.SetSolverOption(snopt, "Major feasibility tolerance", feasibility)
    prog.SetSolverOption(snopt, "Major optimality tolerance", optimality)
    if major_iterations is not None:
        prog.SetSolverOption(snopt, "Major iterations limit", int(major_iterations))
    prog.SetSolverOption(ipopt, "constr_viol_tol", feasibility)
    prog.SetSolverOption(ipopt, "tol", optimality)
    prog.SetSolverOption(NloptSolver().solver_id(), "xtol_rel", optimality)


def solve(prog: Any, solver: Any, initial_guess: npt.ArrayLike | None = None) -> Any:
    """Solve ``prog`` with ``solver`` (None: ``pydrake.solvers.Solve`` chooses)."""
    from pydrake.solvers import Solve

    if solver is None:
        return Solve(prog, initial_guess)
    return solver.Solve(prog, initial_guess, None)


def exit_code(result: Any) -> int | None:
    """SNOPT's exit code (1 = optimal) or IPOPT's status; None for other solvers."""
    details = result.get_solver_details()
    for attribute in ("info", "status"):
        if hasattr(details, attribute):
            return int(getattr(details, attribute))
    return None


def drake_option(name: str, **changes: Any) -> Any:
    """The settings field ``name`` of :data:`OPTIONS` (``changes``: another default or
    help for one method)."""
    return shared_option(OPTIONS, "drake", name, **changes)


class DrakeMethod(LibraryMethod):
    """A method on a Drake plant: checks its solver choice up front; builds the plant untimed.

    Subclasses set ``settings.solver`` (one of :data:`SOLVERS`) and ``solve_chain``.
    """

    def check_robot(self, robot: Robot) -> None:
        make_solver(self.settings.solver)

    def prepare(self, robot: Robot) -> None:
        """Untimed: Drake parses the URDF and finalises its plant."""
        drake_chain(chain_of(robot))
