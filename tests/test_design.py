"""ikbench design without a browser: the designer re-solves on every move (warm-started), judges
by the task contract, says when a point is out of reach, and saves a targets file and a run
folder that ``ikbench run`` reproduces; lines on NICO, the Panda and a bare URDF, a letter,
a 6-D pose path."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import ikbench
from ikbench.cli import main
from ikbench.core.contract import judge
from ikbench.core.errors import InputError
from ikbench.core.metrics import contract_metrics, trajectory_metrics
from ikbench.core.problems import load_problem
from ikbench.methods.base import Method, Solution
from ikbench.methods.registry import get_method
from ikbench.viewer.design.designer import Designer, DesignSpec
from ikbench.viewer.design.reach import reach

DATA = Path(__file__).parent / "data"
#: Metric columns of a line run's table.csv compared between two runs (not the timings).
METRICS = ["loss", "line_distance_mean_mm", "pointing_deviation_mean_deg", "end_point_error_mm",
           "start_point_error_mm"]


@pytest.fixture(scope="module")
def nico():
    return ikbench.load_robot()


@pytest.mark.parametrize("method", ["ours-lm", "ours-exact"])
def test_twenty_moves_of_the_touch_point_each_re_solve(nico, method):
    designer = Designer(nico, method)
    touch = designer.handles()["touch"]
    seen = [designer.update.poses]
    for k in range(20):
        goal = touch + np.array([0.0, 2.0 * k, 1.5 * k])
        update = designer.move_touch(goal)
        assert update.method == method and update.reach is not None and update.reach.reachable
        # the touch pose was found for the point, and the trajectory ends there
        np.testing.assert_allclose(nico.fk(update.poses[-1]).point_mm[0], goal, atol=0.5)
        np.testing.assert_allclose(update.task.goal.end_point_mm, update.reach.point_mm, atol=1e-9)
        assert update.solution.iterations >= 1 and update.elapsed_s > 0
        seen.append(update.poses)
    changes = [np.abs(b - a).max() for a, b in zip(seen[1:-1], seen[2:])]
    assert min(changes) > 0.01  # every move changed the trajectory
    if method == "ours-exact":  # hard constraints: on the line, at both poses
        assert designer.update.ok, [c.text() for c in designer.update.criteria]


def test_settle_solves_from_scratch_what_a_long_drag_solved_warm(nico):
    designer = Designer(nico, "ours-exact")
    centre = designer.handles()["touch"]
    for angle in np.linspace(0.0, 2 * np.pi, 12, endpoint=False):  # a 20 mm circle
        update = designer.move_touch(centre + 20 * np.array([0, np.cos(angle) - 1,
                                                              np.sin(angle)]))
        assert update.warm
    cold = designer.method.solve(nico, update.task).poses
    settled = designer.settle()
    assert not settled.warm and settled.task is not update.task
    np.testing.assert_array_equal(settled.poses, cold)
    np.testing.assert_array_equal(settled.task.goal.points_mm, update.task.goal.points_mm)
    assert settled.reach is update.reach


def test_the_warm_start_solves_the_same_task_as_a_cold_solve(nico):
    task = ikbench.build_tasks(nico, ikbench.load_targets(None, nico).select("3"))[0]
    for name in ("ours-lm", "ours-exact"):
        method = get_method(name)()
        cold = method.solve(nico, task).poses
        shifted = cold + np.linspace(0.0, 1.0, len(cold))[:, None] * 2.0  # a nearby start
        warm = method.solve_from(nico, task, shifted)
        np.testing.assert_allclose(warm.poses, cold, atol=0.05)
        assert method.capabilities.warm_starts and warm.iterations >= 1


class Cold(Method):
    """A method without a warm start: solve_from falls back on solve."""

    name, description = "cold", "the joint interpolation"

    def solve(self, robot, task, progress=None) -> Solution:
        t = np.linspace(0.0, 1.0, task.goal.steps + 1)[:, None]
        start, end = task.required.start_pose, task.required.end_pose
        return Solution(start + t * (end - start),
                        0, 0.0, None)


def test_a_method_without_a_warm_start_solves_from_scratch(nico):
    task = ikbench.build_tasks(nico, ikbench.load_targets(None, nico).select("1"))[0]
    given = np.zeros((task.goal.steps + 1, nico.dof))
    solution = Cold().solve_from(nico, task, given)
    assert not Cold.capabilities.warm_starts
    np.testing.assert_allclose(solution.poses[[0, -1]],
                               [task.required.start_pose, task.required.end_pose])


def test_the_criteria_are_the_contracts_judgement(nico):
    designer = Designer(nico, "ours-lm")  # ours-lm leaves the line by > 5 mm on trajectory 1
    update = designer.update
    figures = contract_metrics(nico, update.task, update.poses, update.task.required.contract)
    verdict = judge(update.task.required.contract, figures)
    shown = {c.name: c.ok for c in update.criteria}
    assert {k: shown[k] for k in verdict} == verdict
    assert not verdict["line"] and update.failed == ["line"]
    line = next(c for c in update.criteria if c.name == "line")
    assert line.value == pytest.approx(figures["line_distance_max_mm"])
    assert line.text().startswith("FAIL line distance: ") and "(limit 5 mm)" in line.text()
    assert shown["collisions"]  # NICO has a collision model: self-collisions are judged
    speed = next(c for c in update.criteria if c.name == "speed")
    assert speed.value == pytest.approx(figures["speed_limit_use"])  # constant timing


def test_the_speed_criterion_follows_the_timing_and_duration(nico):
    designer = Designer(nico, "ours-exact")
    slow = next(c for c in designer.update.criteria if c.name == "speed")
    fast = next(c for c in designer.set_timing("constant", 0.5).criteria if c.name == "speed")
    assert fast.value == pytest.approx(4 * slow.value) and not fast.ok and slow.ok
    assert "speed" in designer.update.failed
    jerk = designer.set_timing("min-jerk", 2.0)
    assert jerk.timed.timing == "min-jerk" and not np.allclose(np.diff(jerk.timed.times_s),
                                                               2.0 / 50)
    assert next(c for c in jerk.criteria if c.name == "speed").value > slow.value
    with pytest.raises(InputError, match="timing: 'fast'; allowed: constant, min-jerk, topp"):
        designer.set_timing("fast")


def test_a_point_out_of_reach_says_so_and_the_design_goes_on(nico):
    designer = Designer(nico, "ours-exact")
    touch = designer.handles()["touch"]
    far = designer.move_touch(touch + np.array([-600.0, 0.0, 0.0]))  # 60 cm further out
    assert far.reach is not None and not far.reach.reachable
    assert far.message.startswith("out of reach: the arm gets within ")
    assert far.failed[0] == "reach" and far.reach.distance_mm > 100
    # the arm went as far as it gets: the reached point, not the asked one, is the touch
    np.testing.assert_allclose(far.task.goal.end_point_mm, far.reach.point_mm, atol=1e-9)
    back = designer.move_touch(touch)
    assert back.reach is not None and back.reach.reachable and "reach" not in back.failed


def test_an_infeasible_exact_solve_shows_the_fallback(nico, monkeypatch):
    designer = Designer(nico, "ours-exact")
    exact = type(designer.method)

    def infeasible(self, robot, task, initial):
        return Solution(initial, 1, 0.0, 1.0, False,
                        {"feasible": False, "infeasible": "point 3: 9 mm from its goal"})
    monkeypatch.setattr(exact, "solve_from", infeasible)
    update = designer.move_touch(designer.handles()["touch"] + np.array([0.0, 10.0, 0.0]))
    assert update.method == "ours-lm"
    assert update.message == ("ours-exact: point 3: 9 mm from its goal; ours-lm's solution is "
                              "shown")
    none = Designer(nico, "ours-exact", DesignSpec(fallback=None))
    assert none.fallback is None


def test_the_start_pose_from_a_recorded_pose_or_a_dragged_start_point(nico):
    designer = Designer(nico, "ours-lm")
    targets = ikbench.load_targets(None, nico)
    update = designer.use_start_pose("7")  # touch pose 7 as the start
    np.testing.assert_allclose(update.task.required.start_pose, targets.touch_poses["7"])
    start = designer.handles()["start"] + np.array([0.0, 0.0, -20.0])
    moved = designer.move("start", start)
    np.testing.assert_allclose(moved.task.goal.start_point_mm, start, atol=0.5)
    with pytest.raises(InputError, match="recorded poses are start, 1, 2, 3, 4, 5, 6, 7"):
        designer.use_start_pose("8")
    with pytest.raises(InputError, match="a line has the points touch and start"):
        designer.move("centre", start)


def test_saving_writes_what_ikbench_run_writes_on_the_saved_targets(nico, tmp_path):
    designer = Designer(nico, "ours-exact", DesignSpec(trajectory="2", duration_s=2.5))
    for _ in range(3):
        designer.move_touch(designer.handles()["touch"] + np.array([0.0, 8.0, 4.0]))
    shown = designer.update.poses.copy()
    saved = designer.save(tmp_path / "out", "mine")
    assert saved.files == (tmp_path / "out" / "mine.targets.json",)
    assert saved.folder == tmp_path / "out" / "mine"
    doc = json.loads(saved.files[0].read_text())
    assert list(doc["targets"]) == ["2"] and doc["steps"] == 50
    assert doc["start_pose"] == designer.update.task.required.start_pose.tolist()
    assert saved.command.startswith("ikbench run --method ours-exact --robot nico_right_arm "
                                    f"--targets {saved.files[0]} --steps 50 --duration 2.5")
    assert saved.change_deg < 0.05  # solved from scratch, it is the trajectory shown
    np.testing.assert_allclose(designer.update.poses, shown, atol=0.05)
    designer.settle()  # at rest the designer shows what ikbench run solves: no change
    assert designer.save(tmp_path / "out", "mine").change_deg < 1e-6
    record = json.loads((saved.folder / "run.json").read_text())
    assert record["targets"] == str(saved.files[0]) and record["duration_s"] == 2.5
    # ikbench run on the saved targets file: the same trajectory and the same metrics
    assert main(["run", "--method", "ours-exact", "--targets", str(saved.files[0]),
                             "--duration", "2.5", "--output", str(tmp_path / "again"),
                             "--no-animation", "--quiet"]) == 0
    mine = pd.read_csv(saved.folder / "table.csv")
    again = pd.read_csv(tmp_path / "again" / "ours-exact" / "table.csv")
    pd.testing.assert_frame_equal(mine[["trajectory", *METRICS]], again[["trajectory",
                                                                         *METRICS]])
    first = pd.read_csv(saved.folder / "trajectory_2.csv")
    pd.testing.assert_frame_equal(first, pd.read_csv(tmp_path / "again" / "ours-exact" /
                                                     "trajectory_2.csv"))
    # and the metrics recomputed from the saved CSV against the saved targets' task
    task = ikbench.build_tasks(nico, ikbench.load_targets(saved.files[0], nico))[0]
    poses = first[list(nico.joint_names)].to_numpy()
    figures = trajectory_metrics(nico, task, poses)
    assert figures["line_distance_mean_mm"] == pytest.approx(mine["line_distance_mean_mm"][0],
                                                             rel=1e-8, abs=1e-9)


def test_a_bad_save_name_is_refused_before_anything_is_written(nico, tmp_path):
    designer = Designer(nico, "ours-lm")
    with pytest.raises(InputError, match="--name: 'a b' is not allowed"):
        designer.save(tmp_path, "a b")
    assert not list(tmp_path.iterdir())


def test_a_letter_moves_with_its_centre_and_scales(nico, tmp_path):
    designer = Designer(nico, "ours-lm", DesignSpec(shape="letter:L", steps=40))
    before = designer.update.task.goal.points_mm
    centre = designer.handles()["centre"]
    moved = designer.move("centre", centre + np.array([0.0, 30.0, -20.0]))
    assert moved.reach is not None and moved.reach.reachable
    shift = moved.reach.point_mm - centre
    np.testing.assert_allclose(moved.task.goal.points_mm, before + shift, atol=1e-6)
    small = designer.set_size(150.0)
    height = np.ptp(small.task.goal.points_mm[:, 2])
    assert height == pytest.approx(np.ptp(before[:, 2]) / 2, rel=1e-6)
    assert {c.name for c in small.criteria} >= {"curve", "pointing", "limits", "speed"}
    with pytest.raises(InputError, match="--size 5.0: a letter is 20 to 1000 mm high"):
        designer.set_size(5.0)
    saved = designer.save(tmp_path, "ell")
    assert "--shape letter:L --size 150" in saved.command
    record = json.loads((saved.folder / "run.json").read_text())
    assert record["shape"] == "letter:L" and record["size_mm"] == 150.0
    assert record["start_pose_deg"] == designer.design.reference_pose.tolist()
    with pytest.raises(InputError, match="one letter at a time"):
        Designer(nico, "ours-lm", DesignSpec(shape="letter:A,B"))


def test_the_panda_and_a_bare_urdf(tmp_path):
    panda = Designer("panda", "ours-exact")
    update = panda.move_touch(panda.handles()["touch"] + np.array([0.0, 30.0, 0.0]))
    assert update.ok, [c.text() for c in update.criteria]
    arm = ikbench.load_robot(DATA / "unaligned_arm.urdf", "tool")
    given = Designer(arm, "ours-lm", DesignSpec(targets=DATA / "unaligned_arm.targets.json",
                                                trajectory="b"))
    assert given.design.trajectory == "b" and given.update.task.goal.steps == 20
    bare = Designer(arm, "ours-lm")  # no targets: from the middle of the joint ranges
    assert bare.update.task.name == "design"
    touch = bare.handles()["touch"]  # up to 150 mm along the pointing axis, as far as it gets
    assert 10.0 < np.linalg.norm(touch - bare.handles()["start"]) <= 150.0 + 1e-6
    inward = touch + 0.3 * (bare.handles()["start"] - touch) + np.array([0.0, 0.0, 3.0])
    assert bare.move_touch(inward).reach.reachable
    saved = bare.save(tmp_path, "arm")
    assert "--end-frame tool" in saved.command
    again = ikbench.load_targets(saved.files[0], arm)
    np.testing.assert_array_equal(again.touch_poses["design"],
                                  bare.design.touch_pose)


def test_a_pose_path_waypoint_drags_its_neighbours(tmp_path):
    designer = Designer(None, "ours-lm", DesignSpec(problem="fetch_arm__hello"))
    assert designer.robot.name == "fetch_arm" and designer.kind == "path"
    n = designer.update.task.goal.steps
    designer.select_waypoint(n // 4)
    before = designer.update.task.goal.points_mm
    point = designer.handles()["waypoint"] + np.array([0.0, 0.0, 10.0])
    update = designer.move("waypoint", point)
    moved = np.linalg.norm(update.task.goal.points_mm - before, axis=1)
    assert moved[n // 4] == pytest.approx(10.0) and moved[n // 4 + 1] < 10.0
    assert moved[-1] == 0.0 and moved[0] == 0.0 or n // 4 < 0.15 * n + 1
    assert {c.name for c in update.criteria} >= {"position", "rotation", "joint_change"}
    with pytest.raises(InputError, match=f"waypoint {n + 1}: the path has waypoints 0 to {n}"):
        designer.select_waypoint(n + 1)
    saved = designer.save(tmp_path, "hello2")
    assert [f.name for f in saved.files] == ["hello2.yaml", "hello2.csv"]
    _, task, _ = load_problem(saved.files[0])
    np.testing.assert_allclose(task.goal.points_mm, update.task.goal.points_mm, atol=1e-9)
    assert (saved.folder / "trajectory_hello2.csv").is_file()
    with pytest.raises(InputError, match="is for robot 'fetch_arm'"):
        Designer("panda", "ours-lm", DesignSpec(problem="fetch_arm__hello"))


def test_reach_points_along_the_asked_direction(nico):
    targets = ikbench.load_targets(None, nico)
    start = targets.touch_poses["4"]
    goal = nico.fk(start).point_mm[0] + np.array([5.0, -5.0, 5.0])
    direction = np.array([-1.0, 0.0, -0.3])
    found = reach(nico, goal, start, direction)
    assert found.reachable
    pointing = nico.fk(found.pose).direction[0]
    angle = np.degrees(np.arccos(pointing @ direction / np.linalg.norm(direction)))
    before = np.degrees(np.arccos(nico.fk(start).direction[0] @ direction
                                  / np.linalg.norm(direction)))
    assert angle < before
