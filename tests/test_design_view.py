"""The designer's browser view without a browser: drags redraw the paths and the arm (checked
against ikbench's FK), the gizmo's own events go through the worker, an unreachable point is
marked and the gizmo snaps back on release, Save from the panel, the CLI's errors and a clean
Ctrl-C."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.viewer.design.designer import Designer, DesignSpec
from tests.conftest import REPO

viser = pytest.importorskip("viser", reason="viser is not installed (pip install "
                            "'ikbench[viewer]')")


@pytest.fixture
def view():
    from ikbench.viewer.design.view import serve_design

    v = serve_design(Designer("nico_right_arm", "ours-lm"), port=0, open_browser=False,
                     animate=False)
    yield v
    v.stop()


def _wait(condition, timeout_s: float = 30.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, "the view did not apply the change"
        time.sleep(0.02)


def test_twenty_drags_redraw_the_paths_and_the_arm(view):
    robot, designer = view.designer.robot, view.designer
    touch = designer.handles()["touch"]
    view.scene_s.clear()
    for k in range(20):
        update = view.drag("touch", touch + np.array([0.0, 2.0 * k, 1.0 * k]))
        tips_m = robot.fk(update.poses).point_mm / 1000.0  # NICO: base = URDF root
        drawn = view.handles["tip_path"].points
        np.testing.assert_allclose(drawn[:, 0], tips_m[:-1], atol=1e-6)
        np.testing.assert_allclose(drawn[-1, 1], tips_m[-1], atol=1e-6)
        goal = view.handles["goal_path"].points
        np.testing.assert_allclose(goal[-1, 1], update.task.goal.end_point_mm / 1000.0, atol=1e-6)
    assert len(view.scene_s) == 20 and all(s > 0 for s in view.scene_s)
    # the arm at the time slider's pose (the touch pose at 1.0), as yourdfpy draws it
    end = view.model.get_transform(robot.end_frame)[:3, 3]
    np.testing.assert_allclose(end, robot.fk(update.poses[-1]).point_mm[0] / 1000, atol=1e-9)
    view.gui["time"].value = 0.0
    _wait(lambda: np.allclose(view.model.get_transform(robot.end_frame)[:3, 3],
                              robot.fk(update.poses[0]).point_mm[0] / 1000, atol=1e-9))
    assert "ours-lm (warm start): solved, timed and judged in" in view.gui["status"].content
    settled = view.release()  # from scratch, as ikbench run solves it
    assert not settled.warm and "(from scratch)" in view.gui["status"].content
    assert ("every criterion met" in view.gui["criteria"].content
            or "fails: " in view.gui["criteria"].content)


def test_the_gizmos_own_events_move_the_design(view):
    designer = view.designer
    gizmo = view.gizmos["touch"]
    goal = designer.handles()["touch"] + np.array([0.0, 15.0, 10.0])
    gizmo.position = goal / 1000.0
    view._on_gizmo("touch", viser.TransformControlsEvent(None, None, gizmo, "update"))
    _wait(lambda: np.allclose(designer.handles()["touch"], goal, atol=0.5))
    far = goal + np.array([-700.0, 0.0, 0.0])
    gizmo.position = far / 1000.0
    view._on_gizmo("touch", viser.TransformControlsEvent(None, None, gizmo, "end"))
    _wait(lambda: view.handles["missed"].visible)
    assert "out of reach" in view.gui["criteria"].content
    assert "#c62828" in view.gui["criteria"].content  # the red banner
    reached = designer.update.reach.point_mm
    np.testing.assert_allclose(view.handles["missed"].position, reached / 1000, atol=1e-6)
    np.testing.assert_allclose(gizmo.position, reached / 1000, atol=1e-6)  # snapped on release
    assert not designer.update.warm  # and solved from scratch


def test_the_panel_changes_timing_and_saves(view, tmp_path):
    view.gui["timing"].value = "min-jerk"
    _wait(lambda: view.designer.update.timed.timing == "min-jerk")
    view.gui["duration"].value = 3.0
    _wait(lambda: view.designer.update.timed.duration_s == pytest.approx(3.0))
    assert "(min-jerk)" in view.gui["status"].content
    saved = view.save(str(tmp_path), "panel")
    assert (saved.folder / "run.json").is_file() and saved.files[0].is_file()
    assert saved.command in view.gui["saved"].content
    assert "--timing min-jerk" in saved.command and "--duration 3" in saved.command
    view.gui["start"].value = "3"
    _wait(lambda: np.allclose(view.designer.update.task.required.start_pose,
                              view.designer.design.recorded_poses["3"]))
    start_m = view.designer.update.task.goal.start_point_mm / 1000  # NICO: base = URDF root
    _wait(lambda: np.allclose(view.gizmos["start"].position, start_m, atol=1e-6))


def test_a_letter_and_a_pose_path_get_their_own_controls():
    from ikbench.viewer.design.view import serve_design

    letter = serve_design(Designer("nico_right_arm", "ours-lm",
                                   DesignSpec(shape="letter:C", steps=30)),
                          port=0, open_browser=False, animate=False)
    try:
        assert set(letter.gizmos) == {"centre"} and "size" in letter.gui
        letter.gui["size"].value = 200.0
        _wait(lambda: letter.designer.design.size_mm == 200.0)
    finally:
        letter.stop()
    path = serve_design(Designer(None, "ours-lm", DesignSpec(problem="fetch_arm__hello")),
                        port=0, open_browser=False, animate=True)
    try:
        assert set(path.gizmos) == {"waypoint"}
        path.gui["waypoint"].value = 3
        goal = path.designer.update.task.goal.points_mm[3]
        _wait(lambda: np.allclose(path.designer.handles()["waypoint"], goal))
        T = path.T_root_base
        # the GUI callback selects the waypoint, then moves the gizmo: wait for both
        expected = goal / 1000 @ T[:3, :3].T + T[:3, 3]
        _wait(lambda: np.allclose(path.gizmos["waypoint"].position, expected, atol=1e-6))
        np.testing.assert_allclose(path.gizmos["waypoint"].position, expected, atol=1e-6)
    finally:
        path.stop()


@pytest.mark.parametrize("args, message", [
    (["--port", "70000"], "--port: 70000 is not a port number (0-65535)"),
    (["--timing", "slow"], "--timing: 'slow'; allowed: constant, min-jerk, topp"),
    (["--method", "nope"], "--method: unknown method 'nope'"),
    (["--name", "../x"], "--name: '../x' is not allowed"),
    (["--problem", "fetch_arm__hello", "--shape", "letter:A"],
     "--shape does not apply to --problem"),
    (["--shape", "spline:x.csv"], "the designer draws line or letter:X"),
])
def test_bad_input_is_one_line(args, message, capsys):
    assert main(["design", *args, "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ikbench: error: ") and message in err and "Traceback" not in err


def test_without_viser_one_line_says_how_to_install(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "viser", None)
    assert main(["design", "--no-browser"]) == 2
    assert capsys.readouterr().err.strip() == ("ikbench: error: ikbench design needs viser, "
                                               "which is not installed: pip install "
                                               "'ikbench[viewer]'")


def test_ikbench_design_stops_cleanly_on_ctrl_c():
    process = subprocess.Popen(
        [sys.executable, "-m", "ikbench.cli", "design", "--method", "ours-lm", "--port", "0",
         "--no-browser"], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = process.stdout.readline()
        assert line.startswith("ikbench designer: http://127.0.0.1:"), line
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 0, err
    assert "stopping the designer" in out and "Traceback" not in err
