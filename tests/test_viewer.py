"""ikbench view without a browser: run folders read back, the scene against ikbench's FK,
trajectory selection, real-speed playback, ghosts, errors, and a clean Ctrl-C."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import ikbench
from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.viewer.folders import load_runs
from tests.conftest import REPO, exit_code

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def folders(tmp_path_factory):
    """NICO: two runs of trajectories 1 and 3 (n = 10); the unaligned arm: one run."""
    out = tmp_path_factory.mktemp("view")
    common = {"only": "1,3", "steps": 10, "output": out, "progress": False, "animation": False}
    ikbench.run("ours-lm", **common)
    ikbench.run("ours-lm", name="lm-c0", options={"weights": {"L0": 100.0}}, **common)
    arm = ikbench.load_robot(DATA / "unaligned_arm.urdf", "tool")
    ikbench.run("ours-lm", robot=arm, targets=DATA / "unaligned_arm.targets.json",
                output=out / "arm", progress=False, animation=False)
    return {"nico": [out / "ours-lm", out / "lm-c0"], "arm": [out / "arm" / "ours-lm"]}


def test_runs_are_read_back_with_their_goal_paths(folders):
    robot, runs = load_runs(folders["nico"])
    assert robot.name == "nico_right_arm" and [r.label for r in runs] == ["ours-lm",
                                                                           "lm-c0 (ours-lm)"]
    traj = runs[0].trajectories["3"]
    assert traj.steps == 10 and traj.duration_s == 2.0 and traj.index_at(1.0) == 5
    task = ikbench.line_tasks(robot, ikbench.load_targets(None, robot).select("3")
                              .with_steps(10))[0]
    np.testing.assert_allclose(traj.goal_mm, task.goal.points_mm, atol=1e-9)
    assert runs[0].goal_source.startswith("goal: rebuilt from run.json (shape line")


def test_a_folder_of_run_folders_stands_for_them(folders, tmp_path):
    """`ikbench view OUTPUT/compare` (a folder with a run.json of its own and one run folder
    per method) shows every method's run; it failed with "robot: 'None'"."""
    root = tmp_path / "compare"
    for folder in folders["nico"]:
        shutil.copytree(folder, root / folder.name)
    (root / "run.json").write_text(json.dumps({"study": "compare"}))
    robot, runs = load_runs([root])
    assert robot.name == "nico_right_arm"
    assert sorted(r.folder.name for r in runs) == ["lm-c0", "ours-lm"]


def test_a_run_whose_targets_cannot_be_found_gets_the_straight_line(folders, tmp_path):
    copy = tmp_path / "moved"
    shutil.copytree(folders["arm"][0], copy)
    record = json.loads((copy / "run.json").read_text())
    record["targets"] = str(tmp_path / "gone.json")
    (copy / "run.json").write_text(json.dumps(record))
    _, (run,) = load_runs([copy])
    assert run.goal_source.startswith("goal: the straight line between each trajectory's "
                                      "first and last fingertip points")
    traj = run.trajectories["a"]
    np.testing.assert_allclose(traj.goal_mm[[0, -1]], traj.tip_mm[[0, -1]], atol=1e-12)


def test_runs_of_different_robots_are_refused(folders):
    with pytest.raises(InputError, match="the runs shown together must share the robot"):
        load_runs([*folders["nico"], *folders["arm"]])


@pytest.fixture
def viewer(folders):
    pytest.importorskip("viser")
    from ikbench.viewer.server import serve

    robot, runs = load_runs(folders["nico"])
    v = serve(robot, runs, port=0, open_browser=False)
    yield robot, v
    v.stop()


def test_the_drawn_arm_and_markers_follow_ikbenchs_fk(viewer):
    robot, v = viewer
    assert v.url.startswith("http://127.0.0.1:") and len(v.times) == 11
    assert v.trajectory == "1"
    for tid in ("3", "1"):
        v.select(tid)
        for step in (0, 4, 10):
            v.set_step(step)
            assert f"step {step} / 10" in v.gui["time"].content
            for s in v.scenes:
                poses = s.run.trajectories[tid].poses
                fk_m = robot.fk(poses[step]).point_mm[0] / 1000  # base = URDF root for NICO
                np.testing.assert_allclose(s.tip_marker.position, fk_m, atol=1e-6)
                model = s.model  # the yourdfpy model ViserUrdf drew this step with
                end = model.get_transform(robot.end_frame)[:3, 3]
                np.testing.assert_allclose(end, fk_m, atol=1e-9)  # yourdfpy vs Pinocchio
                goal = s.run.trajectories[tid].goal_mm[step] / 1000
                np.testing.assert_allclose(s.goal_marker.position, goal, atol=1e-6)
            assert [k for k, p in v.scenes[0].tip_paths.items() if p.visible] == [tid]
            assert [k for k, p in v.scenes[0].faint_paths.items() if p.visible] != [tid]


def _until(condition, what: str) -> None:
    """Wait (really, at most 30 s) until the player thread made ``condition`` true."""
    deadline = time.monotonic() + 30
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.005)


def test_playback_at_real_speed_and_stop_at_the_end(viewer, monkeypatch):
    # the player's clock is one the test moves (the wall clock of a loaded machine let 0.5 s
    # of sleep become 1.2 s: step 6 where 1..4 was asserted)
    from types import SimpleNamespace

    from ikbench.viewer import gui, server

    clock = [1000.0]
    fake_time = SimpleNamespace(perf_counter=lambda: clock[0])
    monkeypatch.setattr(server, "time", fake_time)
    monkeypatch.setattr(gui, "time", fake_time)
    _, v = viewer
    v.set_step(0)
    v.play()
    clock[0] += 0.5  # 0.2 s per step: 2.5 steps
    _until(lambda: v.gui["step"].value == 2, "the player did not reach step 2")
    assert v.playing
    v.gui["speed"].value = "2x"
    v.set_step(7)
    v.play()
    clock[0] += 1.0  # 2x: 10 steps' worth, so it reaches the end and stops there
    # (the player pauses, then moves the slider: wait for both)
    _until(lambda: not v.playing and v.gui["step"].value == 10,
           "the player did not stop at the end")
    assert v.gui["play"].label == "Play"


def test_ghosts_and_show_hide(viewer):
    _, v = viewer
    assert [s.opacity for s in v.scenes] == [1.0, 0.35]  # the second run is a ghost
    v.gui["ghosts"].value = True  # its whole arm shown
    assert v.scenes[1].arm.visible
    v.gui["runs"][1].value = False
    assert not v.scenes[1].frame.visible and v.scenes[0].frame.visible
    v.gui["goal"].value = False
    assert not any(p.visible for s in v.scenes for p in s.goal_paths.values())


def test_other_runs_are_their_fingertip_paths_unless_whole_ghosts_are_asked(folders):
    """Issue 64: five whole-body ghosts of a six-method compare washed out a humanoid. By
    default the other runs show their fingertip paths and markers, not their arms; the
    panel's box, or serve(ghosts=True) (``ikbench view --ghosts``), shows the arms."""
    pytest.importorskip("viser")
    from ikbench.viewer.server import serve

    robot, runs = load_runs(folders["nico"])
    v = serve(robot, runs, port=0, open_browser=False)
    try:
        first, other = v.scenes
        assert first.arm.visible and not other.arm.visible
        assert other.tip_marker.visible and other.tip_paths[v.trajectory].visible
        assert not v.gui["ghosts"].value
        v.gui["ghosts"].value = True
        assert other.arm.visible
        v.gui["ghosts"].value = False
        assert not other.arm.visible and first.arm.visible
    finally:
        v.stop()
    v = serve(robot, runs, port=0, open_browser=False, ghosts=True)
    try:
        assert v.gui["ghosts"].value and v.scenes[1].arm.visible
    finally:
        v.stop()


def test_view_takes_ghosts():
    from ikbench.cli import build_parser

    args = build_parser().parse_args(["view", "results/ours", "--ghosts"])
    assert args.ghosts is True


def test_a_chain_below_the_urdf_root_with_a_prismatic_joint_is_drawn_where_fk_says(tmp_path):
    """The unaligned arm's chain from 'base' (a rotated fixed joint below the URDF's root):
    the viewer places base-frame paths in the URDF's root frame, where yourdfpy draws."""
    pytest.importorskip("viser")
    from ikbench.viewer.server import serve

    config = tmp_path / "arm.toml"
    config.write_text(f'urdf = "{DATA / "unaligned_arm.urdf"}"\nbase_link = "base"\n'
                      'end_frame = "tool"\n')
    arm = ikbench.load_robot(config)
    ikbench.run("ours-lm", robot=arm, targets=DATA / "unaligned_arm.targets.json",
                output=tmp_path, progress=False, animation=False)
    robot, runs = load_runs([tmp_path / "ours-lm"])
    v = serve(robot, runs, port=0, open_browser=False, trajectory="b")
    try:
        s = v.scenes[0]
        T_root_base = s.model.get_transform("base", "world_link")
        assert not np.allclose(T_root_base, np.eye(4))
        for step in (0, 13, 20):
            v.set_step(step)
            fk_m = robot.fk(s.run.trajectories["b"].poses[step]).point_mm[0] / 1000
            expected = T_root_base[:3, :3] @ fk_m + T_root_base[:3, 3]
            np.testing.assert_allclose(s.tip_marker.position, expected, atol=1e-6)
            end = s.model.get_transform(robot.end_frame)[:3, 3]
            np.testing.assert_allclose(end, expected, atol=1e-9)
    finally:
        v.stop()


@pytest.mark.parametrize("args, message", [
    (["nowhere"], "argument RUN_DIR: 'nowhere' not found; give a run folder"),
    (["{arm}", "{nico}"], "the runs shown together must share the robot"),
    (["{nico}", "--port", "70000"], "--port: 70000 is out of range; give a TCP port from 0 to "
     "65535"),
])
def test_bad_input_one_line_exit_2(folders, capsys, args, message):
    args = [a.format(arm=folders["arm"][0], nico=folders["nico"][0]) for a in args]
    assert exit_code(["view", *args, "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1


def test_an_unknown_trajectory_is_one_line_naming_the_ids(folders, capsys):
    pytest.importorskip("viser")
    assert main(["view", *map(str, folders["nico"]), "--trajectory", "9", "--no-browser"]) == 2
    assert capsys.readouterr().err == ("ikbench: error: --trajectory: '9' is not a trajectory "
                                       "of these runs; available: 1, 3\n")


def test_without_viser_one_line_names_the_extra(folders, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "viser", None)  # import viser now fails
    assert main(["view", str(folders["nico"][0]), "--no-browser"]) == 2
    assert capsys.readouterr().err == ("ikbench: error: ikbench view needs viser, which is not "
                                       "installed: pip install 'ikbench[viewer]'\n")


def test_command_line_prints_the_url_and_stops_cleanly_on_ctrl_c(folders):
    """Also when started the way a non-interactive shell starts a background job: with
    SIGINT ignored (the viewer installs its own handler)."""
    pytest.importorskip("viser")
    proc = subprocess.Popen(
        [sys.executable, "-m", "ikbench.cli", "view", *map(str, folders["nico"]), "--port",
         "0", "--no-browser"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        cwd=REPO, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        line, deadline = "", time.monotonic() + 60
        while "ikbench viewer: http://127.0.0.1:" not in line:
            line = proc.stdout.readline()
            assert line or proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "Traceback" not in err + out and "stopping the viewer" in out
