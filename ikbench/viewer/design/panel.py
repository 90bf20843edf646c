"""The designer's panel: what is judged (green or red), the joint ranges used, the controls.

The HTML builders are plain functions of an :class:`~.designer.Update` (the tests read them);
:func:`add_panel` puts them and the controls (method, timing, duration, start pose, letter
size, waypoint, playback, save) into a viser GUI and wires each control to the view.
"""

from __future__ import annotations

import html
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from ikbench.core.robot import wrap_continuous
from ikbench.core.timing import TIMINGS
from ikbench.methods.registry import available_methods
from ikbench.viewer.design.designer import Designer, Update
from ikbench.viewer.design.kinds import SIZE_RANGE_MM, LetterDesign, LineDesign, PathDesign

if TYPE_CHECKING:
    import viser

    from ikbench.core.robot import Robot

GREEN, RED, AMBER = "#1e7b34", "#c62828", "#b26a00"
#: A joint this close to a limit [pose units] is marked.
NEAR_LIMIT = 1.0
#: The start pose menu's entry for a start point dragged by hand.
DRAGGED = "(dragged)"


class DesignerControls(Protocol):
    """What the panel reads of the view and asks of it
    (:class:`ikbench.viewer.design.view.DesignerView`, which adds this panel)."""

    @property
    def designer(self) -> Designer: ...
    @property
    def animate(self) -> bool: ...
    @property
    def output(self) -> str: ...
    @property
    def name(self) -> str: ...
    def request(self, key: str, change: Callable[[], Any], snap: bool = False) -> None: ...
    def select_waypoint(self, waypoint: int) -> None: ...
    def save(self, output: str, name: str) -> object: ...
    def set_playing(self, playing: bool) -> None: ...
    def pose_arm(self, t_s: float | None = None) -> None: ...


def _row(ok: bool, text: str) -> str:
    sign, colour = ("&#10003;", GREEN) if ok else ("&#10007;", RED)
    return (f'<div style="color:{colour};margin:1px 0"><b>{sign}</b> '
            f"{html.escape(text)}</div>")


def criteria_html(update: Update) -> str:
    """A banner (every criterion met, or which fail) and one line per criterion."""
    failed = [c.label for c in update.criteria if not c.ok]
    colour, words = ((GREEN, "every criterion met") if not failed else
                     (RED, "fails: " + ", ".join(failed)))
    out = [f'<div style="background:{colour};color:white;padding:4px 6px;border-radius:4px;'
           f'font-weight:bold">{html.escape(words)}</div>']
    if update.message:
        out.append(f'<div style="color:{AMBER};margin:3px 0">{html.escape(update.message)}'
                   "</div>")
    out += [_row(c.ok, c.text().split(" ", 1)[1]) for c in update.criteria]
    return '<div style="font-size:0.8em;line-height:1.35">' + "".join(out) + "</div>"


def limits_html(robot: Robot, update: Update) -> str:
    """Per joint: its range (grey), the part the trajectory uses (blue; red within
    :data:`NEAR_LIMIT` of a limit), and the numbers."""
    lower, upper = (np.asarray(v, dtype=float) for v in update.task.limits(robot))
    poses = wrap_continuous(robot, update.poses)  # an unwrapped roll: its turn in the range
    rows = []
    for j, name in enumerate(robot.joint_names):
        low, high = float(poses[:, j].min()), float(poses[:, j].max())
        if math.isfinite(lower[j]) and math.isfinite(upper[j]) and upper[j] > lower[j]:
            span = upper[j] - lower[j]
            left, width = 100 * (low - lower[j]) / span, max(100 * (high - low) / span, 1.0)
            near = low - lower[j] < NEAR_LIMIT or upper[j] - high < NEAR_LIMIT
            bar = (f'<div style="position:relative;height:6px;background:#ddd;'
                   f'border-radius:3px"><div style="position:absolute;left:{left:.1f}%;'
                   f"width:{width:.1f}%;height:6px;border-radius:3px;"
                   f'background:{RED if near else "#1f77b4"}"></div></div>')
            bounds = f"[{lower[j]:.0f}, {upper[j]:.0f}]"
        else:
            bar, bounds = "", "(no limits)"
        rows.append(f"<div>{html.escape(name)}: {low:.1f} to {high:.1f} of {bounds}{bar}</div>")
    return ('<div style="font-size:0.75em;line-height:1.3">'
            f"<div>{html.escape(robot.pose_unit)}</div>" + "".join(rows) + "</div>")


def status_text(update: Update, scene_s: float | None) -> str:
    """``ours-exact (warm start): solved, timed and judged in 10.9 ms, scene 2.0 ms; n = 50,
    T = 2 s (constant)``."""
    scene = "" if scene_s is None else f", scene {1000 * scene_s:.1f} ms"
    start = "warm start" if update.warm else "from scratch"
    return (f"{update.method} ({start}): solved, timed and judged in "
            f"{1000 * update.elapsed_s:.1f} ms{scene}; n = {update.task.goal.steps}, "
            f"T = {update.timed.duration_s:.3g} s ({update.timed.timing})")


def add_panel(server: viser.ViserServer, view: DesignerControls) -> dict[str, Any]:
    """Add the controls and read-outs; returns their handles by name (``criteria``,
    ``limits``, ``status``, ``method``, ``timing``, ``duration``, ``play``, ``time``,
    ``output``, ``name``, ``save``, ``saved``, and per kind ``start``, ``size`` or
    ``waypoint``)."""
    designer, design = view.designer, view.designer.design
    gui: dict[str, Any] = {}
    with server.gui.add_folder("Design"):
        server.gui.add_markdown(_what(designer.kind, designer.robot.name))
        names = [n for n, c in available_methods().items() if c.capabilities.warm_starts]
        names = list(dict.fromkeys([designer.method.name, *names]))
        gui["method"] = server.gui.add_dropdown("method", names,
                                                initial_value=designer.method.name)
        if isinstance(design, LineDesign):
            gui["start"] = server.gui.add_dropdown(
                "start pose", [DRAGGED, *design.recorded_poses], initial_value="start",
                hint="a recorded pose of the targets, or drag the start point")
        if isinstance(design, LetterDesign):
            gui["size"] = server.gui.add_slider("size [mm]", min=SIZE_RANGE_MM[0],
                                                max=SIZE_RANGE_MM[1], step=10.0,
                                                initial_value=design.size_mm)
        if isinstance(design, PathDesign):
            gui["waypoint"] = server.gui.add_slider("waypoint", min=0,
                                                    max=design.base_task.goal.steps, step=1,
                                                    initial_value=design.waypoint)
    with server.gui.add_folder("Judged"):
        gui["criteria"] = server.gui.add_html("")
        gui["status"] = server.gui.add_markdown("")
    with server.gui.add_folder("Timing"):
        gui["timing"] = server.gui.add_dropdown("timing", tuple(TIMINGS),
                                                initial_value=designer.timing)
        gui["duration"] = server.gui.add_number("duration [s]", designer.duration_s,
                                                min=0.1, max=60.0, step=0.1,
                                                hint="T of constant and min-jerk (topp finds "
                                                "its own)")
        gui["play"] = server.gui.add_checkbox("play the motion", view.animate)
        gui["time"] = server.gui.add_slider("time (share of T)", min=0.0, max=1.0, step=0.01,
                                            initial_value=1.0)
    with server.gui.add_folder("Joint limits", expand_by_default=False):
        gui["limits"] = server.gui.add_html("")
    with server.gui.add_folder("Save"):
        gui["output"] = server.gui.add_text("output", view.output)
        gui["name"] = server.gui.add_text("name", view.name)
        gui["save"] = server.gui.add_button("Save targets and run")
        gui["saved"] = server.gui.add_markdown("")
    _wire(view, gui)
    return gui


def _what(kind: str, robot: str) -> str:
    return {"line": f"**{robot}**: drag the touch point (or the start point); the line "
                    "runs from the start to the touch point",
            "letter": f"**{robot}**: drag the letter's centre; set its size below",
            "path": f"**{robot}**: pick a waypoint and drag it; its neighbours follow"}[kind]


def _wire(view: DesignerControls, gui: dict[str, Any]) -> None:
    """Each control asks the view for its change (run in the view's worker)."""
    designer = view.designer

    gui["method"].on_update(lambda _: view.request(
        "method", lambda: designer.set_method(str(gui["method"].value))))
    gui["timing"].on_update(lambda _: view.request(
        "timing", lambda: designer.set_timing(str(gui["timing"].value))))
    gui["duration"].on_update(lambda _: view.request(
        "timing", lambda: designer.set_timing(designer.timing, float(gui["duration"].value))))
    gui["play"].on_update(lambda _: view.set_playing(bool(gui["play"].value)))
    gui["time"].on_update(lambda _: view.pose_arm())
    gui["save"].on_click(lambda _: view.request(
        "save", lambda: view.save(str(gui["output"].value), str(gui["name"].value))))
    if "start" in gui:
        def use(_: object) -> None:
            if gui["start"].value != DRAGGED:
                view.request("start", lambda: designer.use_start_pose(str(gui["start"].value)),
                             snap=True)
        gui["start"].on_update(use)
    if "size" in gui:
        gui["size"].on_update(lambda _: view.request(
            "size", lambda: designer.set_size(float(gui["size"].value))))
    if "waypoint" in gui:
        gui["waypoint"].on_update(lambda _: view.request(
            "waypoint", lambda: view.select_waypoint(int(gui["waypoint"].value))))
