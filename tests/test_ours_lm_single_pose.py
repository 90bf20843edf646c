"""ours-lm's compiled single-pose IK: its FK and Jacobian against Pinocchio, its LM against
the numpy reference (``solve_poses``) step for step, restarts in the given order, the budget,
batched equal to one at a time (float64, seeded, no timed assertions)."""

from __future__ import annotations

import numpy as np
import pytest

from ikbench.core.errors import InputError
from ikbench.core.kinematics.chain import pinocchio_frames
from ikbench.core.robot import load_robot
from ikbench.core.robot_packages import robots_folder
from ikbench.core.rotations import geodesic_angle
from ikbench.methods.ours_lm.single_pose import solve_poses

pytest.importorskip("numba")

from ikbench.methods.ours_lm import compiled_chain  # noqa: E402
from ikbench.methods.ours_lm.single_pose_compiled import (  # noqa: E402
    SinglePoseLM,
    random_initials,
)

#: Settings both solvers get when they are compared step for step.
SAME = {"restart_after": 25, "max_step": 30.0, "stop": 1e-3}


@pytest.fixture(scope="module")
def panda():
    return load_robot("panda")


@pytest.fixture(scope="module")
def fetch():
    return load_robot("fetch")


def _targets(robot, count, seed):
    """(configurations (B, dof), frames (B, 4, 4) [m], points (B, 3) [mm], rotations)."""
    q = random_initials(robot, (count,), seed)
    T = robot.fk_transform(q)
    return q, T, T[:, :3, 3] * 1000.0, np.ascontiguousarray(T[:, :3, :3])


def _errors(robot, poses, T):
    """Position [mm] and rotation [deg] errors of poses (B, dof) by Pinocchio's FK."""
    got = robot.fk_transform(poses)
    return (np.linalg.norm(got[:, :3, 3] - T[:, :3, 3], axis=1) * 1000.0,
            np.degrees(geodesic_angle(T[:, :3, :3], got[:, :3, :3])))


@pytest.mark.parametrize("name", ["nico_right_arm", "panda", "fetch"])
def test_compiled_frames_and_jacobians_equal_pinocchio(name):
    """NICO has a motor map (scale, offset), Fetch a prismatic torso [mm] and continuous
    rolls; poses reach beyond +-180 deg where a joint allows it."""
    robot = load_robot(name)
    rng = np.random.default_rng(3)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -400.0)
    upper = np.where(np.isfinite(robot.upper), robot.upper, 400.0)
    poses = rng.uniform(lower, upper, (40, robot.dof))
    mine = compiled_chain.frames(robot, poses)
    reference = pinocchio_frames(robot, poses)
    numpy_chain = robot.chain_kinematics().frames(poses)
    for a, b, c in zip(mine, reference, numpy_chain):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
        np.testing.assert_allclose(a, c, rtol=0, atol=1e-13)
    assert np.abs(mine[2]).max() > 1e-3  # the Jacobians are not all zero


@pytest.mark.parametrize("name, kind", [("nico_right_arm", "pose"), ("panda", "pose"),
                                        ("fetch", "pose"), ("nico_right_arm", "position"),
                                        ("panda", "position")])
@pytest.mark.parametrize("iterations", [1, 2, 5])
def test_the_compiled_lm_equals_solve_poses_step_for_step(name, kind, iterations):
    """Same poses after 1, 2, 5 iterations. For points the 7-joint arms have free directions
    (Panda's last joint turns about the line through its hand) that only lambda (diag + 1e-9)
    damps, where rounding noise steers the step: there the points are compared."""
    robot = load_robot(name)
    _, _, points, rotations = _targets(robot, 8, 11)
    initial = random_initials(robot, (8,), 12)
    ref = solve_poses(robot, points, rotations, initial, position_only=kind == "position",
                      max_iterations=iterations, **SAME)
    lm = SinglePoseLM(robot, kind, max_iterations=iterations, damping=1e-3, abandon=(0, 0.0),
                      **SAME)
    out = [lm.solve(points[i], rotations[i], initial[i:i + 1], np.inf) for i in range(8)]
    poses = np.array([o.pose for o in out])
    if kind == "position":
        mine_mm = robot.fk_transform(poses)[:, :3, 3] * 1000.0
        ref_mm = robot.fk_transform(ref.poses)[:, :3, 3] * 1000.0
        assert np.abs(mine_mm - ref_mm).max() < 1e-8
    else:
        assert np.abs(poses - ref.poses).max() < 1e-9
    assert np.array_equal([o.iterations for o in out], ref.iterations)
    assert np.array_equal([o.success for o in out], ref.converged)
    assert np.abs(poses - initial).max() > 1.0  # it moved


def test_restarts_match_solve_poses_random_rows(panda):
    """solve_poses' restarts draw rows from default_rng(seed); given those rows in order, the
    compiled loop restarts at the same iterations from the same poses."""
    _, _, points, rotations = _targets(panda, 3, 21)
    initial = random_initials(panda, (3,), 22)
    settings = {"restart_after": 2, "max_step": 30.0, "stop": 1e-3}
    for i in range(3):
        ref = solve_poses(panda, points[i:i + 1], rotations[i:i + 1], initial[i:i + 1],
                          max_iterations=7, restarts=2, seed=5, **settings)
        rows = np.vstack([initial[i:i + 1], random_initials(panda, (2,), 5)])
        lm = SinglePoseLM(panda, max_iterations=7, damping=1e-3, abandon=(0, 0.0), **settings)
        out = lm.solve(points[i], rotations[i], rows, np.inf)
        assert ref.restarts[0] == 2 and out.attempts == 3
        assert out.iterations == ref.iterations[0]
        assert np.abs(out.pose - ref.poses[0]).max() < 1e-9


@pytest.mark.parametrize("where", [1, 3])
def test_restarts_take_the_given_rows_in_order(panda, where):
    """Random rows with one iteration each cannot succeed; the target's own configuration at
    row ``where`` does, so exactly ``where + 1`` rows are used."""
    q, _, points, rotations = _targets(panda, 1, 31)
    rows = random_initials(panda, (6,), 32)
    rows[where] = q[0]
    out = SinglePoseLM(panda, restart_after=1).solve(points[0], rotations[0], rows, np.inf)
    assert out.success and out.attempts == where + 1
    assert np.abs(out.pose - q[0]).max() < 1e-6


@pytest.mark.parametrize("kind", ["pose", "position"])
def test_solutions_are_within_tolerance_by_pinocchio(panda, fetch, kind):
    for robot in (panda, fetch):
        _, T, points, rotations = _targets(robot, 20, 41)
        lm = SinglePoseLM(robot, kind)
        starts = random_initials(robot, (20, 64), 42)
        out = [lm.solve(points[i], rotations[i], starts[i], np.inf) for i in range(20)]
        ok = np.array([o.success for o in out])
        assert ok.mean() >= 0.95
        poses = np.array([o.pose for o in out])[ok]
        position_mm, rotation_deg = _errors(robot, poses, T[ok])
        assert position_mm.max() < 1e-3  # stop x 1 mm
        solved = [o for o, good in zip(out, ok) if good]
        np.testing.assert_allclose([o.position_error_mm for o in solved], position_mm, rtol=0,
                                   atol=1e-9)
        if kind == "pose":
            assert rotation_deg.max() < 0.5e-3
            np.testing.assert_allclose([o.rotation_error_deg for o in solved], rotation_deg,
                                       rtol=0, atol=1e-7)
        else:
            assert np.isnan(out[0].rotation_error_deg)
        assert robot.within_limits(poses, tol_deg=0.0)


def test_a_frame_target_equals_its_point_and_rotation(panda):
    _, T, points, rotations = _targets(panda, 4, 51)
    lm = SinglePoseLM(panda)
    starts = random_initials(panda, (4, 16), 52)
    for i in range(4):
        a = lm.solve(T[i], None, starts[i], np.inf)
        b = lm.solve(points[i], rotations[i], starts[i], np.inf)
        assert np.array_equal(a.pose, b.pose) and a[1:] == b[1:]


def test_a_zero_budget_returns_after_at_most_one_iteration(panda):
    _, _, points, rotations = _targets(panda, 5, 61)
    lm = SinglePoseLM(panda)
    starts = random_initials(panda, (5, 100), 62)
    for i in range(5):
        out = lm.solve(points[i], rotations[i], starts[i], 0.0)
        assert out.iterations <= 1 and out.attempts == 1 and not out.success
    batch = lm.solve_batch(points, rotations, starts, 0.0, threads=2)
    assert batch.iterations.max() <= 1 and not batch.success.any()


def test_the_deadline_stops_a_search_that_would_run_on(panda):
    """An unreachable point with 100 000 rows would take over a million iterations; a 20 ms
    budget ends it long before the rows run out."""
    lm = SinglePoseLM(panda, restart_after=12)
    rows = random_initials(panda, (100_000,), 71)
    out = lm.solve(np.array([5000.0, 0.0, 0.0]), np.eye(3), rows, 0.02)
    assert not out.success and out.attempts < len(rows)
    assert out.position_error_mm > 3000.0


def test_the_iteration_cap_holds_over_restarts(panda):
    lm = SinglePoseLM(panda, restart_after=5, max_iterations=23, abandon=(0, 0.0))
    rows = random_initials(panda, (50,), 81)
    out = lm.solve(np.array([5000.0, 0.0, 0.0]), np.eye(3), rows, np.inf)
    assert out.iterations == 23 and out.attempts == 5 and not out.success


def test_an_attempt_far_off_after_t_iterations_restarts(panda):
    far = np.array([5000.0, 0.0, 0.0])  # 5 m: |r| stays above 1 000 tolerances
    rows = random_initials(panda, (50,), 82)
    early = SinglePoseLM(panda, restart_after=1000, max_iterations=30, abandon=(3, 1000.0))
    assert early.solve(far, np.eye(3), rows, np.inf).attempts == 11
    never = SinglePoseLM(panda, restart_after=1000, max_iterations=30, abandon=(0, 0.0))
    assert never.solve(far, np.eye(3), rows, np.inf).attempts == 1


@pytest.mark.parametrize("kind", ["pose", "position"])
def test_batched_equals_one_at_a_time(panda, fetch, kind):
    for robot in (panda, fetch):
        _, T, points, rotations = _targets(robot, 12, 91)
        lm = SinglePoseLM(robot, kind, max_iterations=400)
        starts = random_initials(robot, (12, 8), 92)
        batch = lm.solve_batch(points, rotations, starts, np.inf, threads=2)
        frames = lm.solve_batch(T, None, starts, np.inf, threads=1)
        single = [lm.solve(points[i], rotations[i], starts[i], np.inf) for i in range(12)]
        assert np.array_equal(batch.poses, np.array([o.pose for o in single]))
        assert np.array_equal(batch.success, [o.success for o in single])
        assert np.array_equal(batch.attempts, [o.attempts for o in single])
        assert np.array_equal(batch.iterations, [o.iterations for o in single])
        assert np.array_equal(frames.poses, batch.poses)
        assert batch.success.mean() >= 0.9


def test_bad_input_names_the_problem(panda):
    with pytest.raises(InputError, match="kind"):
        SinglePoseLM(panda, kind="orientation")
    with pytest.raises(InputError, match="restart_after"):
        SinglePoseLM(panda, restart_after=0)
    with pytest.raises(InputError, match="abandon"):
        SinglePoseLM(panda, abandon=(2.5, 10.0))
    lm = SinglePoseLM(panda)
    starts = random_initials(panda, (2,), 0)
    with pytest.raises(InputError, match="rotation"):
        lm.solve(np.zeros(3), None, starts)
    with pytest.raises(ValueError, match="initials"):
        lm.solve(np.zeros(3), np.eye(3), np.zeros((2, 6)))
    with pytest.raises(InputError, match="initials"):
        lm.solve_batch(np.zeros((3, 3)), np.tile(np.eye(3), (3, 1, 1)), starts)


def test_a_step_across_a_limit_turns_the_joint_where_a_turn_brings_it_within(panda):
    """The LM's projection onto the limits: within them a value stays; a revolute joint
    beyond one by less than a turn short of the other comes back by whole turns (the same
    frame); else it is clipped. The numpy reference and the compiled kernel agree."""
    from ikbench.methods.ours_lm import single_pose_kernels as kernels
    from ikbench.methods.ours_lm.single_pose import into_limits

    lower, upper = panda.lower, panda.upper  # joint 0: +-166 deg; joint 5: [-1, 215] deg
    q = np.tile(np.clip(np.zeros(panda.dof), lower, upper), (6, 1))
    q[:, 0] = [100.0, 250.0, 170.0, -200.0, -300.0, 500.0]
    q[:, 5] = [10.0, -2.0, 216.0, 400.0, -150.0, 214.0]
    got = into_limits(panda, q, lower, upper)
    np.testing.assert_allclose(got[:, 0], [100.0, -110.0, upper[0], 160.0, 60.0, 140.0])
    np.testing.assert_allclose(got[:, 5], [10.0, lower[5], upper[5], 40.0, 210.0, 214.0])
    # the same frame wherever a turn was taken
    turned = ~np.isclose(got, np.clip(q, lower, upper))
    assert turned.sum() == 6
    same = np.where(turned, q, got)  # the turned joints as given, the others as moved
    np.testing.assert_allclose(panda.fk_transform(got), panda.fk_transform(same), atol=1e-12)
    spec = SinglePoseLM(panda).spec
    for i in range(len(q)):
        for j in range(panda.dof):
            assert kernels.into_limits(spec, j, q[i, j]) == pytest.approx(got[i, j], abs=1e-9)


def test_ur5_joints_with_two_turns_of_range_never_stop_on_a_limit():
    """UR5's joints range over +-360 deg: a descent that crosses one goes on a turn away,
    so from the same starts the LM solves more targets than clipping would (seeded)."""
    ur5 = load_robot("example-robot-data:ur5")
    q, T, _, _ = _targets(ur5, 60, 7)
    starts = random_initials(ur5, (60, 1), 8)
    lm = SinglePoseLM(ur5, max_iterations=100)
    out = [lm.solve(T[i], None, starts[i], float("inf")) for i in range(60)]
    poses = np.array([o.pose for o in out])
    assert np.all((poses >= ur5.lower) & (poses <= ur5.upper))
    on_limit = np.isclose(poses, ur5.lower) | np.isclose(poses, ur5.upper)
    assert not on_limit[[o.success for o in out]].any()
    assert np.mean([o.success for o in out]) > 0.8


@pytest.mark.parametrize("kind", ["pose", "position"])
@pytest.mark.parametrize("rows", [1, 4])
def test_ik_adapter_one_call_equals_the_solver_on_views_and_copies(panda, kind, rows):
    """``ikbench ik``'s adapter hands the frame's column views [m] to one kernel call
    (``solve_views``): the same answer as :meth:`SinglePoseLM.solve` on C-ordered copies [mm],
    whatever the layout, and bad shapes still name the problem."""
    from ikbench.methods.ours_lm import single_pose_kernels as kernels
    from ikbench.methods.ours_lm.pose_solver import ROWS_CRAWL, ROWS_DAMPING, OursLMSolver
    from ikbench.schemes.single_pose import MAX_STEPS

    solver = OursLMSolver(panda, kind, (1.0, 0.5))
    solver.prepare()
    compiled = len(kernels.solve_views.signatures)
    q, T, points, rotations = _targets(panda, 6, 11)
    initials = random_initials(panda, (6, rows), 12)
    for b in range(6):
        settings = {} if rows == 1 else {"damping": ROWS_DAMPING, "crawl": ROWS_CRAWL}
        reference = SinglePoseLM(panda, kind, (1.0, 0.5), max_iterations=MAX_STEPS * rows,
                                 restart_after=MAX_STEPS, abandon=(0, 0.0), **settings)
        want = reference.solve(points[b], rotations[b], initials[b], float("inf"))
        rotation = None if kind == "position" else T[b][:3, :3]
        copies = (None, None) if rotation is None else (rotation.copy(), rotation.T.copy().T)
        for point_m, rot in ((T[b][:3, 3], rotation), (T[b][:3, 3].copy(), copies[0]),
                             (list(T[b][:3, 3]), copies[1])):  # views, C, a list and F
            got = solver.solve_within(initials[b], point_m, rot, float("inf"))
            np.testing.assert_array_equal(got.q, want.pose)
            assert (got.iterations, got.ok, got.attempts) == (
                want.iterations, want.success, want.attempts)
    # a list or a Fortran-ordered rotation is copied, never compiled for inside the call
    assert len(kernels.solve_views.signatures) == compiled
    with pytest.raises(ValueError, match="goal point"):
        solver.solve_within(initials[0], T[0][:2, 3], T[0][:3, :3], float("inf"))


def test_a_joint_pinned_on_its_limit_leaves_the_normal_equations(panda):
    """A joint on its limit that the step pushes out (clipped back) is marked; the step again
    is 0 for it and, for the others, the damped system without its row and column."""
    from ikbench.methods.ours_lm import single_pose_kernels as kernels

    spec = SinglePoseLM(panda, "pose").spec
    k = panda.dof
    rng = np.random.default_rng(5)
    J = rng.normal(size=(6, k))
    jtj, g, lam = J.T @ J, J.T @ rng.normal(size=6), 0.1
    step, chol, frozen = np.empty(k), np.empty((k, k)), np.zeros(k)
    assert kernels.damped_step(jtj, g, lam, chol, step, k, 1e9)
    q = (panda.lower + panda.upper) / 2.0
    j = int(np.argmax(np.abs(step)))
    q[j] = panda.lower[j] if step[j] < 0 else panda.upper[j]  # the step pushes it out
    q[j - 1] = panda.lower[j - 1] if step[j - 1] > 0 else panda.upper[j - 1]  # pulls it in
    assert kernels.pinned(spec, k, q, step, frozen)
    assert frozen[j] == 1.0 and np.count_nonzero(frozen) == 1
    jtj_free, g_free = np.empty((k, k)), np.empty(k)
    kernels.without(jtj, g, frozen, k, jtj_free, g_free)
    assert kernels.damped_step(jtj_free, g_free, lam, chol, step, k, 1e9)
    free = np.arange(k) != j
    H = jtj + lam * np.diag(np.diag(jtj) + 1e-9)
    np.testing.assert_allclose(step[free], -np.linalg.solve(H[np.ix_(free, free)], g[free]),
                               rtol=1e-9, atol=1e-12)
    assert step[j] == 0.0


@pytest.mark.skipif(robots_folder("example-robot-data") is None,
                    reason="example-robot-data is not installed")
def test_a_crawling_attempt_is_kicked_out_of_the_stretched_elbow_saddle():
    """UR10 target 62 of ``ikbench ik``'s seed 1: from each of its 8 rows, 100 iterations
    end with the elbow straight (0 deg, J^T J blind to bending) 5 or 43 mm off; with the
    crawl check the same rows solve it, and the kicks are seeded (the same answer twice)."""
    from ikbench.schemes.single_pose import MAX_STEPS
    from ikbench.studies.ik import IKSettings, sample_targets

    ur10 = load_robot("example-robot-data:ur10")
    targets = sample_targets(ur10, IKSettings(count=63, seed=1))
    T, rows = targets.T_target[62], targets.initials(62, 8)
    fixed = {"max_iterations": MAX_STEPS, "restart_after": MAX_STEPS, "abandon": (0, 0.0)}
    plain = SinglePoseLM(ur10, "pose", (1.0, 0.5), **fixed)
    for row in rows:
        out = plain.solve(T, None, row[None], float("inf"))
        elbow = ur10.joint_names.index("elbow_joint")
        assert not out.success and abs(out.pose[elbow]) < 0.01  # [deg]
        assert out.position_error_mm > 4.0
    kicked = SinglePoseLM(ur10, "pose", (1.0, 0.5), **{**fixed, "max_iterations": 8 * MAX_STEPS},
                          crawl=(10, 0.5, 2.0))
    first, again = (kicked.solve(T, None, rows, float("inf")) for _ in range(2))
    assert first.success and first.position_error_mm < 1e-3
    np.testing.assert_array_equal(first.pose, again.pose)
    assert first.iterations == again.iterations


def test_the_crawl_setting_is_checked(panda):
    with pytest.raises(InputError, match="crawl"):
        SinglePoseLM(panda, crawl=(10, 0.5))
    with pytest.raises(InputError, match="crawl"):
        SinglePoseLM(panda, crawl=(2.5, 0.5, 1.0))


@pytest.mark.skipif(robots_folder("example-robot-data") is None,
                    reason="example-robot-data is not installed")
def test_the_batch_runs_the_per_call_solver_under_a_fixed_count_rule():
    """Under ``--attempts 8`` with no clock (the deterministic table) the batched throughput
    runs the per-call solver with its settings (the crawl kick included): per target the same
    success, answer and attempts as :meth:`OursLMSolver.solve_within`, on UR10 targets of
    seed 1 that include the stretched-elbow saddle (target 62) the budgeted solver misses."""
    from ikbench.methods.ours_lm.pose_solver import OursLMSolver
    from ikbench.studies.ik import IKSettings, sample_targets

    ur10 = load_robot("example-robot-data:ur10")
    targets = sample_targets(ur10, IKSettings(count=63, seed=1))
    picked = list(range(52, 63))
    T = targets.T_target[picked]
    initials = np.stack([targets.initials(t, 8) for t in picked])
    solver = OursLMSolver(ur10, "pose", (1.0, 0.5))
    solver.prepare()
    one = [solver.solve_within(initials[b], T[b][:3, 3], T[b][:3, :3], float("inf"))
           for b in range(len(picked))]
    for threads in (1, 2):
        batch = solver.solve_batch(initials, np.ascontiguousarray(T[:, :3, 3]),
                                   np.ascontiguousarray(T[:, :3, :3]), float("inf"), threads)
        np.testing.assert_array_equal(batch.q, np.stack([o.q for o in one]))
        assert list(batch.attempts) == [o.attempts for o in one]
    assert one[-1].ok  # target 62: solved by the kick, in both
