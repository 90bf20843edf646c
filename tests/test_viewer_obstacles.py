"""Obstacles in run folders and the viewer (issue 23): ``ikbench run`` records the tasks'
obstacles in run.json, the viewer reads them back, draws them once and marks each
trajectory's colliding waypoints; older run folders, without the key, show none."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import ikbench
from ikbench.core.errors import InputError
from ikbench.core.obstacles import box, sphere
from ikbench.core.problems import load_problem
from ikbench.core.task import Goal, Requirements, Task
from ikbench.render.arm_plots import colliding_waypoints
from ikbench.runtime.record import obstacles_entry
from ikbench.viewer.folders import load_runs

TID = "panda__1cube"


@pytest.fixture(scope="module")
def cube_run(tmp_path_factory) -> Path:
    """``ikbench run --method ours-lm --problem panda__1cube`` (no animation)."""
    out = tmp_path_factory.mktemp("view_obstacles")
    ikbench.run("ours-lm", problem="panda__1cube", output=out, progress=False,
                animation=False)
    return out / "ours-lm"


def _edited(folder: Path, where: Path, edit) -> Path:
    """A copy of ``folder`` at ``where`` whose run.json ``edit(record)`` changed."""
    shutil.copytree(folder, where)
    record = json.loads((where / "run.json").read_text())
    edit(record)
    (where / "run.json").write_text(json.dumps(record))
    return where


def test_a_problem_run_records_its_obstacles_and_reads_them_back(cube_run):
    _, task, _ = load_problem("panda__1cube")
    record = json.loads((cube_run / "run.json").read_text())
    assert record["obstacles"] == [o.to_dict() for o in task.required.obstacles]
    assert record["obstacles"][0]["center_mm"] == [0.0, 200.0, 700.0]  # the cube, 0.25 m
    _, (run,) = load_runs([cube_run])
    assert [o.name for o in run.obstacles] == ["box0"]
    (cube,) = run.obstacles
    np.testing.assert_allclose(cube.center_mm, task.required.obstacles[0].center_mm, atol=1e-9)
    np.testing.assert_allclose(cube.size_mm, [250.0, 250.0, 250.0])
    np.testing.assert_allclose(cube.rotation, np.eye(3), atol=1e-12)
    assert run.trajectories[TID].obstacles == run.obstacles


def test_an_older_run_folder_without_the_key_reads_with_none(cube_run, tmp_path):
    old = _edited(cube_run, tmp_path / "old", lambda r: r.pop("obstacles"))
    _, (run,) = load_runs([old])
    assert run.obstacles == () and run.trajectories[TID].obstacles == ()


def _task(name: str, obstacles) -> Task:
    return Task(name, Goal(np.zeros((2, 3)), np.tile([0.0, 0.0, 1.0], (2, 1))),
                Requirements(obstacles=tuple(obstacles)))


def test_run_json_records_one_list_per_run_or_per_trajectory_and_nothing_without():
    cube, ball = box("cube", [0, 0, 500], [100, 100, 100]), sphere("ball", [0, 300, 0], 50)
    assert obstacles_entry([_task("1", ()), _task("2", ())]) is None
    assert obstacles_entry([_task("1", [cube]), _task("2", [cube])]) == [cube.to_dict()]
    assert obstacles_entry([_task("1", [cube]), _task("2", [ball]), _task("3", ())]) == {
        "1": [cube.to_dict()], "2": [ball.to_dict()]}


def test_a_line_run_without_obstacles_writes_run_json_as_before(tmp_path):
    ikbench.run("ours-lm", only="1", steps=5, output=tmp_path, progress=False,
                animation=False)
    assert "obstacles" not in json.loads((tmp_path / "ours-lm" / "run.json").read_text())


def test_obstacles_per_trajectory_and_bad_entries(cube_run, tmp_path):
    ball = sphere("ball", [0, 300, 0], 50)
    own = _edited(cube_run, tmp_path / "own",
                  lambda r: r.update(obstacles={TID: [ball.to_dict()]}))
    _, (run,) = load_runs([own])
    assert run.obstacles == () and [o.name for o in run.trajectories[TID].obstacles] == [
        "ball"]
    compare = _edited(cube_run, tmp_path / "compare", lambda r: r.update(
        obstacles={"source": "ball.json", "items": [ball.to_dict()]}))
    _, (run,) = load_runs([compare])  # the form of ikbench compare's run.json
    assert [o.name for o in run.obstacles] == ["ball"]
    bad = _edited(cube_run, tmp_path / "bad",
                  lambda r: r.update(obstacles=[{"type": "box", "center_mm": [0, 0]}]))
    with pytest.raises(InputError, match="run.json obstacles"):
        load_runs([bad])
    worse = _edited(cube_run, tmp_path / "worse", lambda r: r.update(obstacles="box"))
    with pytest.raises(InputError, match="expected a list of obstacles"):
        load_runs([worse])


@pytest.fixture
def serve():
    """``ikbench.viewer.server.serve`` on any free port, stopped after the test."""
    pytest.importorskip("viser")
    from ikbench.viewer.server import serve as start

    viewers = []

    def _serve(folders, **kwargs):
        robot, runs = load_runs(folders)
        viewers.append(start(robot, runs, port=0, open_browser=False, **kwargs))
        return robot, viewers[-1]

    yield _serve
    for v in viewers:
        v.stop()


def _root_m(robot, points_mm):
    from ikbench.viewer import scene as sc

    model = sc.load_model(robot, meshes=False)
    return sc.to_root_m(sc.base_transform(model, robot), np.asarray(points_mm, dtype=float))


def test_the_viewer_draws_the_cube_once_and_hides_it_with_its_runs(cube_run, tmp_path,
                                                                      serve):
    twin = _edited(cube_run, tmp_path / "twin", lambda r: None)
    robot, v = serve([cube_run, twin])
    first, second = v.scenes
    (cube,) = first.obstacles[TID]
    assert second.obstacles[TID] == [cube] and second.obstacles[TID][0] is cube  # drawn once
    np.testing.assert_allclose(cube.position, _root_m(robot, [0.0, 200.0, 700.0]), atol=1e-9)
    np.testing.assert_allclose(cube.dimensions, [0.25, 0.25, 0.25])
    assert cube.visible and "obstacles" in v.gui and "collisions" in v.gui
    assert first.collisions == {}  # ours-lm's path avoids the cube
    v.gui["runs"][0].value = False
    assert cube.visible  # the second run shows it too
    v.gui["runs"][1].value = False
    assert not cube.visible
    v.gui["runs"][1].value = True
    v.gui["obstacles"].value = False
    assert not cube.visible


def test_colliding_waypoints_are_marked_red_at_the_fingertip(cube_run, tmp_path, serve):
    """The cube moved onto the path's middle: the waypoints there collide."""
    _, (run,) = load_runs([cube_run])
    traj = run.trajectories[TID]
    middle = traj.tip_mm[len(traj.tip_mm) // 2]
    moved = box("box0", middle, [80.0, 80.0, 80.0])
    hit = _edited(cube_run, tmp_path / "hit",
                  lambda r: r.update(obstacles=[moved.to_dict()]))
    robot, v = serve([hit])
    expect = colliding_waypoints(robot, traj.poses, (moved,))
    assert expect is not None and 0 < expect.sum() < len(expect)
    marker = v.scenes[0].collisions[TID]
    # viser sends the points as float16: within 0.5 mm
    np.testing.assert_allclose(marker.points, _root_m(robot, traj.tip_mm[expect]), atol=5e-4)
    assert marker.visible
    v.gui["collisions"].value = False
    assert not marker.visible


def test_without_obstacles_the_scene_and_panel_are_as_before(cube_run, tmp_path, serve):
    old = _edited(cube_run, tmp_path / "old", lambda r: r.pop("obstacles"))
    _, v = serve([old])
    assert v.scenes[0].obstacles == {} and v.scenes[0].collisions == {}
    assert "obstacles" not in v.gui and "collisions" not in v.gui
