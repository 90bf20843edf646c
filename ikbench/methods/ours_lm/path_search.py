"""ours-lm's 6-D pose-path search, compiled: carried IK tracks from anchors along the path, the
globally shortest collision-free stitch through them, and the pose-path LM.

The numpy search (:func:`.start_search.search`) is the reference of every step; this module
runs the same steps in compiled kernels (:mod:`.compiled_paths`) with the robot's capsules
(:mod:`ikbench.core.capsules`), so that no pose of the search is a Python call:

1. **Anchors and seeds.** :data:`ANCHORS` waypoints spread over the path (both ends among
   them); at each, IK from :data:`SEEDS` poses drawn within the task's limits (the reference
   pose and a given initial configuration at the first), all anchors in one batched solve
   (:func:`.anchor_ik.first_waypoint_ik`, compiled :func:`.start_search.first_waypoint_ik`);
   the distinct converged solutions that collide with nothing are kept (where all collide,
   the clearest collision-free samples of their self-motion manifolds,
   :meth:`_Search.free_on_manifolds`).
2. **Tracks.** Each is carried forward to the last waypoint and backward to the first
   (:func:`.compiled_paths.carry_tracks`: damped least squares with joint-limit and collision
   avoidance in the null space), so every waypoint has a node from every anchor's solutions
   that got there: a carried pose within :data:`.start_search.STITCH_REACHED` of its goal that
   collides with nothing (:func:`.compiled_paths.track_nodes`).
3. **Stitch.** Dynamic programming picks one node per waypoint minimising the weighted joint
   path length (:func:`.start_search.stitch_costs`), a step above the stitch's limits costing
   :data:`.start_search.STITCH_JUMP_COST`: the shortest collision-free path through the
   nodes, switching between tracks where they meet. Where a step still exceeds CppFlow's
   limit, the window of waypoints around it is **repaired** (:meth:`_Search.repair`,
   :func:`.self_motion.repair_window`): the arm's self-motion manifold is swept at every
   waypoint of the window from the path's pose there, and the window is replaced by the
   shortest path through the collision-free samples with its steps below the limit. While
   the stitch still jumps: the first round's tracks that ran into something (an obstacle
   along any link, the robot itself, a joint limit) are carried again with the collision push
   from :data:`RESUME` waypoints before (:meth:`_Search.resume`); an end of the path with
   fewer than :data:`FEW_AT_ENDS` collision-free IK solutions gets the collision-free samples
   of its solutions' manifolds, and of those from more seeds (:meth:`_Search.augment_ends`);
   then more anchors are placed around the jumps (:data:`ROUNDS` rounds at most). A step
   that none of this brings below the limit has the whole path's manifolds swept through the
   stitch's poses, every sample a node (:meth:`_Search.add_sweeps`), once.
4. **Refine.** The pose-path LM (:func:`.compiled_paths.solve_path`; c0 L0 + c1 L1 + c6 L6 and
   the clearance penalty against obstacles and between the robot's own links) runs from the
   stitch to its stopping rule or :data:`LM_ITERATIONS`, and returns its last iterate that
   meets CppFlow's criteria with the search margin and collides with nothing: the smoothness
   term keeps shortening the path while it stays valid. Should none be valid, the next
   stitch (without the failed path's tracks at its worst waypoint) is refined, at most
   :data:`RETRIES` times.

Self-collision is always avoided when the robot has a collision model, obstacles or not.
Deterministic for a seed and a thread count (the tracks do not depend on the thread count).
"""

from __future__ import annotations

import sys
import time
from typing import TYPE_CHECKING, cast

import numpy as np

from ikbench.core.capsules import capsule_model
from ikbench.core.collision import collision_model
from ikbench.core.errors import InputError
from ikbench.core.obstacles import box
from ikbench.core.task import Goal, Hints, Requirements, Task
from ikbench.core.validity import (
    MAX_INITIAL_DISTANCE,
    MAX_JOINT_CHANGE_DEG,
    MAX_JOINT_CHANGE_MM,
    MAX_POSITION_ERROR_MM,
    MAX_ROTATION_ERROR_DEG,
)
from ikbench.methods.ours_lm import anchor_ik, self_motion
from ikbench.methods.ours_lm import compiled_paths as kernels
from ikbench.methods.ours_lm.avoidance import (
    ACTIVATION_MM,
    CARRY_GAIN,
    CARRY_MAX_STEP,
    SELF_CLEARANCE_MM,
)
from ikbench.methods.ours_lm.compiling import say_if_compiling
from ikbench.methods.ours_lm.frames import errors_from_frames
from ikbench.methods.ours_lm.search_common import (
    AVOIDANCE_GAIN,
    CARRY_DAMPING,
    CARRY_ITERATIONS,
    CARRY_RETRY,
    DROP_MM_DEG,
    SEARCH_MARGIN,
    STITCH_JUMP_COST,
    STITCH_REACHED,
    OursLMSettings,
    SearchResult,
    distinct,
    stitch_costs,
)

if TYPE_CHECKING:
    from ikbench.core.capsules import CapsuleScene
    from ikbench.core.robot import Robot
    from ikbench.core.task import Task
    from ikbench.methods.ours_lm.search_common import OursLMSettings

#: Anchor waypoints spread over the path in the first round, and IK seeds at each (twice as
#: many at the anchors of later rounds).
ANCHORS = 5
SEEDS = 16
#: An anchor's IK solution closer than this to its goal [mm and deg] is carried (the carrying
#: steps close the rest, or its poses are no nodes).
ANCHOR_TOLERANCE = 0.5
#: Rounds of anchors around the stitch's jumps (and waypoints without a node); anchors per
#: jump, waypoint offsets around it, and jumps per round at most.
ROUNDS = 3
AROUND = np.array([-20, -8, 0, 1, 9, 21])
JUMPS = 4
#: Repairs of the stitch's steps above CppFlow's limit (:func:`.self_motion.repair_window`)
#: at most; the window reaches this many waypoints beyond the steps it repairs (steps this
#: close together are repaired in one window), its sweeps this many samples each way, and the
#: repaired steps are held below this share of CppFlow's limits.
REPAIRS = 3
REPAIR_WINDOW = 30
REPAIR_SAMPLES = 100
REPAIR_STEP = 0.99
#: Steps above this many times CppFlow's limits are left to more anchors (a window rarely
#: repairs them: they join two of the arm's branches).
REPAIRABLE = 60.0 / 7.0
#: Sweeps of the self-motion manifold (:func:`.self_motion.sweep_manifolds`): samples each
#: way; at an anchor where every IK solution collides, the collision-free samples of their
#: manifolds are its solutions, this far apart [pose units] at least.
SWEEP_SAMPLES = 150
SPREAD_DEG = 10.0
#: Where the stitch still jumps, an end of the path (which the stitch cannot jump around)
#: where the first round found fewer collision-free IK solutions than this gets the sweeps'
#: samples of its IK solutions and of those from this many times the seeds.
FEW_AT_ENDS = 3
MORE = 4
#: A track carried without the collision push that stops being a node is carried again,
#: with it, from this many waypoints before.
RESUME = 10
#: Waypoints each way the tracks of those rounds are carried.
REACH = 40
#: A stitched step above this [pose units] is a jump that more anchors are placed around; the
#: LM smooths smaller excesses over the stitch's step limit.
RETRACK_STEP = 2.0 * MAX_JOINT_CHANGE_DEG
#: The refinement's shortening phases, strong to none, each tried while the last failed:
#: (smoothness weight c6, LM iterations, clearance [mm] the penalty asks for meanwhile) each,
#: validity not checked (the pose errors grow to millimetres while the path straightens out; a
#: strong one may press the path against an obstacle where the poses cannot be reached again:
#: hence the wider clearance while shortening).
SHORTEN = (((10.0, 40, 10.0), (1.0, 20, 5.0)), ())
#: LM iterations of the refinement's last phase (the task's weights) at most.
LM_ITERATIONS = 40
#: Further stitches refined when a refinement ends without a valid path, each without the
#: nodes the failed path used within this many waypoints of where it failed worst.
RETRIES = 2
STRIKE = 5
#: The poses keep this far inside the joint limits [pose units]: a joint held at a limit stays
#: within it after a trajectory CSV's rounding (10 significant digits), as ours-exact's.
BOUND_MARGIN = 1e-5
#: CppFlow's limits: position [mm], rotation [deg] (both times the search margin,
#: :data:`.start_search.SEARCH_MARGIN`, where they are used), revolute step [deg] and prismatic
#: step [mm], these two a hair inside (a step at the limit may round over it in a CSV).
LIMITS = np.array([MAX_POSITION_ERROR_MM, MAX_ROTATION_ERROR_DEG, 0.999 * MAX_JOINT_CHANGE_DEG,
                   0.999 * MAX_JOINT_CHANGE_MM])


def available(robot: Robot) -> bool:
    """True when the compiled search can run for ``robot``: numba imports and its collision
    geometry (if any) is capsules and spheres (this module imports only where numba does)."""
    return collision_model(robot) is None or capsule_model(robot) is not None


def scene_for(robot: Robot, task: Task) -> CapsuleScene | None:
    """The capsule scene of the robot with the task's obstacles (None without a model)."""
    model = capsule_model(robot)
    return None if model is None else model.scene(task.required.obstacles)


def turns(robot: Robot, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(dof,) one turn [pose units] of every continuous revolute joint (no limits of its own)
    whose task limits span a whole turn (CppFlow's [-180, 180] deg), else 0: such a joint's
    pose is equivalent modulo a turn and its steps are judged wrapped."""
    kin = robot.chain_kinematics()
    period = 2.0 * np.pi / np.abs(kin.urdf_per_unit)
    continuous = ~np.isfinite(robot.lower) & ~np.isfinite(robot.upper) \
        & ~kin.prismatic
    return np.where(continuous & (upper - lower >= period * (1.0 - 1e-9)), period, 0.0)


def unwrap(path: np.ndarray, period: np.ndarray) -> np.ndarray:
    """The path (N, dof) with each turning joint's steps taken the shorter way (continuous)."""
    if not np.any(period > 0):
        return path
    out = path.copy()
    turn = np.where(period > 0, period, 1.0)
    steps = np.diff(path, axis=0)
    wrapped = steps - turn * np.round(steps / turn)
    out[1:] = path[0] + np.cumsum(np.where(period > 0, wrapped, steps), axis=0)
    out[1:, period <= 0] = path[1:, period <= 0]
    return out


def wrap(poses: np.ndarray, period: np.ndarray, lower: np.ndarray) -> np.ndarray:
    """Poses with each turning joint brought into [lower, lower + one turn)."""
    if not np.any(period > 0):
        return poses
    turn = np.where(period > 0, period, 1.0)
    wrapped = lower + np.remainder(poses - lower, turn)
    return np.where(period > 0, wrapped, poses)


def warm_up(robot: Robot) -> None:
    """Compile (or load from numba's cache) the search's kernels outside any timed region: a
    three-waypoint path of the robot's current end frame, with a box."""
    say_if_compiling(sys.modules[__name__])

    pose = np.clip(np.zeros(robot.dof), robot.sample_lower, robot.sample_upper)
    point, rotation, _, _ = robot.chain_kinematics().frames(pose[None], False)
    points_mm = np.repeat(point * 1000.0, 3, axis=0)
    far = box("warm-up", points_mm[0] + 5000.0, [10.0, 10.0, 10.0])
    task = Task("warm-up", Goal(points_mm, np.tile([1.0, 0.0, 0.0], (3, 1)),
                                np.repeat(rotation, 3, axis=0)),
                Requirements(obstacles=(far,)), Hints(reference_pose=pose))

    s = _Search(robot, task, OursLMSettings(max_iterations=2))
    for threads in (1, 2):
        previous = kernels.set_threads(threads)
        try:
            s.add_tracks(np.array([0, 2]), 2)
        finally:
            kernels.set_threads(previous)
    # the carry, from the pose itself: add_tracks carries nothing when the pose's IK
    # solutions collide (the Panda's clipped zero pose touches itself)
    s._carry(np.array([0]), np.array([1]), np.array([3]), pose[None], True)
    s.more_solutions(0, 2)  # the anchor IK from one goal (add_tracks gave it one per seed)
    path, _ = s.stitch()
    path = np.repeat(pose[None], 3, axis=0) if path is None else path
    s.refine(path, {"L0": 1.0, "L1": 1.0, "L6": 0.001}, SHORTEN[0])
    s.add_sweeps(path)
    s.free_on_manifolds(0, path[:1], 2)
    self_motion.repair_window(s.spec, s.goals_p, s.goals_R, path, 0, 2, 2, s.weights,
                              s.step_limit, STITCH_JUMP_COST, s.period, STITCH_REACHED)


class _Search:
    """One task's search state: the kernels' spec, the goals and the tracks found so far."""

    def __init__(self, robot: Robot, task: Task, settings: OursLMSettings) -> None:
        self.robot, self.task, self.settings = robot, task, settings
        lower, upper = (np.asarray(v, dtype=float) for v in task.limits(robot))
        self.low = np.where(np.isfinite(lower), lower, robot.sample_lower)
        self.high = np.where(np.isfinite(upper), upper, robot.sample_upper)
        self.period = turns(robot, lower, upper)
        # a continuous joint bounded to one turn: searched unbounded, wrapped at the end; the
        # others kept BOUND_MARGIN inside their limits
        self.lower = np.where(self.period > 0, -np.inf, lower + BOUND_MARGIN)
        self.upper = np.where(self.period > 0, np.inf, upper - BOUND_MARGIN)
        self.task_lower = lower
        self.scene = scene_for(robot, task)
        self.spec = kernels.PathSpec(robot, self.lower, self.upper, self.scene)
        self.goals_p = np.ascontiguousarray(task.goal.points_mm, dtype=float)
        self.goals_R = np.ascontiguousarray(cast(np.ndarray, task.goal.rotations), dtype=float)
        self.n = len(self.goals_p)
        self.rng = np.random.default_rng(settings.seed)
        self.weights, self.max_step = stitch_costs(robot)
        self.step_limit = LIMITS[2:4][robot.chain_kinematics().prismatic.astype(int)]
        self.tracks = np.zeros((0, self.n, robot.dof))
        self.nodes = np.zeros((0, self.n), dtype=bool)
        self.carry_settings = np.array([CARRY_ITERATIONS, CARRY_RETRY, DROP_MM_DEG, CARRY_DAMPING,
                                        AVOIDANCE_GAIN, ACTIVATION_MM, CARRY_GAIN,
                                        CARRY_MAX_STEP])
        self.ik_iterations = self.carry_iterations = 0
        self.first_solutions = 0
        self.choice: np.ndarray | None = None
        self.repairs = 0
        self.swept = False
        self.cut: list[tuple[int, int, int, np.ndarray]] = []
        self.at_ends: dict[int, tuple] = {}

    def seeds_at(self, anchors: np.ndarray, count: int) -> np.ndarray:
        """(A, count) IK solutions per anchor, NaN where none; distinct and collision-free."""
        dof = self.robot.dof
        seeds = self.rng.uniform(self.low, self.high, (len(anchors), count, dof))
        for a, anchor in enumerate(anchors):
            if anchor == 0 and self.task.hints.reference_pose is not None:
                seeds[a, 0] = self.task.hints.reference_pose
            if anchor == 0 and self.task.required.initial_pose is not None:
                seeds[a, 1 % count] = self.task.required.initial_pose
        q, position, rotation, iterations = anchor_ik.first_waypoint_ik(
            self.spec, np.repeat(self.goals_p[anchors], count, axis=0),
            np.repeat(self.goals_R[anchors], count, axis=0), seeds.reshape(-1, dof))
        self.ik_iterations += iterations
        q = q.reshape(len(anchors), count, dof)
        ok = ((position < ANCHOR_TOLERANCE) & (rotation < ANCHOR_TOLERANCE)).reshape(
            len(anchors), count)
        out = np.full_like(q, np.nan)
        for a in range(len(anchors)):
            converged = distinct(q[a], ok[a])
            found = converged
            if found.size and self.scene is not None:
                d, _, _, _ = self.scene.distances(q[a, found], 0.0)
                found = found[np.all(d > 0.0, axis=1)]
            solutions = q[a, found]
            if not found.size and converged.size and self.scene is not None:
                solutions = self.free_on_manifolds(int(anchors[a]), q[a, converged], count)
            if anchors[a] in (0, self.n - 1):
                self.at_ends[int(anchors[a])] = (solutions, q[a, converged], count)
            out[a, :len(solutions)] = solutions
            if anchors[a] == 0:
                self.first_solutions = max(self.first_solutions, len(solutions))
        return out

    def augment_ends(self) -> bool:
        """At each end of the path (which the stitch cannot jump around) where the first
        round found fewer than :data:`FEW_AT_ENDS` collision-free IK solutions: the
        collision-free samples of the self-motion manifolds of its IK solutions and of those
        from :data:`MORE` times as many seeds (other branches of the arm), carried along the
        whole path as the first round's; False when there was nothing to add."""
        starts, anchor_of, direction = [], [], []
        for anchor, (solutions, converged, count) in self.at_ends.items():
            if len(solutions) >= FEW_AT_ENDS or self.scene is None:
                continue
            sources = np.concatenate([converged, self.more_solutions(anchor, MORE * count)])
            more = [m for m in self.free_on_manifolds(anchor, sources, count)
                    if all(np.abs(m - f).max() > SPREAD_DEG for f in solutions)]
            starts += more
            anchor_of += [anchor] * len(more)
            direction += [1 if anchor == 0 else -1] * len(more)
        self.at_ends = {}
        if starts:
            self._carry(np.array(anchor_of), np.array(direction), np.full(len(starts), self.n),
                        np.array(starts), False)
        return bool(starts)

    def more_solutions(self, waypoint: int, count: int) -> np.ndarray:
        """Distinct IK solutions (M, k) at ``waypoint`` from ``count`` more random seeds."""
        seeds = self.rng.uniform(self.low, self.high, (count, self.robot.dof))
        q, position, rotation, iterations = anchor_ik.first_waypoint_ik(
            self.spec, self.goals_p[waypoint], self.goals_R[waypoint], seeds)
        self.ik_iterations += iterations
        return q[distinct(q, (position < ANCHOR_TOLERANCE) & (rotation < ANCHOR_TOLERANCE))]

    def free_on_manifolds(self, waypoint: int, poses: np.ndarray, count: int) -> np.ndarray:
        """Up to ``count`` collision-free poses (M, k) on the self-motion manifolds of IK
        solutions ``poses`` (K, k) at ``waypoint``: their sweeps' collision-free samples, the
        clearest first, :data:`SPREAD_DEG` apart."""
        assert self.scene is not None
        sweeps = self_motion.sweep_manifolds(self.spec, self.goals_p, self.goals_R,
                                             np.full(len(poses), waypoint), poses,
                                             SWEEP_SAMPLES).reshape(-1, self.robot.dof)
        sweeps = sweeps[~np.isnan(sweeps[:, 0])]
        if not len(sweeps):
            return sweeps
        d, _, _, _ = self.scene.distances(sweeps)
        clearance = d.min(axis=1)
        chosen: list[np.ndarray] = []
        for k in np.argsort(-clearance, kind="stable"):
            if clearance[k] <= 0.0 or len(chosen) == count:
                break
            if all(np.abs(sweeps[k] - c).max() > SPREAD_DEG for c in chosen):
                chosen.append(sweeps[k])
        return np.array(chosen).reshape(-1, self.robot.dof)

    @property
    def spec_frames(self):
        return self.robot.chain_kinematics().frames

    def add_tracks(self, anchors: np.ndarray, count: int, reach: int | None = None,
                   avoid: bool = False) -> None:
        """Carry the seeds' solutions at ``anchors`` both ways, to the ends or ``reach``
        waypoints (``avoid``: pushed away from close pairs); add their nodes."""
        solutions = self.seeds_at(anchors, count)
        starts, anchor_of, direction, length = [], [], [], []
        most = self.n if reach is None else reach + 1
        for a, anchor in enumerate(anchors):
            found = solutions[a][~np.isnan(solutions[a, :, 0])]
            for sign, size in ((1, min(most, self.n - anchor)), (-1, min(most, anchor + 1))):
                if size < 2:
                    continue
                starts += list(found)
                anchor_of += [anchor] * len(found)
                direction += [sign] * len(found)
                length += [size] * len(found)
        if starts:
            self._carry(np.array(anchor_of), np.array(direction), np.array(length),
                        np.array(starts), avoid and self.scene is not None)

    def _carry(self, anchors: np.ndarray, direction: np.ndarray, length: np.ndarray,
               starts: np.ndarray, avoid: bool) -> None:
        """Carry ``starts`` (T, k) from their anchors (T,) in their directions over their
        lengths (:func:`.compiled_paths.carry_tracks`) and add the tracks and their nodes; a
        track carried without the collision push whose nodes stop before its end is noted for
        :meth:`resume`."""
        tracks, iterations = kernels.carry_tracks(
            self.spec, self.goals_p, self.goals_R, anchors, direction, length, starts, avoid,
            self.carry_settings)
        self.carry_iterations += int(iterations.sum())
        nodes = kernels.track_nodes(self.spec, self.goals_p, self.goals_R, tracks,
                                    STITCH_REACHED)
        self._restrict_start(tracks, nodes)
        self.tracks = np.concatenate([self.tracks, tracks])
        self.nodes = np.concatenate([self.nodes, nodes])
        if avoid or self.scene is None:
            return
        for t in range(len(tracks)):
            span = anchors[t] + direction[t] * np.arange(length[t])
            run = np.flatnonzero(~nodes[t, span])
            if run.size and run[0] > 0:
                at = max(0, run[0] - RESUME)
                self.cut.append((span[at], direction[t], length[t] - at, tracks[t, span[at]]))

    def resume(self) -> bool:
        """Carry the tracks cut short so far (carried without the collision push, they stop
        being nodes before their end: an obstacle, the robot itself or a joint limit) again
        from :data:`RESUME` waypoints before, with the push; False when there were none."""
        cut, self.cut = self.cut, []
        if cut:
            anchors, direction, length, starts = (np.array(v) for v in zip(*cut))
            self._carry(anchors, direction, length, starts, True)
        return bool(cut)

    def _restrict_start(self, tracks: np.ndarray, nodes: np.ndarray) -> None:
        """With an initial configuration, only first poses near it are nodes."""
        initial = self.task.required.initial_pose
        if initial is None:
            return
        urdf = self.robot.to_urdf(np.nan_to_num(tracks[:, 0]))
        near = np.linalg.norm(urdf - self.robot.to_urdf(np.asarray(initial, dtype=float)),
                              axis=1) < MAX_INITIAL_DISTANCE
        nodes[:, 0] &= near

    def stitch(self, nodes: np.ndarray | None = None) -> tuple[np.ndarray | None, np.ndarray]:
        """(the stitched path (unwrapped) or None, its jumps (waypoints i whose step to i + 1
        jumps)); ``self.choice``: its track at each waypoint."""
        self.choice = kernels.stitch_choice(self.tracks, self.nodes if nodes is None else nodes,
                                            self.weights, self.max_step, STITCH_JUMP_COST,
                                            self.period)
        if self.choice is None:
            return None, np.zeros(0, dtype=int)
        path = unwrap(self.tracks[self.choice, np.arange(self.n)], self.period)
        return path, self.jumps(path)

    def too_large(self, path: np.ndarray) -> np.ndarray:
        """Waypoints i whose step to i + 1 is above CppFlow's limits."""
        return self_motion.too_large(path, self.step_limit)

    def jumps(self, path: np.ndarray) -> np.ndarray:
        """Waypoints i whose step to i + 1 is a jump (above :data:`RETRACK_STEP`)."""
        return self_motion.too_large(path, np.maximum(self.max_step,
                                                      RETRACK_STEP / self.weights))

    def repair(self, path: np.ndarray) -> np.ndarray:
        """The path with its steps above CppFlow's limits repaired, window by window, worst
        first (:func:`.self_motion.repair_window`), while that lowers its largest step."""
        limit = REPAIR_STEP * self.step_limit
        for _ in range(REPAIRS):
            bad = self.too_large(path)
            if not bad.size:
                break
            steps = (np.abs(np.diff(path, axis=0)) / limit).max(axis=1)
            bad = bad[steps[bad] * REPAIR_STEP < REPAIRABLE]
            if not bad.size:
                break
            centre = bad[np.argmax(steps[bad])]
            near = bad[np.abs(bad - centre) <= 2 * REPAIR_WINDOW]
            first = max(0, int(near.min()) - REPAIR_WINDOW)
            last = min(self.n - 1, int(near.max()) + 1 + REPAIR_WINDOW)
            repaired = self_motion.repair_window(
                self.spec, self.goals_p, self.goals_R, path, first, last, REPAIR_SAMPLES,
                self.weights, limit, STITCH_JUMP_COST, self.period, STITCH_REACHED)
            if repaired is None or (np.abs(np.diff(repaired[first:last + 1], axis=0)) / limit
                                    ).max() >= steps[first:last].max():
                break
            path = repaired
            self.repairs += 1
        return path

    def add_sweeps(self, path: np.ndarray) -> None:
        """Sweep the self-motion manifold through the path's pose at every waypoint
        (:data:`SWEEP_SAMPLES` each way); each sample index across the waypoints becomes a
        track, its collision-free samples nodes of the stitch."""
        sweeps = self_motion.sweep_manifolds(self.spec, self.goals_p, self.goals_R,
                                             np.arange(self.n), path, SWEEP_SAMPLES)
        tracks = np.ascontiguousarray(sweeps.transpose(1, 0, 2))
        nodes = kernels.track_nodes(self.spec, self.goals_p, self.goals_R, tracks,
                                    STITCH_REACHED)
        self._restrict_start(tracks, nodes)
        self.tracks = np.concatenate([self.tracks, tracks])
        self.nodes = np.concatenate([self.nodes, nodes])
        self.swept = True

    def gaps(self) -> np.ndarray:
        """Waypoints without any node."""
        return np.flatnonzero(~self.nodes.any(axis=0))

    def refine(self, path: np.ndarray, weights: dict, shorten: tuple = ()) -> tuple:
        """:func:`.compiled_paths.solve_path` from a stitched path: the ``shorten`` phases
        (one of :data:`SHORTEN`), then the task's weights, returning the last valid iterate
        (mode 1); the iterations of all phases are summed."""
        s = self.settings
        c = np.array([weights.get("L0", 0.0), weights.get("L1", 0.0), weights.get("L6", 0.0)])
        collision = np.array([s.clearance_mm, SELF_CLEARANCE_MM,
                              s.collision_weight if self.scene is not None else 0.0])
        iterations = 0
        for c6, count, clearance_mm in shorten:
            wide = np.array([max(clearance_mm, s.clearance_mm), SELF_CLEARANCE_MM, collision[2]])
            path, _, _, used, _, _, _ = kernels.solve_path(
                self.spec, self.goals_p, self.goals_R, path, np.array([c[0], c[1], c6]), wide,
                count, s.tolerance, s.damping, SEARCH_MARGIN, LIMITS, mode=2)
            iterations += used
        poses, loss, terms, used, converged, valid, figures = kernels.solve_path(
            self.spec, self.goals_p, self.goals_R, path, c, collision,
            min(s.max_iterations, LM_ITERATIONS), s.tolerance, s.damping, SEARCH_MARGIN, LIMITS,
            mode=1)
        return poses, loss, terms, iterations + used, converged, valid, figures

    def first_pose_ok(self, poses: np.ndarray) -> bool:
        initial = self.task.required.initial_pose
        if initial is None:
            return True
        distance = np.linalg.norm(self.robot.to_urdf(poses[0])
                                  - self.robot.to_urdf(np.asarray(initial, dtype=float)))
        return bool(distance < MAX_INITIAL_DISTANCE)


def search_compiled(robot: Robot, task: Task, settings: OursLMSettings,
                    weights: dict) -> SearchResult:
    """Solve a 6-D pose path by the compiled search (see the module docstring)."""

    started = time.perf_counter()
    s = _Search(robot, task, settings)
    previous = kernels.set_threads(settings.threads)
    try:
        s.add_tracks(np.linspace(0, s.n - 1, ANCHORS).round().astype(int), SEEDS)
        t_seeds = time.perf_counter()
        path, jumps = s.stitch()
        rounds = 1
        while True:
            if path is not None:
                path = s.repair(path)
                jumps = s.jumps(path)
                if ((not jumps.size or rounds > ROUNDS) and not s.swept
                        and s.too_large(path).size):
                    s.add_sweeps(path)
                    path, _ = s.stitch()
                    assert path is not None
                    path = s.repair(path)
                    jumps = s.jumps(path)
            if (path is not None and not jumps.size) or rounds > ROUNDS:
                break
            if s.resume() or s.augment_ends():
                path, jumps = s.stitch()
                continue
            where = s.gaps() if path is None else jumps
            if not where.size:
                where = np.linspace(0, s.n - 1, ANCHORS + 2)[1:-1].round().astype(int)
            if len(where) > JUMPS:
                where = where[np.linspace(0, len(where) - 1, JUMPS).round().astype(int)]
            around = np.unique(np.clip((where[:, None] + AROUND).ravel(), 0, s.n - 1))
            s.add_tracks(around, 2 * SEEDS, REACH, avoid=True)
            path, jumps = s.stitch()
            rounds += 1
        t_carry = time.perf_counter()
        if path is None:
            if not len(s.tracks):
                raise InputError(f"trajectory {task.name!r}: no collision-free IK solution "
                                 "found at any anchor waypoint (out of reach?); try another "
                                 "--lm-seed")
            best = int(np.argmax(s.nodes.sum(axis=1)))
            path = np.nan_to_num(s.tracks[best])
        best_result = None
        nodes = s.nodes.copy()
        lm_iterations, refined = 0, 0
        for attempt in range(len(SHORTEN) * (RETRIES + 1)):
            # each stitch shortened strongly and refined, then less, then refined as it is
            result = s.refine(path, weights, SHORTEN[attempt % len(SHORTEN)])
            poses, loss, terms, iterations, converged, valid, figures = result
            valid = valid and s.first_pose_ok(poses)
            lm_iterations += iterations
            refined += 1
            if best_result is None or valid or loss < best_result[1]:
                best_result = (poses, loss, terms, converged, valid, figures)
            if valid:
                break
            if attempt % len(SHORTEN) < len(SHORTEN) - 1:
                continue
            # the next stitch: without the nodes the failed path used around its worst place
            if s.choice is None:
                break
            worst = _worst_waypoint(s, poses)
            span = np.arange(max(0, worst - STRIKE), min(s.n, worst + STRIKE + 1))
            nodes[s.choice[span], span] = False
            candidate, _ = s.stitch(nodes)
            if candidate is None:
                break
            path = candidate
        assert best_result is not None
        poses, loss, terms, converged, valid, figures = best_result
        poses = wrap(poses, s.period, s.task_lower)
    finally:
        kernels.set_threads(previous)
    t_end = time.perf_counter()
    lengths = np.abs(np.diff(poses, axis=0)) @ s.weights
    info = {"search": "compiled", "ik_seeds": SEEDS, "anchors": ANCHORS,
            "seeds_reaching_first_waypoint": s.first_solutions,
            "stitch_tracks": int(len(s.tracks)), "stitch_rounds": rounds, "repairs": s.repairs,
            "swept": s.swept,
            "stitched": True, "candidates_refined": refined, "lm_iterations": lm_iterations,
            "seed": settings.seed, "search_max_position_error_mm": float(figures[0]),
            "search_max_rotation_error_deg": float(figures[1]),
            "search_max_joint_step_deg": float(figures[2]),
            "search_weighted_path_length": float(lengths.sum()),
            "self_collision_avoided": s.scene is not None,
            "seeds_s": t_seeds - started, "carry_s": t_carry - t_seeds,
            "refine_s": t_end - t_carry}
    return SearchResult(poses, float(loss), terms, bool(valid),
                        s.ik_iterations + s.carry_iterations + lm_iterations, bool(converged),
                        info)


def _worst_waypoint(s: _Search, poses: np.ndarray) -> int:
    """The waypoint where a refined path fails worst: its largest joint step, or else its
    largest pose error."""
    steps = np.abs(np.diff(poses, axis=0)).max(axis=1)
    if steps.max() >= MAX_JOINT_CHANGE_DEG * 0.999:
        return int(np.argmax(steps))
    point, rotation, _, _ = s.spec_frames(poses, False)

    e_point, e_rot, _, _ = errors_from_frames(point, rotation, None, None, s.goals_p, s.goals_R)
    size = np.maximum(np.linalg.norm(e_point, axis=1) / MAX_POSITION_ERROR_MM,
                      np.linalg.norm(e_rot, axis=1) / MAX_ROTATION_ERROR_DEG)
    return int(np.argmax(size))
