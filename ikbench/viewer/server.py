"""The 3-D viewer in the browser (``ikbench view``), on viser.

Each run gets an arm drawn from the URDF's visual shapes (``viser.extras.ViserUrdf``): the
first run's in the URDF's own colours, every further run's as a *ghost* (its run colour,
35 % opaque), so methods are compared side by side on the same target. The ghosts' arms are
hidden by default (five whole-body ghosts wash out a humanoid): the other runs show their
fingertip paths and markers, and the panel's "whole ghosts" box (``ikbench view --ghosts``:
ticked from the start) shows their arms too. A dropdown picks the
trajectory (the target); for it, each run shows its fingertip path (run colour), its goal
path (green) and spheres at the current fingertip and goal points; the first run's other
trajectories stay faint for context. A slider steps through time; Play plays at the
trajectory's real speed (one step every T/n seconds, times the chosen speed; the step is
taken from the wall clock, so playback does not drift), with loop and speed controls. Under
``--timing min-jerk`` or ``topp`` each pose is shown from the time the timing reaches it
(:meth:`ikbench.viewer.folders.ViewTrajectory.retime`); the slider then steps at the shortest
segment (at most :data:`MAX_STEPS` steps). A run whose tasks have obstacles (run.json's
``obstacles``) shows them, translucent brown, with the selected trajectory
(:func:`ikbench.viewer.scene.add_obstacles`; a set of obstacles several runs share is drawn
once), and red points at the fingertip of each waypoint where the arm touches an obstacle
or itself (:func:`ikbench.viewer.scene.add_collision_markers`); a run without obstacles is
drawn as before.

Needs the ``[viewer]`` extra (viser); :mod:`ikbench.viewer` imports it only here.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import signal
import threading
import time
import webbrowser
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import viser
from viser.extras import ViserUrdf

from ikbench.core.errors import InputError
from ikbench.core.robot import Robot
from ikbench.render.arm_plots import frame_labels
from ikbench.viewer import scene as sc
from ikbench.viewer.folders import ViewRun
from ikbench.viewer.gui import SPEEDS, add_gui

GHOST_OPACITY = 0.35
#: The most slider steps of a retimed timeline.
MAX_STEPS = 5000
TITLE = "ikbench viewer"


@dataclass
class RunScene:
    """The scene handles of one run: its arm, and per trajectory id its configurations,
    fingertip and goal points [m, URDF root frame] and paths."""

    run: ViewRun
    color: sc.RGB
    opacity: float  # of the arm: 1, or GHOST_OPACITY in the run colour
    model: object  # the yourdfpy.URDF that ViserUrdf poses
    frame: viser.FrameHandle
    arm: viser.FrameHandle
    urdf: ViserUrdf
    cfg: dict[str, np.ndarray]
    tip_m: dict[str, np.ndarray]
    goal_m: dict[str, np.ndarray | None]
    tip_paths: dict[str, viser.LineSegmentsHandle]
    faint_paths: dict[str, viser.LineSegmentsHandle]
    goal_paths: dict[str, viser.LineSegmentsHandle]
    tip_marker: viser.IcosphereHandle
    goal_marker: viser.IcosphereHandle
    #: per trajectory id: the handles of its obstacles (one list shared by the trajectories,
    #: and by the runs, that have the same obstacles); ids without obstacles are absent
    obstacles: dict[str, list] = field(default_factory=dict)
    #: per trajectory id: the red points at its colliding waypoints; absent when none collide
    collisions: dict[str, viser.PointCloudHandle] = field(default_factory=dict)


@dataclass
class Viewer:
    """A running viewer: the viser server, its scene and GUI, and the playback state."""

    server: viser.ViserServer
    host: str
    times: np.ndarray  # (S,) timeline [s], one entry per slider step
    scenes: list[RunScene]
    gui: dict = field(default_factory=dict)
    ghosts: bool = False  # the other runs' whole arms shown at the start
    playing: bool = False
    _lock: threading.RLock = field(default_factory=threading.RLock)
    _stop: threading.Event = field(default_factory=threading.Event)
    _anchor: tuple[float, int] = (0.0, 0)  # (wall clock, step) when playback (re)started
    _thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        """The viewer's address (``localhost`` for a wildcard host)."""
        return address(self.server, self.host)

    @property
    def trajectory(self) -> str:
        """The trajectory id shown."""
        return str(self.gui["trajectory"].value)

    @property
    def step_s(self) -> float:
        """Seconds between slider steps at 1x."""
        return float(self.times[1] - self.times[0]) if len(self.times) > 1 else 0.0

    def set_step(self, step: int) -> None:
        """Show timeline step ``step`` (moves the slider; every arm follows)."""
        step = int(min(max(step, 0), len(self.times) - 1))
        if self.gui["step"].value == step:
            self.show(step)
        else:
            self.gui["step"].value = step  # runs the slider's callback

    def select(self, trajectory: str) -> None:
        """Show trajectory ``trajectory`` (an id of the runs)."""
        self.gui["trajectory"].value = trajectory  # runs the dropdown's callback

    def play(self) -> None:
        """Play from the current step (from the start when at the end)."""
        with self._lock:
            if self.gui["step"].value >= len(self.times) - 1:
                self.set_step(0)
            self._anchor = (time.perf_counter(), int(self.gui["step"].value))
            self.playing = True
            self.gui["play"].label, self.gui["play"].icon = "Pause", viser.Icon.PLAYER_PAUSE

    def pause(self) -> None:
        """Stop playing at the current step."""
        with self._lock:
            self.playing = False
            self.gui["play"].label, self.gui["play"].icon = "Play", viser.Icon.PLAYER_PLAY

    def stop(self) -> None:
        """End playback and stop the server."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        with contextlib.redirect_stdout(io.StringIO()):  # viser's "Server stopped"
            self.server.stop()

    def show(self, step: int) -> None:
        """Pose every arm and marker for timeline step ``step`` of the selected trajectory."""
        tid, t_s = self.trajectory, float(self.times[step])
        with self._lock, self.server.atomic():
            for s in self.scenes:
                traj = s.run.trajectories.get(tid)
                if traj is None:
                    continue
                k = traj.index_at(t_s)
                s.urdf.update_cfg(s.cfg[tid][k])
                s.tip_marker.position = s.tip_m[tid][k]
                goal = s.goal_m[tid]
                if goal is not None:
                    s.goal_marker.position = goal[min(k, len(goal) - 1)]
            self.gui["time"].content = (f"t = {t_s:.2f} s of {self.times[-1]:.2f} s "
                                        f"(step {step} / {len(self.times) - 1})")

    def refresh_visibility(self) -> None:
        """Show the selected trajectory's paths and arms as the checkboxes say."""
        tid, gui = self.trajectory, self.gui
        whole = bool(gui["ghosts"].value) if "ghosts" in gui else self.ghosts
        for i, (s, box) in enumerate(zip(self.scenes, gui["runs"])):
            s.frame.visible = bool(box.value)
            has = tid in s.run.trajectories
            s.tip_marker.visible = has
            s.arm.visible = has and (i == 0 or whole)
            s.goal_marker.visible = has and s.goal_m.get(tid) is not None and gui["goal"].value
            for key, path in s.tip_paths.items():
                path.visible = key == tid and bool(gui["tip"].value)
            for key, path in s.faint_paths.items():
                path.visible = key != tid and bool(gui["others"].value)
            for key, path in s.goal_paths.items():
                path.visible = key == tid and bool(gui["goal"].value)
            for key, points in s.collisions.items():
                points.visible = key == tid and bool(gui["collisions"].value)
        shown = {id(h) for s, box in zip(self.scenes, gui["runs"]) if box.value
                 for h in s.obstacles.get(tid, ())} if "obstacles" in gui else set()
        for s in self.scenes:
            for handles in s.obstacles.values():
                for handle in handles:
                    handle.visible = id(handle) in shown and bool(gui["obstacles"].value)

    def _player(self) -> None:
        """Playback loop: the step follows the wall clock x speed (no drift)."""
        while not self._stop.wait(0.005):
            with self._lock:
                if not self.playing or self.step_s <= 0.0:
                    continue
                t0, s0 = self._anchor
                speed = SPEEDS.get(str(self.gui["speed"].value), 1.0)
                step = s0 + int((time.perf_counter() - t0) * speed / self.step_s)
                if step > len(self.times) - 1:
                    if self.gui["loop"].value:
                        self._anchor, step = (time.perf_counter(), 0), 0
                    else:
                        step = len(self.times) - 1
                        self.pause()
                if step != self.gui["step"].value:
                    self.gui["step"].value = step


def timeline(runs: list[ViewRun]) -> np.ndarray:
    """The slider's times [s]: the finest pose spacing over the longest trajectory."""
    trajs = [t for r in runs for t in r.trajectories.values()]
    dts = [t.duration_s / t.steps if t.times_s is None else float(np.diff(t.times_s).min())
           for t in trajs if t.duration_s > 0 and t.steps > 0]
    if not dts:
        return np.zeros(1)
    dt, total = min(dts), max(t.duration_s for t in trajs)
    if any(t.times_s is not None for t in trajs):
        dt = max(dt, total / MAX_STEPS)
    return np.arange(int(round(total / dt)) + 1) * dt


def _add_run(server, robot: Robot, run: ViewRun, index: int, framing: list,
             drawn: dict[str, list] | None = None) -> RunScene:
    """Add one run's arm, paths, markers, obstacles and collision markers to the scene;
    ``framing`` gains the points [m] the initial camera should see, ``drawn`` (obstacle
    sets already in the scene, by their JSON) the obstacles drawn here."""
    color = sc.RUN_COLORS[index % len(sc.RUN_COLORS)]
    model = sc.load_model(robot)  # one yourdfpy model per arm
    T_root_base = sc.base_transform(model, robot)
    frame = server.scene.add_frame(f"/run{index}", show_axes=False)
    arm = server.scene.add_frame(f"/run{index}/robot", show_axes=False)
    override = None if index == 0 else (color[0] / 255, color[1] / 255, color[2] / 255,
                                        GHOST_OPACITY)
    urdf = ViserUrdf(server, model, root_node_name=f"/run{index}/robot",
                     mesh_color_override=override)
    cfg, tips, goals, tip_paths, faint, goal_paths = {}, {}, {}, {}, {}, {}
    for tid, traj in run.trajectories.items():
        cfg[tid] = sc.configurations(model, robot, traj.poses)
        tips[tid] = sc.to_root_m(T_root_base, traj.tip_mm)
        goals[tid] = None if traj.goal_mm is None else sc.to_root_m(T_root_base, traj.goal_mm)
        framing += [tips[tid], sc.to_root_m(T_root_base, robot.skeleton_mm(traj.poses)
                                            ).reshape(-1, 3)]
        name = f"/run{index}/paths/{_node(tid)}"
        tip_paths[tid] = server.scene.add_line_segments(
            f"{name}/tip", sc.segments(tips[tid]), color, thickness=0.004)
        if index == 0:  # the first run's other trajectories, for context
            faint[tid] = server.scene.add_line_segments(
                f"{name}/faint", sc.segments(tips[tid]), sc.lighter(color, 0.65),
                thickness=0.0015)
        if traj.goal_segments_mm is not None and len(traj.goal_segments_mm):
            goal_paths[tid] = server.scene.add_line_segments(
                f"{name}/goal", sc.to_root_m(T_root_base, traj.goal_segments_mm),
                sc.GOAL_COLOR, thickness=0.0025)
        for row in cfg[tid][[0, -1]]:  # the visual shapes' extent at the first and last pose
            model.update_cfg(row)
            if model.scene is not None and len(model.scene.geometry):
                framing.append(np.asarray(model.scene.bounds, dtype=float))
    tip_marker = server.scene.add_icosphere(f"/run{index}/tip_marker", radius=0.008,
                                            color=color)
    goal_marker = server.scene.add_icosphere(f"/run{index}/goal_marker", radius=0.006,
                                             color=sc.GOAL_COLOR, opacity=0.8)
    obstacles, collisions = _add_obstacles(server, robot, run, index, T_root_base, framing,
                                           {} if drawn is None else drawn)
    return RunScene(run, color, 1.0 if override is None else GHOST_OPACITY, model, frame, arm,
                    urdf, cfg, tips, goals, tip_paths, faint, goal_paths, tip_marker,
                    goal_marker, obstacles, collisions)


def _add_obstacles(server, robot: Robot, run: ViewRun, index: int, T_root_base: np.ndarray,
                   framing: list, drawn: dict[str, list]) -> tuple[dict, dict]:
    """Draw the run's obstacles (each distinct set once, under ``/obstacles/<k>``; a set an
    earlier run drew is reused) and red points at each trajectory's colliding waypoints.
    Returns (handles by trajectory id, collision markers by trajectory id); both empty for
    a run without obstacles."""
    handles: dict[str, list] = {}
    markers: dict[str, viser.PointCloudHandle] = {}
    trajs = [t for t in run.trajectories.values() if t.obstacles]
    if not trajs:
        return handles, markers
    around = np.vstack([t.tip_mm for t in run.trajectories.values()])  # a half-space's patch
    for traj in trajs:
        key = json.dumps([o.to_dict() for o in traj.obstacles], sort_keys=True)
        if key not in drawn:
            drawn[key] = sc.add_obstacles(server, traj.obstacles, T_root_base, around,
                                          name=f"/obstacles/{len(drawn)}")
            framing.append(np.array([h.position for h, o in zip(drawn[key], traj.obstacles)
                                     if o.kind != "halfspace"]).reshape(-1, 3))
        handles[traj.name] = drawn[key]
        marker = sc.add_collision_markers(
            server, f"/run{index}/paths/{_node(traj.name)}/collisions", robot, traj.poses,
            traj.tip_mm, traj.obstacles, T_root_base)
        if marker is not None:
            markers[traj.name] = marker
    return handles, markers


def _node(tid: str) -> str:
    """A scene-node name for a trajectory id (letters, digits, '_', '-', '.')."""
    return "t_" + "".join(c if c.isalnum() or c in "_-." else "_" for c in tid)


def frame_scene(server: viser.ViserServer, robot: Robot, framing: list) -> None:
    """Floor grid, base axes and the initial camera from the robot's figure view, framing
    the points [m] of ``framing`` (arrays (..., 3), URDF root frame)."""
    points = np.vstack(framing)
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = float(max(hi[0] - lo[0], hi[1] - lo[1])) * 1.2 + 0.1
    server.scene.add_grid("/grid", width=size, height=size, cell_size=0.05,
                          section_size=0.25, position=((lo[0] + hi[0]) / 2,
                                                       (lo[1] + hi[1]) / 2,
                                                       min(0.0, float(lo[2])) - 0.002))
    server.scene.add_frame("/root_axes", axes_length=0.05, axes_radius=0.002)
    _, (elev, azim) = frame_labels(robot)
    fov = math.radians(50.0)
    position, look_at = sc.camera_pose(points, sc.view_direction(elev, azim), fov)
    server.initial_camera.fov = fov
    server.initial_camera.position = position
    server.initial_camera.look_at = look_at


def check_trajectory(runs: list[ViewRun], trajectory: str | None) -> list[str]:
    """The trajectory ids of ``runs``; InputError when ``trajectory`` is not one of them."""
    ids = list(dict.fromkeys(t for r in runs for t in r.trajectories))
    if trajectory is not None and trajectory not in ids:
        raise InputError(f"trajectory: {trajectory!r} is not a trajectory of these runs; "
                         f"available: {', '.join(ids)}")
    return ids


def serve(robot: Robot, runs: list[ViewRun], *, port: int = 8080, host: str = "127.0.0.1",
          open_browser: bool = True, trajectory: str | None = None,
          ghosts: bool = False) -> Viewer:
    """Start the viewer (non-blocking) and return its handle.

    Args:
        robot: the runs' robot.
        runs: the runs to show side by side (first: solid arm, others: ghosts).
        port: TCP port (viser tries the next ones when it is taken; 0: any free port).
        host: interface to listen on (default: this machine only).
        open_browser: open the URL in the default browser.
        trajectory: the trajectory id shown first (default: the first run's first).
        ghosts: show the other runs' whole arms from the start (default: their fingertip
            paths only; the panel's "whole ghosts" box switches).
    """
    ids = check_trajectory(runs, trajectory)
    server = new_server(host, port, TITLE)
    framing: list[np.ndarray] = []
    drawn: dict[str, list] = {}  # obstacle sets in the scene, shared by the runs that have them
    scenes = [_add_run(server, robot, run, i, framing, drawn) for i, run in enumerate(runs)]
    frame_scene(server, robot, framing)
    viewer = Viewer(server, host, timeline(runs), scenes, ghosts=ghosts)
    add_gui(server, viewer, ids)
    if trajectory is not None:
        viewer.select(trajectory)
    viewer.refresh_visibility()
    viewer.show(0)
    viewer._thread = threading.Thread(target=viewer._player, name="viewer-player", daemon=True)
    viewer._thread.start()
    if open_browser:
        webbrowser.open(viewer.url)  # False, not an error, where there is no browser
    return viewer


def new_server(host: str, port: int, label: str) -> viser.ViserServer:
    """A viser server on ``host:port`` (the next free port when taken; 0: any), z up,
    without viser's banner (the caller prints the URL)."""
    with contextlib.redirect_stdout(io.StringIO()):
        server = viser.ViserServer(host=host, port=port, label=label, verbose=False)
    server.scene.set_up_direction("+z")
    return server


def address(server: viser.ViserServer, host: str) -> str:
    """``http://HOST:PORT/`` of a server listening on ``host`` (``localhost`` for a wildcard
    host), with the port it bound."""
    shown = "localhost" if host in ("0.0.0.0", "::", "") else host
    return f"http://{shown}:{server.get_port()}/"


def run_forever(robot: Robot, runs: list[ViewRun], **kwargs: Any) -> None:
    """Serve (keywords of :func:`serve`), print the URL and block until Ctrl-C or SIGTERM,
    then stop cleanly (:func:`block_until_stopped`)."""
    block_until_stopped(lambda: serve(robot, runs, **kwargs), TITLE)


def block_until_stopped(start: Callable[[], Any], title: str) -> None:
    """Start a viewer (``start()``: an object with ``url`` and ``stop()``), print its URL and
    block until Ctrl-C or SIGTERM, then stop it cleanly (no traceback; another Ctrl-C while
    stopping changes nothing).

    The handlers are installed here, not inherited: a process started in the background by
    a non-interactive shell ignores SIGINT, and Ctrl-C must stop the viewer anyway.
    """
    stop = threading.Event()
    handlers = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        try:
            handlers[signum] = signal.signal(signum, lambda *_: stop.set())
        except ValueError:  # not the main thread: Ctrl-C comes as KeyboardInterrupt
            pass
    viewer = None
    try:
        viewer = start()
        print(f"{title}: {viewer.url}  (Ctrl-C to stop)", flush=True)
        stop.wait()
    except KeyboardInterrupt:
        pass
    finally:
        if viewer is not None:
            print(f"\nstopping the {title.split()[-1]}", flush=True)
            viewer.stop()
        for signum, handler in handlers.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)
