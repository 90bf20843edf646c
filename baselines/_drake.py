"""What the two Drake methods share: the plant of a chain, the solver choice and its options.

Plant: ``MultibodyPlant(time_step=0)``, ``Parser(plant).AddModelsFromString(urdf, "urdf")``
on the chain's URDF text, the URDF's root link welded to the world (``plant.WeldFrames``;
Drake would give it a floating joint otherwise), ``plant.Finalize()``. Goals are expressed in
``plant.GetFrameByName(base_link)``. The chain's joints are the plant's positions (the other
joints are fixed in the text), mapped by ``joint.position_start()``.

Solver (``--drake-solver``): ``auto`` lets ``pydrake.solvers.Solve`` choose (SNOPT for these
nonlinear programs; the pip wheel bundles it), or ``snopt`` / ``ipopt`` / ``nlopt`` by name.
The tolerances set: SNOPT's "Major feasibility tolerance" / "Major optimality tolerance",
IPOPT's ``constr_viol_tol`` / ``tol``, NLopt's ``xtol_rel`` (optimality only).
"""

from __future__ import annotations

import weakref
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from baselines._chain import Chain, chain_of
from baselines._method import LibraryMethod
from ikbench.core.errors import InputError

SOLVERS = ("auto", "snopt", "ipopt", "nlopt")
_PLANTS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


@dataclass(frozen=True)
class DrakeChain:
    """A chain's Drake plant.

    Attributes:
        plant: the finalised ``MultibodyPlant``.
        index: (dof,) position index of each chain joint.
        base_frame, end_frame: the plant's frames of the base link and the end frame.
    """

    plant: Any
    index: np.ndarray
    base_frame: Any
    end_frame: Any

    def positions(self, q_chain) -> np.ndarray:
        """The plant's position vector for chain joint values (dof,)."""
        q = np.zeros(self.plant.num_positions())
        q[self.index] = q_chain
        return q


def urdf_root(urdf_text: str) -> str:
    """The URDF's root link (the one that is no joint's child)."""
    root = ET.fromstring(urdf_text)
    children = {j.find("child").get("link") for j in root.iter("joint")}  # type: ignore
    return next(str(name) for link in root.iter("link")
                if (name := link.get("name")) not in children)


def drake_chain(chain: Chain) -> DrakeChain:
    """The chain's :class:`DrakeChain` (cached per chain)."""
    if chain in _PLANTS:
        return _PLANTS[chain]
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    plant = MultibodyPlant(time_step=0.0)
    Parser(plant).AddModelsFromString(chain.urdf_text, "urdf")
    root = urdf_root(chain.urdf_text)
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


def make_solver(name: str):
    """The Drake solver called ``name`` (None for ``auto``); InputError if not usable here."""
    if name == "auto":
        return None
    from pydrake.solvers import IpoptSolver, NloptSolver, SnoptSolver

    solver = {"snopt": SnoptSolver, "ipopt": IpoptSolver, "nlopt": NloptSolver}[name]()
    if not (solver.available() and solver.enabled()):
        raise InputError(f"--drake-solver {name}: this Drake build cannot use it "
                         "(not available or not enabled)")
    return solver


def set_tolerances(prog, feasibility: float, optimality: float, major_iterations=None) -> None:
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


def solve(prog, solver, initial_guess=None):
    """Solve ``prog`` with ``solver`` (None: ``pydrake.solvers.Solve`` chooses)."""
    from pydrake.solvers import Solve

    if solver is None:
        return Solve(prog, initial_guess)
    return solver.Solve(prog, initial_guess, None)


def exit_code(result) -> int | None:
    """SNOPT's exit code (1 = optimal) or IPOPT's status; None for other solvers."""
    details = result.get_solver_details()
    for attribute in ("info", "status"):
        if hasattr(details, attribute):
            return int(getattr(details, attribute))
    return None


class DrakeMethod(LibraryMethod):
    """A method on a Drake plant: checks its solver choice up front; builds the plant untimed.

    Subclasses set ``settings.solver`` (one of :data:`SOLVERS`) and ``solve_chain``.
    """

    def check_robot(self, robot) -> None:
        make_solver(self.settings.solver)

    def prepare(self, robot) -> None:
        """Untimed: Drake parses the URDF and finalises its plant."""
        drake_chain(chain_of(robot))
