"""The viewer's panel: trajectory dropdown, playback controls, run legend and checkboxes.

Assigning a handle's ``value`` on the server runs its ``on_update`` callbacks in the
assigning thread, so the playback thread moves the slider and the slider poses the arms.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Sequence
from typing import Protocol

import numpy as np
import viser

from ikbench.viewer import scene as sc
from ikbench.viewer.folders import ViewRun

#: Playback speeds (label -> factor of the real speed).
SPEEDS = {"0.25x": 0.25, "0.5x": 0.5, "1x": 1.0, "2x": 2.0}


class PanelScene(Protocol):
    """What the panel reads of one run's scene (:class:`ikbench.viewer.server.RunScene`)."""

    run: ViewRun
    color: sc.RGB
    obstacles: dict[str, list]
    collisions: dict[str, viser.PointCloudHandle]


class PanelViewer(Protocol):
    """What the panel drives of the viewer (:class:`ikbench.viewer.server.Viewer`); the
    server builds the viewer and adds this panel to it, so the panel names it by this type."""

    gui: dict
    _anchor: tuple[float, int]
    ghosts: bool

    @property
    def scenes(self) -> Sequence[PanelScene]: ...
    @property
    def times(self) -> np.ndarray: ...
    @property
    def playing(self) -> bool: ...
    @property
    def _lock(self) -> threading.RLock: ...
    def play(self) -> None: ...
    def pause(self) -> None: ...
    def show(self, step: int) -> None: ...
    def refresh_visibility(self) -> None: ...


def _legend(scenes, ghosts: bool = False) -> str:
    def swatch(rgb, alpha=1.0):
        return ('<span style="display:inline-block;width:12px;height:12px;margin-right:6px;'
                f'background:rgba({rgb[0]},{rgb[1]},{rgb[2]},{alpha});border:1px solid #555">'
                '</span>')

    other = "fingertip, arm ghost" if ghosts else "fingertip (arm: whole ghosts)"
    rows = [f"<div>{swatch(s.color)}<b>{s.run.label}</b>: "
            f"{'fingertip, arm in URDF colours' if i == 0 else other}</div>"
            for i, s in enumerate(scenes)]
    rows.append(f"<div>{swatch(sc.GOAL_COLOR)}goal path</div>")
    if any(s.obstacles for s in scenes):
        rows.append(f"<div>{swatch(sc.OBSTACLE_COLOR, sc.OBSTACLE_OPACITY)}obstacles</div>")
        rows.append(f"<div>{swatch(sc.COLLISION_COLOR)}colliding waypoints (fingertip)</div>")
    return '<div style="font-size:0.8em;line-height:1.6">' + "".join(rows) + "</div>"


def _collision_note(scene: PanelScene) -> str:
    """``; obstacles: N, colliding waypoints: 1: 12 of 200, ...`` for a run with
    obstacles, else nothing."""
    if not scene.obstacles:
        return ""
    counts = ", ".join(
        f"{tid}: {len(scene.collisions[tid].points) if tid in scene.collisions else 0} of "
        f"{len(traj.poses)}" for tid, traj in scene.run.trajectories.items()
        if tid in scene.obstacles)
    count = len({id(h) for handles in scene.obstacles.values() for h in handles})
    return f"; {count} obstacle{'s' * (count != 1)}, colliding waypoints {counts}"


def add_gui(server: viser.ViserServer, viewer: PanelViewer, ids: list[str]) -> None:
    """Add the panel's controls to ``server`` and wire them to ``viewer``; the handles go
    into ``viewer.gui`` (``trajectory``, ``step``, ``time``, ``play``, ``speed``, ``loop``,
    ``runs``, ``goal``, ``tip``, ``others``; ``ghosts`` with several runs; ``obstacles`` and
    ``collisions`` when a run has obstacles)."""
    gui, scenes = viewer.gui, viewer.scenes
    with server.gui.add_folder("Trajectory"):
        gui["trajectory"] = server.gui.add_dropdown("trajectory", ids, initial_value=ids[0])
        server.gui.add_markdown("<br>".join(f"**{s.run.label}**: {s.run.goal_source}"
                                            f"{_collision_note(s)}" for s in scenes))
    with server.gui.add_folder("Playback"):
        gui["step"] = server.gui.add_slider("step", min=0, max=max(len(viewer.times) - 1, 1),
                                            step=1, initial_value=0)
        gui["time"] = server.gui.add_markdown("")
        gui["play"] = server.gui.add_button("Play", icon=viser.Icon.PLAYER_PLAY)
        gui["speed"] = server.gui.add_dropdown("speed", tuple(SPEEDS), initial_value="1x")
        gui["loop"] = server.gui.add_checkbox("loop", False)
    with server.gui.add_folder("Runs"):
        server.gui.add_html(_legend(scenes, viewer.ghosts))
        gui["runs"] = [server.gui.add_checkbox(s.run.label, True) for s in scenes]
        gui["goal"] = server.gui.add_checkbox("goal path", True)
        gui["tip"] = server.gui.add_checkbox("fingertip path", True)
        gui["others"] = server.gui.add_checkbox("other trajectories", True,
                                                hint="the first run's, faint")
        if len(scenes) > 1:
            gui["ghosts"] = server.gui.add_checkbox(
                "whole ghosts", viewer.ghosts,
                hint="the other runs' arms, translucent (off: their fingertip paths only)")
        if any(s.obstacles for s in scenes):
            gui["obstacles"] = server.gui.add_checkbox("obstacles", True)
            gui["collisions"] = server.gui.add_checkbox(
                "colliding waypoints", True, hint="red: the arm touches an obstacle or itself")

    @gui["step"].on_update
    def _(event) -> None:
        if event.client is not None and viewer.playing:  # dragged while playing
            viewer._anchor = (time.perf_counter(), int(gui["step"].value))
        viewer.show(int(gui["step"].value))

    @gui["play"].on_click
    def _(_) -> None:
        viewer.pause() if viewer.playing else viewer.play()

    @gui["speed"].on_update
    def _(_) -> None:
        with viewer._lock:  # keep the step, change the rate from now on
            viewer._anchor = (time.perf_counter(), int(gui["step"].value))

    @gui["trajectory"].on_update
    def _(_) -> None:
        viewer.refresh_visibility()
        viewer.show(int(gui["step"].value))

    boxes = [*gui["runs"], gui["goal"], gui["tip"], gui["others"]]
    for box in boxes + [gui[k] for k in ("obstacles", "collisions", "ghosts") if k in gui]:
        box.on_update(lambda _: viewer.refresh_visibility())
