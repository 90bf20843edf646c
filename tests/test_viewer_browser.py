"""ikbench view in a real browser: headless Chromium must draw the arms, the paths and the GUI.

Serves results/ours and results/sequential-ik (NICO, trajectory 1, step 30 of 50) on a free
port, opens the page in headless Chromium (:mod:`ikbench.viewer.browser`), captures it,
hides the arms on the server, captures again and compares:

- the arms: thousands of pixels of the 3-D view change when they are hidden;
- the paths: pixels of both runs' fingertip colours and of the goal colour are there, with
  and without the arms;
- the GUI: the panel lists the controls and both runs;
- another robot: a Panda run of ours-lm draws its arm and fingertip path.

Skipped when viser or Chromium is missing. ``IKBENCH_VIEWER_SCREENSHOT=docs/viewer.png``
keeps the capture with the arms (how docs/viewer.png was made).
"""

from __future__ import annotations

import io
import os
import shutil
import time

import numpy as np
import pytest
from PIL import Image

from ikbench.viewer.browser import HeadlessPage, find_chromium
from tests.conftest import REPO

pytest.importorskip("viser", reason="viser is not installed (pip install 'ikbench[viewer]')")
pytestmark = pytest.mark.skipif(find_chromium() is None, reason="no Chromium installed "
                                "(Debian: apt-get install -y chromium)")

RUNS = [REPO / "results" / "ours", REPO / "results" / "sequential-ik"]
VIEW_COLUMNS = 930  # the GUI panel starts at x ~ 945 in a 1280 px wide page


def _rgb(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int32)


def _hue_sat(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hue [deg] and HSV saturation of (..., 3) RGB values in [0, 1]."""
    top, c = rgb.max(axis=-1), rgb.max(axis=-1) - rgb.min(axis=-1)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    safe = np.where(c > 0, c, 1.0)
    hue = np.where(top == r, ((g - b) / safe) % 6,
                   np.where(top == g, (b - r) / safe + 2, (r - g) / safe + 4))
    return np.where(c > 0, hue * 60.0, 0.0), np.where(top > 0, c / np.where(top > 0, top, 1), 0)


def _pixels_of_hue(img: np.ndarray, rgb, tolerance_deg: float = 15.0) -> int:
    """Saturated pixels of the 3-D view near the hue of ``rgb`` (lit surfaces vary in
    brightness, so hue, not RGB distance)."""
    hue, sat = _hue_sat(img[:, :VIEW_COLUMNS] / 255.0)
    ref, _ = _hue_sat(np.array(rgb, dtype=float).reshape(1, 1, 3) / 255.0)
    distance = np.abs((hue - ref[0, 0] + 180.0) % 360.0 - 180.0)
    return int(((distance <= tolerance_deg) & (sat > 0.35)).sum())


def _drawn(img: np.ndarray) -> float:
    """Share of the 3-D view's pixels that differ from its background."""
    view = img[:, :VIEW_COLUMNS]
    background = np.median(view.reshape(-1, 3), axis=0)
    return float((np.abs(view - background).max(axis=-1) > 40).mean())


def _changed(a: np.ndarray, b: np.ndarray) -> int:
    """Pixels of the 3-D view that differ between two captures."""
    return int((np.abs(a - b).sum(axis=-1) > 30)[:, :VIEW_COLUMNS].sum())


def _settled(page, path, unlike=None, timeout_s: float = 90.0) -> np.ndarray:
    """Capture until the 3-D view is drawn (not blank, differs from ``unlike``) and two
    captures in a row agree: software WebGL takes seconds to draw the first frames."""
    previous, deadline = None, time.monotonic() + timeout_s
    while True:
        img = _rgb(page.capture(path))
        ready = _drawn(img) > 0.01 and (unlike is None or _changed(img, unlike) > 3000)
        if ready and previous is not None and _changed(img, previous) < 200:
            return img
        if time.monotonic() > deadline:
            return img  # the assertions below say what is missing
        previous = img if ready else None
        time.sleep(0.5)


def test_chromium_draws_the_arms_the_paths_and_the_gui(tmp_path):
    from ikbench.viewer.folders import load_runs
    from ikbench.viewer.scene import GOAL_COLOR
    from ikbench.viewer.server import serve

    robot, runs = load_runs(RUNS)
    viewer = serve(robot, runs, port=0, open_browser=False)
    viewer.set_step(30)
    try:
        with HeadlessPage(viewer.url, width=1280, height=800) as page:
            page.wait_for_text("sequential-ik")
            text = page.evaluate("document.body.innerText")
            full = _settled(page, tmp_path / "with_arms.png")
            for scene in viewer.scenes:
                scene.arm.visible = False
            bare = _settled(page, tmp_path / "without_arms.png", unlike=full)
    finally:
        viewer.stop()

    for word in ("ikbench viewer", "trajectory", "Playback", "Play", "step 30 / 50", "ours",
                 "sequential-ik", "goal path", "goal: rebuilt from run.json"):
        assert word in text, f"{word!r} is not in the page"
    assert _drawn(full) > 0.01, "a blank canvas"
    changed = _changed(full, bare)
    assert changed > 3000, f"hiding the arms changed only {changed} pixels"
    for scene in viewer.scenes:  # ours blue, sequential-ik orange (its path and ghost arm)
        assert _pixels_of_hue(full, scene.color) > 300, f"no {scene.run.label} colour"
        assert _pixels_of_hue(bare, scene.color) > 100, f"no {scene.run.label} path"
    assert _pixels_of_hue(full, GOAL_COLOR) > 50, "no goal path colour"
    keep = os.environ.get("IKBENCH_VIEWER_SCREENSHOT")
    if keep:
        shutil.copy(tmp_path / "with_arms.png", keep)


def test_chromium_draws_a_panda_run(tmp_path):
    """The same for another robot: a Panda run of ours-lm on its default targets."""
    from ikbench.cli import main
    from ikbench.viewer.folders import load_runs
    from ikbench.viewer.server import serve

    assert main(["run", "--method", "ours-lm", "--robot", "panda", "--only", "front", "--steps",
                 "20", "--output", str(tmp_path), "--no-animation", "--quiet"]) == 0
    robot, runs = load_runs([tmp_path / "ours-lm"])
    assert robot.name == "panda"
    viewer = serve(robot, runs, port=0, open_browser=False)
    viewer.set_step(10)
    try:
        with HeadlessPage(viewer.url, width=1280, height=800) as page:
            page.wait_for_text("ours-lm")
            full = _settled(page, tmp_path / "with_arm.png")
            viewer.scenes[0].arm.visible = False
            bare = _settled(page, tmp_path / "without_arm.png", unlike=full)
    finally:
        viewer.stop()
    assert _drawn(full) > 0.01, "a blank canvas"
    changed = _changed(full, bare)
    assert changed > 3000, f"hiding the Panda changed only {changed} pixels"
    assert _pixels_of_hue(bare, viewer.scenes[0].color) > 50, "no fingertip path"
