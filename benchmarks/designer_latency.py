"""Time from a move of the touch point to the designer's updated scene (``ikbench design``).

For each method (default ours-lm and ours-exact), a designer of NICO's line 1 (n = 50) is
served (:func:`ikbench.viewer.design.view.serve_design`, the arm playing as in use) and its
touch point is moved ``--moves`` times along a small circle (radius 20 mm) around the touch
point, as a hand drags it, each move through :meth:`DesignerView.drag`: the touch pose's IK,
the warm-started solve, the timing, the judgement and the scene update (paths, markers, the
arm's pose, the panel). Rounds are interleaved between the methods, so background load hits
both alike. ``--browser`` connects a headless Chromium to the page of the designer measured
(one at a time: its software WebGL takes a core of its own), so every update is also sent
to a browser.

Run: ``.venv/bin/python benchmarks/designer_latency.py [--moves 20] [--rounds 5]
[--browser] [--output runs/designer_latency.csv]``; the CSV has one row per move (method,
round, move, ``solve_s``: the designer's part, ``scene_s``: to the updated scene,
``warm_solve_s``: the solve alone, ``cold_solve_s``: the same task solved from scratch right
after, the baseline) with the CPU, the load average and versions in every row; the printout
gives the median and the 95th percentile per method.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import time

import numpy as np
import pandas as pd

from ikbench.core.io import atomic_write_csv, check_writable
from ikbench.core.provenance import provenance
from ikbench.viewer.browser import HeadlessPage, find_chromium
from ikbench.viewer.design.designer import Designer, Update
from ikbench.viewer.design.view import serve_design

RADIUS_MM = 20.0


def circle(centre: np.ndarray, moves: int) -> np.ndarray:
    """(moves, 3) points on a circle of RADIUS_MM about ``centre`` in its y-z plane [mm]."""
    angle = np.linspace(0.0, 2.0 * np.pi, moves, endpoint=False)
    return centre + RADIUS_MM * np.stack([0 * angle, np.cos(angle) - 1, np.sin(angle)], 1)


def cold_solve_s(designer: Designer, update: Update) -> float:
    """Wall time [s] of the same method solving the update's task from scratch (the
    baseline of the warm start, measured in the same run)."""
    started = time.perf_counter()
    designer.method.solve(designer.robot, update.task)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", default="ours-lm,ours-exact")
    parser.add_argument("--moves", type=int, default=20, help="moves per round (default 20)")
    parser.add_argument("--rounds", type=int, default=5, help="rounds (default 5)")
    parser.add_argument("--browser", action="store_true",
                        help="connect a headless Chromium to each designer's page")
    parser.add_argument("--output", default="runs/designer_latency.csv")
    args = parser.parse_args()
    if min(args.moves, args.rounds) < 1:
        parser.error("--moves and --rounds must be >= 1")
    if args.browser and find_chromium() is None:
        parser.error("--browser: no Chromium found (Debian: apt-get install -y chromium)")
    check_writable(args.output)
    methods = args.methods.split(",")
    views = {m: serve_design(Designer("nico_right_arm", m), port=0, open_browser=False)
             for m in methods}
    rows = []
    for rep in range(args.rounds + 1):  # round 0: warm-up, not recorded
        for method, view in views.items():
            for other in views.values():  # only the designer measured plays its arm
                other.set_playing(other is view)
            with contextlib.ExitStack() as stack:
                if args.browser:  # one browser at a time: software WebGL takes a core
                    page = stack.enter_context(HeadlessPage(view.url))
                    page.wait_for_text("Judged")
                    page.settled()
                start = view.designer.handles()["touch"]
                view.scene_s.clear()
                load = os.getloadavg()[0]
                updates = [view.drag("touch", p) for p in circle(start, args.moves)]
            if rep:
                rows += [{"method": method, "round": rep, "move": k,
                          "solve_s": u.elapsed_s, "scene_s": s,
                          "warm_solve_s": u.solution.duration_s,
                          "cold_solve_s": cold_solve_s(view.designer, u),
                          "load_1min": load, "browser": args.browser}
                         for k, (u, s) in enumerate(zip(updates, view.scene_s))]
    for view in views.values():
        view.stop()
    info = provenance(extra=("viser",))
    frame = pd.DataFrame(rows).assign(
        cpu=info["cpu"], cpu_count=info["cpu_count"], git_revision=info["git_revision"],
        git_commit=info["git_commit"], git_clean=info["git_clean"],
        viser=info["packages"]["viser"], created_utc=info["created_utc"])
    atomic_write_csv(args.output, frame)
    print(f"CPU: {info['cpu']} ({info['cpu_count']} cores); load average (1 min) "
          f"{frame['load_1min'].min():.1f}-{frame['load_1min'].max():.1f}; "
          f"{args.rounds} rounds x {args.moves} moves; browser connected: {args.browser}")
    for method in methods:
        part = frame[frame["method"] == method]
        scene, solve = part["scene_s"] * 1000, part["solve_s"] * 1000
        ratio = (part["cold_solve_s"] / part["warm_solve_s"]).median()
        print(f"{method:>11}: move -> updated scene median {scene.median():.1f} ms, p95 "
              f"{np.percentile(scene, 95):.1f} ms (IK, solve, timing, judgement: median "
              f"{solve.median():.1f} ms; the solve warm-started {ratio:.1f}x faster than from "
              "scratch, median); per-round medians "
              + ", ".join(f"{statistics.median(g['scene_s']) * 1000:.1f}"
                          for _, g in part.groupby("round")))


if __name__ == "__main__":
    main()
