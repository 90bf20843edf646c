"""``ikbench experiment run DIR --touchscreen --emulator|--robot-port P``: the lab's
touchscreen page, its touches the answers of the hardware back-end.

The page (``pages/touch.html``, full screen on the screen in front of NICO) draws the goal set
at its pixels (design.json ``goals.pixels``, in a ``viewBox`` of the screen's size in pixels,
so a touch's coordinates are the screen's pixels whatever the browser's scale), shows the
instructions before the first trial and a break between blocks (a touch on its button goes
on), and posts every touch. The play loop (:func:`ikbench.experiment.play.run`) stays in
charge: :class:`TouchscreenPresenter` waits for the page between blocks, then plays the trial
on the bus (:class:`ikbench.experiment.play.BusPresenter`), whose answer source
:func:`browser_answers` blocks until the page posts a touch for that trial or the response
window passes (a timeout). The reaction time runs from the arm's stop (the answer source's
call) to the touch's arrival. Routes: ``GET /`` the page, ``GET /api/state``, ``POST
/api/continue`` ``{token}``, ``POST /api/touch`` ``{trial, attempt, x_px, y_px}`` (409 when no
trial awaits that touch: a touch during the motion, a stale page).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from ikbench.core.errors import InputError
from ikbench.experiment.layout import GoalSet
from ikbench.experiment.play import Presenter
from ikbench.experiment.scene import TARGET_RADIUS_PX
from ikbench.experiment.web import Reply, page

INSTRUCTIONS = ("NICO will move its head and its arm toward one of the targets and stop before "
                "it gets there. Touch the target you think NICO is going for, as quickly and "
                "accurately as you can, once it has stopped.")


class TouchscreenApp:
    """The touchscreen page's state, shared by the server's threads and the play loop."""

    def __init__(self, goals: GoalSet, response_window_s: float):
        self.goals, self.response_window_s = goals, float(response_window_s)
        self._lock = threading.Condition()
        self.state: dict[str, Any] = {"phase": "idle", "token": 0, "message": "",
                                      "trial": None, "attempt": None, "progress": ""}
        self._touch: dict | None = None
        self._continued = -1

    # ----- the play loop's side ----------------------------------------------------------
    def _set(self, **changes: Any) -> None:
        with self._lock:
            self.state.update(changes)
            self.state["token"] += 1
            self._lock.notify_all()

    def wait_continue(self, phase: str, message: str, progress: str = "") -> None:
        """Show an instructions or break screen and block until the page's button is touched."""
        self._set(phase=phase, message=message, trial=None, attempt=None, progress=progress)
        with self._lock:
            token = self.state["token"]
            self._lock.wait_for(lambda: self._continued >= token)

    def moving(self, trial: Mapping, attempt: int, progress: str) -> None:
        self._set(phase="moving", trial=int(trial["trial"]), attempt=attempt, message="",
                  progress=progress)

    def await_touch(self, trial: Mapping, attempt: int) -> dict | None:
        """Open the response window for a trial; the touch (x_px, y_px, at [monotonic s]) or
        None when the window passes."""
        with self._lock:
            self._touch = None
        started = time.monotonic()
        self._set(phase="awaiting", trial=int(trial["trial"]), attempt=attempt)
        with self._lock:
            self._lock.wait_for(lambda: self._touch is not None,
                                timeout=self.response_window_s)
            touch, self._touch = self._touch, None
            self.state.update(phase="returning")
            self.state["token"] += 1
        if touch is not None:
            touch["reaction_s"] = touch["at"] - started
        return touch

    def finish(self, message: str = "Thank you! The study is over.") -> None:
        self._set(phase="done", message=message, trial=None, attempt=None)

    # ----- the page's side ---------------------------------------------------------------
    def handle(self, method: str, path: str, query: Mapping[str, str], body: Any) -> Reply:
        if method == "GET":
            if path in ("/", "/index.html"):
                return page("touch.html")
            if path.startswith("/pages/"):
                return page(path[len("/pages/"):])
            if path == "/api/layout":
                return Reply.json({"screen_px": list(self.goals.screen.size_px),
                                   "targets": {str(t): [float(x) for x in p] for t, p in
                                               zip(self.goals.ids, self.goals.pixels)},
                                   "radius_px": TARGET_RADIUS_PX,
                                   "instructions": INSTRUCTIONS})
            if path == "/api/state":
                with self._lock:
                    return Reply.json(dict(self.state))
            return Reply.error(404, f"no page {path!r}")
        if method == "POST" and path == "/api/continue":
            return self._continue(body)
        if method == "POST" and path == "/api/touch":
            return self._touched(body)
        return Reply.error(404 if method == "GET" else 405, f"{method} {path}: not served")

    def _continue(self, body: Any) -> Reply:
        try:
            token = int(body["token"])
        except (KeyError, TypeError, ValueError):
            return Reply.error(400, "give the state's token as an integer")
        with self._lock:
            if self.state["phase"] not in ("instructions", "break") or token != self.state["token"]:
                return Reply.error(409, "no screen waits for that touch")
            self._continued = token
            self._lock.notify_all()
        return Reply.json({"continued": True})

    def _touched(self, body: Any) -> Reply:
        arrived = time.monotonic()
        try:
            trial, attempt = int(body["trial"]), int(body["attempt"])
            px = np.array([float(body["x_px"]), float(body["y_px"])])
        except (KeyError, TypeError, ValueError):
            return Reply.error(400, "give trial, attempt, x_px and y_px")
        size = np.asarray(self.goals.screen.size_px, float)
        if not np.all(np.isfinite(px)) or np.any(px < 0) or np.any(px > size):
            return Reply.error(400, f"touch ({px[0]:g}, {px[1]:g}) px is off the screen")
        with self._lock:
            s = self.state
            if s["phase"] != "awaiting" or s["trial"] != trial or s["attempt"] != attempt \
                    or self._touch is not None:
                return Reply.error(409, f"trial {trial} attempt {attempt} awaits no touch now "
                                        f"(phase {s['phase']}, trial {s['trial']})")
            self._touch = {"px": px, "at": arrived}
            self._lock.notify_all()
        return Reply.json({"accepted": True})


def browser_answers(app: TouchscreenApp) -> Callable[[Mapping, int], dict]:
    """An answer source for :class:`ikbench.experiment.play.BusPresenter`: blocks until the
    touchscreen page posts a touch for the trial or its response window passes; the answer
    is the target nearest to the touch (in mm on the screen)."""
    goals = app.goals

    def answer(trial: Mapping, attempt: int) -> dict:
        touch = app.await_touch(trial, attempt)
        if touch is None:
            return {"answer_target": None, "touch_px": None, "reaction_s": None,
                    "timed_out": True}
        index = int(goals.nearest(goals.screen.px_to_mm(touch["px"])))
        return {"answer_target": int(goals.ids[index]), "touch_px": touch["px"],
                "reaction_s": round(float(touch["reaction_s"]), 3), "timed_out": False}

    return answer


class TouchscreenPresenter(Presenter):
    """A hardware presenter with the page's instructions and breaks: before the first trial
    of the session and whenever the block changes it waits for the page's button."""

    def __init__(self, inner: Presenter, app: TouchscreenApp, total: Callable[[Mapping], str]
                 | None = None):
        self.inner, self.app = inner, app
        self.backend = inner.backend
        self.block: tuple[str, int] | None = None
        self.total = total or (lambda trial: "")

    def present(self, trial: Mapping, attempt: int) -> dict:
        block = (str(trial["participant"]), int(trial["block"]))
        progress = self.total(trial)
        if self.block is None or block[0] != self.block[0]:
            self.app.wait_continue("instructions", f"Participant {block[0]}. {INSTRUCTIONS}",
                                   progress)
        elif block != self.block:
            self.app.wait_continue("break", "Take a short break. Touch Continue when you are "
                                   "ready.", progress)
        self.block = block
        self.app.moving(trial, attempt, progress)
        return self.inner.present(trial, attempt)

    def close(self) -> None:
        self.app.finish()
        self.inner.close()


def check_touchscreen(touchscreen: bool, emulator: bool, robot_port: str | None,
                      answers: object) -> None:
    """One line for a touchscreen run without a hardware back-end or with --answers."""
    if touchscreen and not (emulator or robot_port):
        raise InputError("--touchscreen: give --emulator or --robot-port (the touches answer "
                         "the trials NICO plays)")
    if touchscreen and answers:
        raise InputError("--touchscreen takes the answers from the page; drop --answers")
