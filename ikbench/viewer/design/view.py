"""The designer in the browser (``ikbench design``), on viser.

The scene: the arm (the URDF's visual shapes, ``ViserUrdf``) playing the trajectory at its
timing, the goal path (green), the fingertip path (blue), and a translation gizmo on each of
the design's points (:meth:`~.designer.Designer.handles`: the touch and start points of a
line, a letter's centre, a pose path's chosen waypoint). Dragging a gizmo re-solves the
trajectory (:meth:`~.designer.Designer.move`, warm-started) and redraws it; releasing it
solves the task from scratch (:meth:`~.designer.Designer.settle`, what Save writes). Where the
arm cannot get to the point, a red sphere shows where it got, and the gizmo snaps there when
released. The panel
(:mod:`.panel`) shows every criterion, green or red, and the controls.

Changes from the browser run in one worker thread, the latest of each kind first (a drag
sends many positions; the ones that arrive while a solve runs are replaced by the newest, so
the view never falls behind the hand). :meth:`DesignerView.drag` makes the same change
synchronously, as the tests and the benchmark do.
"""

from __future__ import annotations

import contextlib
import io
import threading
import time
import webbrowser
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
import numpy.typing as npt
import viser
from viser.extras import ViserUrdf

from ikbench.studies.run import DEFAULT_OUTPUT
from ikbench.viewer import scene as sc
from ikbench.viewer.design import panel
from ikbench.viewer.design.designer import Designer, Update
from ikbench.viewer.design.save import Saved
from ikbench.viewer.server import address, block_until_stopped, frame_scene, new_server

TITLE = "ikbench designer"
#: Gizmo size [m] and the playback's frame rate [1/s].
GIZMO_SCALE = 0.1
FPS = 30.0
#: The motion holds its last pose this long before it plays again [s].
HOLD_S = 0.8
TIP_COLOR = sc.RUN_COLORS[0]
#: Gizmo colours are viser's; the point the arm got to, when it is not the dragged one.
MISSED_COLOR = sc.COLLISION_COLOR


@dataclass
class DesignerView:
    """A running designer: the viser server, its scene and panel, and the designer."""

    designer: Designer
    server: viser.ViserServer
    host: str
    urdf: ViserUrdf
    model: Any  # the yourdfpy.URDF that ViserUrdf poses
    T_root_base: np.ndarray
    animate: bool = True
    #: Save's default output folder and run name
    output: str = DEFAULT_OUTPUT
    name: str = "design"
    gizmos: dict[str, viser.TransformControlsHandle] = field(default_factory=dict)
    handles: dict[str, Any] = field(default_factory=dict)
    gui: dict[str, Any] = field(default_factory=dict)
    #: seconds from each change to its scene update (IK, solve, judgement and drawing)
    scene_s: list[float] = field(default_factory=list)
    saved: Saved | None = None
    _lock: threading.RLock = field(default_factory=threading.RLock)
    _wake: threading.Event = field(default_factory=threading.Event)
    _stop: threading.Event = field(default_factory=threading.Event)
    _pending: dict[str, Callable[[], Any]] = field(default_factory=dict)
    _clock: float = field(default_factory=time.perf_counter)
    _threads: list[threading.Thread] = field(default_factory=list)

    @property
    def url(self) -> str:
        """The designer's address."""
        return address(self.server, self.host)

    @property
    def update(self) -> Update:
        """The update shown."""
        return self.designer.update

    # ----- changes ----------------------------------------------------------------------------
    def drag(self, handle: str, point_mm: npt.ArrayLike) -> Update:
        """Move the gizmo ``handle`` to ``point_mm`` (3,) [mm, base frame] as one step of a
        drag in the browser does, re-solve (warm-started) and redraw, synchronously
        (:attr:`scene_s` gets the time)."""
        point = np.asarray(point_mm, dtype=float)
        self.gizmos[handle].position = sc.to_root_m(self.T_root_base, point)
        return self.apply(lambda: self.designer.move(handle, point))

    def release(self) -> Update:
        """What releasing a gizmo does: solve from scratch (:meth:`~.designer.Designer.
        settle`), redraw and put the gizmos on their points."""
        return self.apply(self.designer.settle, snap=True)

    def apply(self, change: Callable[[], Any], snap: bool = False) -> Update:
        """Make a change of the designer and redraw (``snap``: and put the gizmos on their
        points, after a change that moved them, e.g. a recorded start pose); returns the
        update shown."""
        started = time.perf_counter()
        with self._lock:
            change()
            if snap:
                self._snap()
            self.show(started)
        return self.update

    def request(self, key: str, change: Callable[[], Any], snap: bool = False) -> None:
        """Queue a change for the worker (:meth:`apply`); a pending change of the same ``key``
        is replaced."""
        with self._lock:
            self._pending.pop(key, None)
            self._pending[key] = partial(self.apply, change, snap)
        self._wake.set()

    def select_waypoint(self, waypoint: int) -> None:
        """Drag waypoint ``waypoint`` of a pose path from now on (the gizmo moves there)."""
        self.designer.select_waypoint(waypoint)
        self._snap()

    def save(self, output: str, name: str) -> Saved:
        """Save the design (:meth:`~.designer.Designer.save`) and say where, in the panel."""
        self.gui["saved"].content = "saving..."
        try:
            self.saved = saved = self.designer.save(output, name)
        except Exception as exc:  # a bad name or folder: said in the panel, the view goes on
            self.gui["saved"].content = f"**not saved**: {exc}"
            raise
        files = ", ".join(f"`{f}`" for f in saved.files)
        self.gui["saved"].content = (f"saved {files} and `{saved.folder}/` (the trajectory "
                                     f"changed by {saved.change_deg:.2g} when solved from "
                                     f"scratch)  \n`{saved.command}`")
        return saved

    def set_playing(self, playing: bool) -> None:
        """Play the motion in a loop, or hold the arm at the time slider's pose."""
        self.animate = playing
        self._clock = time.perf_counter()
        self.pose_arm()

    # ----- drawing ----------------------------------------------------------------------------
    def show(self, started: float | None = None) -> None:
        """Draw the designer's update: paths, markers, gizmos, panel."""
        update, robot = self.update, self.designer.robot
        tips = sc.to_root_m(self.T_root_base, robot.fk(update.poses).point_mm)
        goal = np.asarray(update.task.goal.points_mm, dtype=float)
        down = np.asarray(update.task.goal.pen_down, dtype=bool)
        segments = sc.segments(sc.to_root_m(self.T_root_base, goal))[down[:-1] & down[1:]]
        with self.server.atomic():
            self.handles["tip_path"].points = sc.segments(tips).astype(np.float32)
            self.handles["goal_path"].points = segments.astype(np.float32)
            found = update.reach
            missed = found is not None and not found.reachable
            self.handles["missed"].visible = missed
            if found is not None and missed:
                self.handles["missed"].position = sc.to_root_m(self.T_root_base,
                                                               found.point_mm)
            self.gui["criteria"].content = panel.criteria_html(update)
            self.gui["limits"].content = panel.limits_html(robot, update)
            self.pose_arm()
        if started is not None:
            self.scene_s.append(time.perf_counter() - started)
        self.gui["status"].content = panel.status_text(
            update, self.scene_s[-1] if started is not None else None)

    def pose_arm(self, t_s: float | None = None) -> None:
        """Pose the arm at time ``t_s`` [s] of the motion (default: the playback's time, or
        the time slider's when not playing)."""
        timed = self.update.timed
        if t_s is None:
            if self.animate:
                cycle = timed.duration_s + HOLD_S
                t_s = min((time.perf_counter() - self._clock) % cycle, timed.duration_s)
            else:
                t_s = float(self.gui["time"].value) * timed.duration_s
        q, _, _ = timed.sample(np.array([t_s]))
        cfg = sc.configurations(self.model, self.designer.robot, q)[0]
        with self.server.atomic():
            self.urdf.update_cfg(cfg)
            self.handles["tip"].position = sc.to_root_m(
                self.T_root_base, self.designer.robot.fk(q).point_mm[0])

    def _snap(self) -> None:
        """Put every gizmo on its point (where the arm got)."""
        for name, point in self.designer.handles().items():
            self.gizmos[name].position = sc.to_root_m(self.T_root_base, point)

    # ----- threads ----------------------------------------------------------------------------
    def _on_gizmo(self, name: str, event: viser.TransformControlsEvent) -> None:
        point = to_base_mm(self.T_root_base, np.asarray(event.target.position, dtype=float))

        release = event.phase == "end"

        def move() -> None:
            if not np.allclose(point, self.designer.handles()[name], atol=1e-9):
                self.designer.move(name, point)
            if release:
                self.designer.settle()
            if name == "start" and "start" in self.gui:
                self.gui["start"].value = panel.DRAGGED
        self.request(f"move {name}", move, snap=release)

    def _worker(self) -> None:
        """Apply queued changes, oldest key first, each the newest of its key."""
        while not self._stop.is_set():
            self._wake.wait(0.1)
            self._wake.clear()
            while True:
                with self._lock:
                    if not self._pending:
                        break
                    key = next(iter(self._pending))
                    change = self._pending.pop(key)
                try:
                    change()
                except Exception as exc:  # said in the panel; the designer keeps its state
                    self.gui["status"].content = f"**{key} refused**: {exc}"

    def _player(self) -> None:
        while not self._stop.wait(1.0 / FPS):
            if self.animate:
                with self._lock:
                    self.pose_arm()

    def stop(self) -> None:
        """Stop the threads and the server."""
        self._stop.set()
        self._wake.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        with contextlib.redirect_stdout(io.StringIO()):  # viser's "Server stopped"
            self.server.stop()


def to_base_mm(T_root_base: np.ndarray, point_m: np.ndarray) -> np.ndarray:
    """A point (3,) [m] in the URDF's root frame -> the robot's base frame [mm]."""
    return (np.asarray(point_m, dtype=float) - T_root_base[:3, 3]) @ T_root_base[:3, :3] * 1000.0


def serve_design(designer: Designer, *, port: int = 8080, host: str = "127.0.0.1",
                 open_browser: bool = True, animate: bool = True,
                 output: str = DEFAULT_OUTPUT, name: str = "design") -> DesignerView:
    """Start the designer's view (non-blocking) and return it.

    Args:
        designer: the design.
        port: TCP port (viser tries the next ones when it is taken; 0: any free port).
        host: interface to listen on (default: this machine only).
        open_browser: open the URL in the default browser.
        animate: play the motion in a loop (False: the arm holds the time slider's pose).
        output, name: where Save writes, as the panel first shows it.
    """
    robot = designer.robot
    server = new_server(host, port, TITLE)
    server.gui.configure_theme(control_width="large")
    model = sc.load_model(robot)
    T_root_base = sc.base_transform(model, robot)
    urdf = ViserUrdf(server, model, root_node_name="/robot")
    view = DesignerView(designer, server, host, urdf, model, T_root_base, animate, output,
                        name)
    empty = np.zeros((1, 2, 3), dtype=np.float32)
    view.handles = {
        "goal_path": server.scene.add_line_segments("/paths/goal", empty, sc.GOAL_COLOR,
                                                    thickness=0.003),
        "tip_path": server.scene.add_line_segments("/paths/tip", empty, TIP_COLOR,
                                                   thickness=0.004),
        "tip": server.scene.add_icosphere("/tip", radius=0.008, color=TIP_COLOR),
        "missed": server.scene.add_icosphere("/missed", radius=0.012, color=MISSED_COLOR,
                                             visible=False)}
    for name, point in designer.handles().items():
        gizmo = server.scene.add_transform_controls(
            f"/gizmo/{name}", scale=GIZMO_SCALE, disable_rotations=True,
            position=sc.to_root_m(T_root_base, point))
        gizmo.on_update(partial(view._on_gizmo, name))
        server.scene.add_label(f"/gizmo/{name}/label", name, position=(0.0, 0.0, 0.03))
        view.gizmos[name] = gizmo
    if designer.update.task.required.obstacles:
        sc.add_obstacles(server, designer.update.task.required.obstacles, T_root_base,
                         designer.update.task.goal.points_mm)
    frame_scene(server, robot, _framing(view))
    view.gui = panel.add_panel(server, view)
    view.show()
    for target, label in ((view._worker, "designer-worker"), (view._player, "designer-player")):
        thread = threading.Thread(target=target, name=label, daemon=True)
        thread.start()
        view._threads.append(thread)
    if open_browser:
        webbrowser.open(view.url)
    return view


def _framing(view: DesignerView) -> list[np.ndarray]:
    """Points [m] the initial camera frames: the arm along the motion, the goal path and a
    margin around each gizmo (room to drag)."""
    robot, update = view.designer.robot, view.update
    poses = update.poses[:: max(1, update.task.goal.steps // 10)]
    out = [sc.to_root_m(view.T_root_base, robot.skeleton_mm(poses)).reshape(-1, 3),
           sc.to_root_m(view.T_root_base, update.task.goal.points_mm)]
    for gizmo in view.gizmos.values():
        out.append(np.asarray(gizmo.position) + GIZMO_SCALE * np.array([[1, 1, 1], [-1, -1, 0]]))
    return out


def run_design_forever(designer: Designer, **kwargs: Any) -> None:
    """Serve the designer (keywords of :func:`serve_design`), print the URL and block until
    Ctrl-C or SIGTERM (:func:`ikbench.viewer.server.block_until_stopped`)."""
    block_until_stopped(lambda: serve_design(designer, **kwargs), TITLE)

